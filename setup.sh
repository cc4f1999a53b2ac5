#!/usr/bin/env bash
# Installs raysweep's dependencies (Debian 12 packages only) and builds it.
# Run as root on a fresh Debian 12 machine; safe to run again (incremental).
set -euo pipefail
cd "$(dirname "$0")"

PACKAGES=(
  cmake ninja-build g++ ccache pkg-config git
  libembree-dev libtbb-dev libhdf5-dev hdf5-tools libcgal-dev libeigen3-dev
  libdraco-dev libtinygltf-dev libopenmesh-dev libmeshoptimizer-dev
  libosmium2-dev libexpat1-dev zlib1g-dev libdeflate-dev libbz2-dev libproj-dev proj-bin
  libcli11-dev nlohmann-json3-dev libspdlog-dev libfmt-dev libtomlplusplus-dev libssl-dev
  libgtest-dev libbenchmark-dev
  clang libclang-rt-14-dev
  sumo sumo-tools
  libns3-dev ns3 libgsl-dev
  openmpi-bin libopenmpi-dev
  python3-h5py python3-numpy python3-matplotlib python3-pyproj python3-sklearn python3-torch
  libopenvdb-dev libboost-iostreams-dev python3-openvdb blender
)
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${#missing[@]} Debian packages: ${missing[*]}"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

export SUMO_HOME=/usr/share/sumo
# ccache keys relative to the checkout, so that a clone in another folder (CI)
# reuses what this one compiled (debug builds would otherwise hash the folder).
export CCACHE_BASEDIR="$PWD" CCACHE_NOHASHDIR=1
BUILD_TYPE=${RAYSWEEP_BUILD_TYPE:-Release}
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE="$BUILD_TYPE" >/dev/null
cmake --build build -j"$(nproc)"

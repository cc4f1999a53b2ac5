#!/usr/bin/env bash
# The test suite under AddressSanitizer + UndefinedBehaviorSanitizer, in its
# own incremental build (build-asan/): every unit and behaviour test; the long
# end-to-end CLI runs, ns-3 and Blender stay in the Release suite (setup.sh's
# build). Any sanitizer report fails its test. Then every fuzz target of
# tests/fuzz/ runs a few seconds on its corpus (tests/fuzz.sh: clang +
# libFuzzer in build-fuzz/, skipped where clang is missing).
# Usage: bash tests/sanitize.sh
set -euo pipefail
cd "$(dirname "$0")/.."
export SUMO_HOME=/usr/share/sumo
export CCACHE_BASEDIR="$PWD" CCACHE_NOHASHDIR=1  # see setup.sh
cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" \
  -DRAYSWEEP_SANITIZE=address,undefined -DRAYSWEEP_BUILD_BENCH=OFF -DRAYSWEEP_BUILD_NS3=OFF >/dev/null
cmake --build build-asan -j"$(nproc)"
# Leaks are reported too; the suppressions name third-party libraries only.
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:strict_string_checks=1:detect_stack_use_after_return=1"
export LSAN_OPTIONS="suppressions=$PWD/tests/sanitize.supp:print_suppressions=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
ctest --test-dir build-asan --output-on-failure -j"$(nproc)" -E '^(Cli|RunSinr|ns3_|Render\.|FcdMemory\.)'
bash tests/fuzz.sh

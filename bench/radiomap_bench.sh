#!/usr/bin/env bash
# Radio-map speed on the demo city's streets (1 m voxels, 0.5-3 m): voxels/s
# and scaling with the number of transmitters; median of REPEATS runs each.
#   bash bench/radiomap_bench.sh [SCENE_DIR] [REPEATS]
# SCENE_DIR defaults to out/demo/scene (from `raysweep run datasets/demo/city.toml`).
set -euo pipefail
cd "$(dirname "$0")/.."
scene=${1:-out/demo/scene}
repeats=${2:-3}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# The demo's [radio] and [tracer] settings without its [radiomap] transmitter.
sed '/^\[radiomap\]/,$d' datasets/demo/city.toml > "$tmp/city.toml"
txs=("rsu1,120,70,6" "rsu2,40,28,6" "rsu3,185,125,6" "rsu4,190,40,6")
echo "tx  voxels  solve_s(median)  voxels/s  s/tx"
for n in 1 2 4; do
  args=()
  for ((k = 0; k < n; k++)); do args+=(--tx "${txs[$k]}"); done
  times=()
  for ((r = 0; r < repeats; r++)); do
    out=$(./build/raysweep radiomap --scene "$scene" "${args[@]}" --config "$tmp/city.toml" \
          --out "$tmp/m.vdb" 2>&1 | grep -E '^.*\.vdb: ')
    voxels=$(echo "$out" | sed -E 's/.*: ([0-9]+) voxels.*/\1/')
    times+=("$(echo "$out" | sed -E 's/.* in ([0-9.e+-]+) s.*/\1/')")
  done
  med=$(printf '%s\n' "${times[@]}" | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}')
  awk -v n="$n" -v v="$voxels" -v t="$med" 'BEGIN {printf "%d  %d  %.2f  %.0f  %.2f\n", n, v, t, n * v / t, t / n}'
done

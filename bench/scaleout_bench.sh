#!/usr/bin/env bash
# Scale-out benchmark: `mpirun -n R raysweep run CITY --mpi` on the VaN3Twin
# ring road (60 vehicles, ../shared/data) for R in RANKS: wall time of the
# whole run, efficiency T1 / (R x TR), the merge's time (from rank 0's log),
# CPU seconds and peak RSS of every rank (GNU time -v; CPU time shows the work
# each rank duplicates, whatever else the machine runs), the load average when
# the run started, and whether the merged dataset is byte-identical to the
# one-rank run's.
#
#   bench/scaleout_bench.sh [SECONDS] [BLOCK_FRAMES] ["RANKS"] [THREADS_PER_RANK]
#   defaults: 10 s of traffic (100 frames), blocks of 25 frames, "1 2 4", 1 thread per rank
#
# The recipe is datasets/van3twin-ring/city.toml with the sweep cut to SECONDS
# from t = 70 s and without its [sinr] table (the sweep and the merge are
# measured, not the SINR stage); the shared stages are built once, untimed.
# Results: $OUT/results.md (default out/scaleout-bench).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
SECS=${1:-10}
BF=${2:-25}
RANKS=${3:-"1 2 4"}
J=${4:-1}
OUT=${OUT:-$ROOT/out/scaleout-bench}
B=$ROOT/build/raysweep
SHARED=$(cd "$ROOT/../shared/data" && pwd)
export SUMO_HOME=${SUMO_HOME:-/usr/share/sumo}
mkdir -p "$OUT"

END=$(awk "BEGIN { printf \"%.2f\", 70 + $SECS - 0.05 }")
sed -e "s#\.\./\.\./\.\./shared/data#$SHARED#g" -e "s#^end_s = 129.95.*#end_s = $END#" \
    -e "s#^block_frames = .*#block_frames = $BF#" "$ROOT/datasets/van3twin-ring/city.toml" |
  awk '/^\[sinr\]/ { skip = 1 } /^\[/ && !/^\[sinr\]/ { skip = 0 } !skip' > "$OUT/city.toml"
grep -q "^end_s = $END" "$OUT/city.toml" || { echo "could not set end_s" >&2; exit 1; }

"$B" -q run "$OUT/city.toml" --out "$OUT/city" --until traffic

t1=""
{
  echo "| ranks | threads/rank | wall s | efficiency | merge s | CPU s per rank | CPU s total / 1 rank | peak RSS per rank (MB) | load avg at start | identical to 1 rank |"
  echo "|---|---|---|---|---|---|---|---|---|---|"
} > "$OUT/results.md"
for n in $RANKS; do
  rm -rf "$OUT/city/shards" "$OUT/city/dataset.h5" "$OUT/city/dataset.h5.merge.json" "$OUT"/city/.stamps/sweep*
  rm -f "$OUT"/time.$n.*
  load=$(cut -d' ' -f1 /proc/loadavg)
  t0=$(date +%s.%N)
  mpirun --allow-run-as-root --oversubscribe -n "$n" sh -c \
    "/usr/bin/time -v -o $OUT/time.$n.\$OMPI_COMM_WORLD_RANK $B -j $J run $OUT/city.toml --out $OUT/city --mpi" \
    > "$OUT/log.$n" 2>&1
  t=$(awk "BEGIN { printf \"%.1f\", $(date +%s.%N) - $t0 }")
  [ -z "$t1" ] && t1=$t && cp "$OUT/city/dataset.h5" "$OUT/dataset.1rank.h5"
  eff=$(awk "BEGIN { printf \"%.2f\", $t1 / ($n * $t) }")
  merge=$(grep -o 'merged .* in [0-9.]* s' "$OUT/log.$n" | grep -o 'in [0-9.]* s' | tr -dc '0-9.')
  rss=""
  cpus=""
  cpu_total=0
  for r in $(seq 0 $((n - 1))); do
    kb=$(grep "Maximum resident set size" "$OUT/time.$n.$r" | tr -dc '0-9')
    rss="$rss${rss:+, }$((kb / 1024))"
    cpu=$(awk -F': ' '/User time|System time/ { s += $2 } END { printf "%.1f", s }' "$OUT/time.$n.$r")
    cpus="$cpus${cpus:+, }$cpu"
    cpu_total=$(awk "BEGIN { print $cpu_total + $cpu }")
  done
  [ -z "${cpu1:-}" ] && cpu1=$cpu_total
  overhead=$(awk "BEGIN { printf \"%.2f\", $cpu_total / $cpu1 }")
  same=$(cmp -s "$OUT/city/dataset.h5" "$OUT/dataset.1rank.h5" && echo "byte-identical" || echo "DIFFERS")
  echo "| $n | $J | $t | $eff | $merge | $cpus | $overhead | $rss | $load | $same |" | tee -a "$OUT/results.md"
done
frames=$("$B" info --json "$OUT/city/dataset.h5" | /usr/bin/python3 -c "import json,sys; d=json.load(sys.stdin); print(d['frames'], 'frames,', d['links'], 'links,', d['file_bytes'], 'bytes')")
echo "sweep: $frames; $(nproc) cores; $(date -u +%FT%TZ)" | tee -a "$OUT/results.md"

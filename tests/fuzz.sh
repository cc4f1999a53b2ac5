#!/usr/bin/env bash
# Short fuzzing runs for CI (tests/sanitize.sh calls this): builds
# build-fuzz/ with clang (libFuzzer + ASan + UBSan; only the libraries the
# harnesses need) and runs every target of tests/fuzz/ for a few seconds on
# its committed corpus, which holds the seeds and every input that once
# crashed, so each run is also a regression test. A crash, sanitizer report,
# leak, timeout, out-of-memory or unexpected exception fails the script and
# leaves the input in build-fuzz/artifacts/. Skipped (exit 0, with a note)
# where clang or libFuzzer is missing.
# Usage: bash tests/fuzz.sh [SECONDS_PER_TARGET (default 6): the cap is 5 x that]
set -euo pipefail
cd "$(dirname "$0")/.."
source tests/fuzz/lib.sh
SECONDS_PER_TARGET=${1:-6}
if ! fuzz_toolchain_ok; then
  echo "fuzz: skipped"; exit 0
fi
fuzz_build
fuzz_env
failed=()
# Targets with an open finding (tests/fuzz/open/README.md) only replay their
# corpus (-runs=0) instead of mutating it, so CI does not fail on it by chance.
REPLAY_ONLY=" "
# A fixed seed and a fixed number of inputs per target (1-3 s of each on the
# 2-core machine; the time limit is only a cap):
# every run explores the same inputs, so a CI failure reproduces, and CI does
# not fail by chance on a finding a faster machine happens to reach.
ci_runs() {
  case "$1" in
    dataset_h5) echo 80 ;; ns3_table_h5) echo 200 ;; sinr_h5) echo 400 ;; osm_xml) echo 1500 ;;
    fcd|osm_pbf) echo 3000 ;; vtypes|toml) echo 4000 ;; sumo_net|off) echo 6000 ;; *) echo 10000 ;;
  esac
}
for t in "${FUZZ_TARGETS[@]}"; do
  work="build-fuzz/ci/$t"
  budget=(-seed=1 -runs="$(ci_runs "$t")" -max_total_time=$((5 * SECONDS_PER_TARGET)))
  [[ "$REPLAY_ONLY" == *" $t "* ]] && budget=(-runs=0)
  rm -rf "$work"; mkdir -p "$work/new" build-fuzz/artifacts
  dict=$(fuzz_dict "$t")
  start=$(date +%s%N)
  # New inputs go to $work/new; the committed corpus is only read.
  if build-fuzz/tests/fuzz/fuzz_"$t" "${budget[@]}" -rss_limit_mb=2048 -timeout=10 \
       -print_final_stats=1 -artifact_prefix="build-fuzz/artifacts/$t-" ${dict:+-dict=$dict} \
       "$work/new" "tests/fuzz/corpus/$t" >"$work/log" 2>&1; then
    runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$work/log" | tail -1)
    printf 'fuzz %-13s ok %9s execs %6d ms\n' "$t" "${runs:-?}" $(( ($(date +%s%N) - start) / 1000000 ))
  else
    echo "fuzz $t FAILED (input saved under build-fuzz/artifacts/$t-*):"
    grep -E "raysweep-fuzz finding|ERROR: |runtime error|SUMMARY" "$work/log" | head -20 || tail -30 "$work/log"
    failed+=("$t")
  fi
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz: findings in ${failed[*]}"; exit 1
fi
echo "fuzz: all ${#FUZZ_TARGETS[@]} targets clean"

#!/usr/bin/env bash
# Long fuzzing runs of every tests/fuzz/ target, one after the other (one
# libFuzzer worker: the machine is shared), then a table of executions,
# coverage (libFuzzer's cov = edges, ft = features), corpus size and findings.
#
#   bash bench/fuzz.sh SECONDS [TARGET...]      # each target for SECONDS
#   FUZZ_RUNS=1000000 bash bench/fuzz.sh 1800   # ... or until 1e6 executions, whichever comes first
#
# FUZZ_NO_BUILD=1 skips the (incremental) build of build-fuzz/. FUZZ_TABLE=FILE
# writes the table there instead (two runs side by side, one per core).
# FUZZ_TIMEOUT=S: an input running longer than S seconds is a hang (default
# 10). libFuzzer's clock is wall time, so a run sharing a busy machine (or
# under nice) needs more, or it reports starvation as hangs.
# Corpora grow in fuzz-out/corpus/<target>/ (seeded from tests/fuzz/corpus/,
# kept between runs); logs in fuzz-out/logs/, findings (crash-, leak-,
# timeout-, oom- inputs) in fuzz-out/artifacts/<target>/. The table is also
# written to fuzz-out/table.md. Minimise a finding with
#   build-fuzz/tests/fuzz/fuzz_<target> -minimize_crash=1 -runs=100000 FILE
# and add it to tests/fuzz/corpus/<target>/ with its fix and regression test.
set -euo pipefail
cd "$(dirname "$0")/.."
source tests/fuzz/lib.sh
if [ $# -lt 1 ]; then
  echo "usage: bash bench/fuzz.sh SECONDS [TARGET...]" >&2; exit 2
fi
SECS=$1; shift
TARGETS=("$@")
[ ${#TARGETS[@]} -eq 0 ] && TARGETS=("${FUZZ_TARGETS[@]}")
fuzz_toolchain_ok || exit 1
[ -n "${FUZZ_NO_BUILD:-}" ] || fuzz_build  # FUZZ_NO_BUILD=1: use build-fuzz/ as it is
fuzz_env
mkdir -p fuzz-out/logs
table="${FUZZ_TABLE:-fuzz-out/table.md}"
{
  echo "| target | seconds | execs | execs/s | cov | ft | corpus | findings |"
  echo "|---|---|---|---|---|---|---|---|"
} > "$table"
for t in "${TARGETS[@]}"; do
  corpus="fuzz-out/corpus/$t" art="fuzz-out/artifacts/$t" log="fuzz-out/logs/$t.log"
  mkdir -p "$corpus" "$art"
  before=$(find "$art" -type f | wc -l)
  dict=$(fuzz_dict "$t")
  start=$(date +%s)
  set +e
  build-fuzz/tests/fuzz/fuzz_"$t" -max_total_time="$SECS" ${FUZZ_RUNS:+-runs=$FUZZ_RUNS} -rss_limit_mb=2048 \
    -timeout="${FUZZ_TIMEOUT:-10}" -print_final_stats=1 -artifact_prefix="$art/" ${dict:+-dict=$dict} \
    "$corpus" "tests/fuzz/corpus/$t" >"$log" 2>&1
  rc=$?
  set -e
  took=$(( $(date +%s) - start ))
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  last=$(grep -aE '^#[0-9]+.*cov: ' "$log" | tail -1)
  cov=$(sed -nE 's/.* cov: ([0-9]+).*/\1/p' <<<"$last")
  ft=$(sed -nE 's/.* ft: ([0-9]+).*/\1/p' <<<"$last")
  corp=$(find "$corpus" -type f | wc -l)
  found=$(( $(find "$art" -type f | wc -l) - before ))
  note=""
  [ "$rc" -ne 0 ] && note=" (stopped: exit $rc, see $log)"
  printf '| %s | %s | %s | %s | %s | %s | %s | %s%s |\n' "$t" "$took" "${execs:-?}" \
    "$(( ${execs:-0} / (took > 0 ? took : 1) ))" "${cov:-?}" "${ft:-?}" "$corp" "$found" "$note" >> "$table"
  tail -1 "$table"
done
echo
cat "$table"

#!/usr/bin/python3
"""Compare two builds of a Google Benchmark binary in back-to-back pairs of runs.

usage: ab_pairs.py OLD_BINARY NEW_BINARY --filter REGEX [--rounds N] [--counters a,b]

On a shared or throttled machine one binary's runs a minute apart can differ by
20 %, more than most code changes are worth; a table of one run each compares
the minutes, not the code. Here each round runs both binaries once, one right
after the other (which one first alternates from round to round, so a drift
favours neither), and the verdict is the median over rounds of the per-round
ratio NEW / OLD of each case's real time (and of the named counters, e.g.
ms_image,ms_shoot,ms_pairs of bench_tracer). Cases run one iteration each
(--benchmark_min_time=0.001), so give the filter the expensive cases only.

Prints one line per case: both medians, the median ratio and its range over
rounds. Exit status 2 when a binary fails or the filter matches nothing.
"""
import argparse
import json
import statistics
import subprocess
import sys


def run(binary, regex):
    out = subprocess.run([binary, f"--benchmark_filter={regex}", "--benchmark_min_time=0.001",
                          "--benchmark_format=json"], capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"{binary}: exit status {out.returncode}: {out.stderr.strip()[-500:]}")
    cases = {}
    if not out.stdout.strip():  # the filter matched nothing
        return cases
    for b in json.loads(out.stdout)["benchmarks"]:
        if "error_message" in b:
            continue
        cases[b["name"].removesuffix("/real_time")] = b
    return cases


def main(argv=None):
    p = argparse.ArgumentParser(description="Paired comparison of two benchmark binaries.")
    p.add_argument("old")
    p.add_argument("new")
    p.add_argument("--filter", required=True, help="--benchmark_filter regex")
    p.add_argument("--rounds", type=int, default=6)
    p.add_argument("--counters", default="", help="comma-separated counters to compare too")
    a = p.parse_args(argv)
    counters = [c for c in a.counters.split(",") if c]
    rounds = []
    try:
        for k in range(a.rounds):
            order = (a.old, a.new) if k % 2 == 0 else (a.new, a.old)
            got = {b: run(b, a.filter) for b in order}
            rounds.append((got[a.old], got[a.new]))
    except (RuntimeError, OSError, json.JSONDecodeError) as e:
        print(f"ab_pairs.py: {e}", file=sys.stderr)
        return 2
    names = [n for n in rounds[0][0] if all(n in o and n in w for o, w in rounds)]
    if not names:
        print(f"ab_pairs.py: no case matches {a.filter!r} in both binaries", file=sys.stderr)
        return 2
    for n in names:
        old = [o[n]["real_time"] for o, _ in rounds]
        new = [w[n]["real_time"] for _, w in rounds]
        ratios = [y / x for x, y in zip(old, new) if x > 0]
        line = (f"{n}: old {statistics.median(old):.4g}, new {statistics.median(new):.4g} "
                f"{rounds[0][0][n].get('time_unit', '')}; new/old {statistics.median(ratios):.3f} "
                f"(rounds {min(ratios):.3f}..{max(ratios):.3f})")
        for c in counters:
            r = [w[n][c] / o[n][c] for o, w in rounds if c in o[n] and c in w[n] and o[n][c] > 0]
            if r:
                line += f"; {c} {statistics.median(r):.3f}"
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())

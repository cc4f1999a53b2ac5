"""python -m ml --city NAME=RUN_DIR [--city ...] --out DIR [--seed 1] [--max-train-s 600] [--max-links N]

Exit status: 0 done, 2 a missing or malformed input (one line on stderr naming the file).
"""
import argparse
import json
import math
import os
import sys
import tempfile
import time

import numpy as np


def parse_args(argv):
    p = argparse.ArgumentParser(prog="python -m ml", description="ML benchmark of raysweep datasets")
    p.add_argument("--city", action="append", required=True, metavar="NAME=RUN_DIR",
                   help="a city's run directory (dataset.h5, optional features.h5 and sinr/ray.h5); repeatable")
    p.add_argument("--out", required=True, help="output directory: results.json, report.md, PNGs")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--max-train-s", type=float, default=600.0, help="training wall clock, all splits together")
    p.add_argument("--max-links", type=int, default=200000, help="links per city (deterministic subsample)")
    p.add_argument("--threads", type=int, default=2, help="torch threads of the cnn")
    p.add_argument("--resamples", type=int, default=200, help="bootstrap resamples")
    args = p.parse_args(argv)
    cities = []
    for c in args.city:
        name, sep, path = c.partition("=")
        if not sep or not name or not path:
            p.error(f"--city {c!r}: expected NAME=RUN_DIR")
        if name in [n for n, _ in cities]:
            p.error(f"--city {name}: given twice")
        cities.append((name, path))
    args.cities = cities
    return args


def _json_value(v):
    """NaN and infinities are not JSON: null."""
    if isinstance(v, (float, np.floating)):
        return float(v) if math.isfinite(v) else None
    if isinstance(v, np.integer):
        return int(v)
    return v


def write_json_atomic(path, rows):
    clean = [{k: _json_value(v) for k, v in r.items()} for r in rows]
    fd, tmp = tempfile.mkstemp(prefix=".results.", dir=os.path.dirname(path) or ".")
    with os.fdopen(fd, "w") as f:
        json.dump(clean, f, indent=1)
        f.write("\n")
    os.replace(tmp, path)


def main(argv=None):
    args = parse_args(sys.argv[1:] if argv is None else argv)
    from . import data, pipeline, report  # after argument errors: imports take a while
    log = lambda msg: print(msg, file=sys.stderr, flush=True)
    t0 = time.monotonic()
    try:
        cities = [data.load_city(n, p, args.max_links, args.seed) for n, p in args.cities]
    except data.InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    vocab = data.unify_materials(cities)
    for c in cities:
        log(f"{c.name}: {len(c.rows)} links ({int(c.in_sample.sum())} sampled of {c.link_total}), "
            f"{0 if c.rec is None else len(c.rec['row'])} 802.11p receptions, context {c.ctx is not None}")
        for note in c.notes:
            log(f"  note: {note}")
    try:
        rows, per_split = pipeline.run(cities, len(vocab), args.max_train_s, args.seed, args.resamples, log,
                                      args.threads)
    except data.InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    os.makedirs(args.out, exist_ok=True)
    report.write(args.out, cities, rows, per_split, vars_of(args), time.monotonic() - t0)
    write_json_atomic(os.path.join(args.out, "results.json"), rows)
    print(report.summary(rows, per_split))
    log(f"wrote {args.out}/results.json and report.md in {time.monotonic() - t0:.0f} s")
    return 0


def vars_of(args):
    return {"cities": args.cities, "seed": args.seed, "max_train_s": args.max_train_s,
            "max_links": args.max_links, "resamples": args.resamples, "threads": args.threads}


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""LoS-label fractions of a channel dataset against 3GPP TR 37.885's V2V probabilities.

    /usr/bin/python3 python/los_fractions.py DATASET.h5 [--png OUT.png] [--json OUT.json]

Per distance bin (and overall): the fractions of LOS / NLOSV / NLOS links by the geometric label
(/links/los_class: the direct ray alone) and by the first-Fresnel-zone label
(/links/los_class_fresnel, schema >= 1.2.0), beside TR 37.885 Table 6.2-1's expected fractions at
the same links' distances: urban P_LOS = min(1, 1.05 exp(-0.0114 d)), P_NLOS from its log-normal
fit, NLOSV the rest; highway P_LOS quadratic in d, NLOSV the rest (no buildings). Out-of-range links
are left out.
"""
import argparse
import json
import math
import sys

import numpy as np

sys.path.insert(0, __import__("os").path.dirname(__file__))
from raysweep_dataset import FLAG_OUT_OF_RANGE, open_dataset  # noqa: E402

CLASSES = ("LOS", "NLOSV", "NLOS")
BINS = (0, 25, 50, 100, 200, 400, 1e9)


def tr37885(scenario, d):
    """Expected (P_LOS, P_NLOSV, P_NLOS) at 2-D distance d (m), TR 37.885 Table 6.2-1."""
    if scenario == "urban":
        p_los = min(1.0, 1.05 * math.exp(-0.0114 * d))
        lg = math.log(max(d, 1e-3)) - 5.0063
        p_nlos = 1.0 / (0.0312 * max(d, 1e-3)) * math.exp(-(lg * lg) / 2.4544)
        p_nlos = min(max(p_nlos, 0.0), 1.0 - p_los)
    else:
        p_los = min(1.0, 2.1013e-6 * d * d - 0.002 * d + 1.0193) if d <= 475 else max(0.0, 0.54 - 0.001 * (d - 475))
        p_nlos = 0.0
    return p_los, 1.0 - p_los - p_nlos, p_nlos


def fractions(classes):
    n = len(classes)
    return [float(np.count_nonzero(classes == c)) / n if n else float("nan") for c in range(3)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset")
    ap.add_argument("--png")
    ap.add_argument("--json")
    args = ap.parse_args()
    with open_dataset(args.dataset) as ds:
        links = ds.links_table()
        if "los_class_fresnel" not in links:
            sys.exit(f"{args.dataset}: no /links/los_class_fresnel (schema {ds.schema_version} < 1.2.0)")
        keep = (links["flags"] & FLAG_OUT_OF_RANGE) == 0
        d = ds.link_distances()[keep]
        geo = links["los_class"][keep]
        zone = links["los_class_fresnel"][keep]
        clearance = links["fresnel_clearance"][keep]
    rows = []
    for lo, hi in list(zip(BINS[:-1], BINS[1:])) + [(0, 1e9)]:
        m = (d >= lo) & (d < hi)
        if not np.any(m):
            continue
        expect = {s: np.mean([tr37885(s, x) for x in d[m]], axis=0).tolist() for s in ("urban", "highway")}
        rows.append({"bin_m": [lo, hi if hi < 1e9 else None], "links": int(np.count_nonzero(m)),
                     "geometric": fractions(geo[m]), "fresnel": fractions(zone[m]),
                     "tr37885_urban": expect["urban"], "tr37885_highway": expect["highway"],
                     "median_vehicle_clearance_nlosv": float(np.median(clearance[m & (zone == 1)]))
                     if np.any(m & (zone == 1)) else None})
    print(f"{args.dataset}: {int(np.count_nonzero(keep))} in-range links")
    print(f"{'distance m':>12} {'links':>7}  {'geometric LOS/NLOSV/NLOS %':>28}  {'Fresnel LOS/NLOSV/NLOS %':>26}"
          f"  {'TR 37.885 urban %':>20}  {'highway %':>18}")
    for r in rows:
        lo, hi = r["bin_m"]
        label = "all" if lo == 0 and hi is None else f"{lo:g}-{hi:g}" if hi else f">= {lo:g}"
        fmt = lambda f: "/".join(f"{100 * x:.1f}" for x in f)  # noqa: E731
        print(f"{label:>12} {r['links']:>7}  {fmt(r['geometric']):>28}  {fmt(r['fresnel']):>26}"
              f"  {fmt(r['tr37885_urban']):>20}  {fmt(r['tr37885_highway']):>18}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"dataset": args.dataset, "rows": rows}, f, indent=1)
    if args.png:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        binned = [r for r in rows if r["bin_m"][1] is not None or r["bin_m"][0] > 0]
        x = np.arange(len(binned))
        fig, axes = plt.subplots(1, 3, figsize=(13, 3.8), sharey=True)
        for ax, c in zip(axes, range(3)):
            for key, style in (("geometric", "o--"), ("fresnel", "o-"), ("tr37885_urban", "s:"),
                               ("tr37885_highway", "^:")):
                ax.plot(x, [100 * r[key][c] for r in binned], style, label=key.replace("_", " "))
            ax.set_xticks(x, [f"{r['bin_m'][0]:g}-{r['bin_m'][1]:g}" if r["bin_m"][1] else f">{r['bin_m'][0]:g}"
                              for r in binned], rotation=30)
            ax.set_title(CLASSES[c])
            ax.set_xlabel("distance (m)")
            ax.grid(alpha=0.3)
        axes[0].set_ylabel("links (%)")
        axes[0].legend(fontsize=8)
        fig.suptitle(args.dataset)
        fig.tight_layout()
        fig.savefig(args.png, dpi=110)
        print(f"picture: {args.png}")


if __name__ == "__main__":
    main()

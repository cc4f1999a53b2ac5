#!/usr/bin/env python3
"""PRR against distance: ns-3 (raysweep-ns3-cam's receptions.csv) beside
`raysweep sinr`'s 802.11p receptions on the same channels.

  /usr/bin/python3 python/ns3_compare.py --png docs/img/ns3_prr.png \
      demo:OUT/cam-demo/receptions.csv:OUT/sinr-demo.h5 ring:...:...
Prints a Markdown table (PRR per 50 m bin, both tools, receptions counted)."""
import argparse
import csv

import h5py
import numpy as np

BIN_M = 50.0
MAX_M = 300.0


def ns3_rows(path):
    d, ok = [], []
    with open(path) as f:
        for r in csv.DictReader(f):
            d.append(float(r["distance_m"]))
            ok.append(r["received"] == "1")
    return np.array(d), np.array(ok, dtype=bool)


def sinr_rows(path):
    with h5py.File(path, "r") as f:
        rat = f["/receptions/rat"][:]
        sel = rat == 1  # 802.11p
        return f["/receptions/distance_m"][:][sel], f["/receptions/decoded"][:][sel] == 1


def prr(d, ok):
    edges = np.arange(0, MAX_M + BIN_M, BIN_M)
    out = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        m = (d >= lo) & (d < hi)
        out.append((lo, hi, int(m.sum()), float(ok[m].mean()) if m.any() else float("nan")))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("runs", nargs="+", help="LABEL:RECEPTIONS.csv:SINR.h5")
    ap.add_argument("--png")
    a = ap.parse_args()
    rows = []
    curves = []
    for spec in a.runs:
        label, csv_path, sinr_path = spec.split(":")
        n = prr(*ns3_rows(csv_path))
        s = prr(*sinr_rows(sinr_path))
        curves.append((label, n, s))
        for (lo, hi, cn, pn), (_, _, cs, ps) in zip(n, s):
            rows.append(f"| {label} | {lo:.0f}-{hi:.0f} | {pn:.3f} ({cn}) | {ps:.3f} ({cs}) | {pn - ps:+.3f} |")
    print("| scenario | distance (m) | ns-3 PRR (receptions) | raysweep sinr PRR (receptions) | ns-3 - sinr |")
    print("|---|---|---|---|---|")
    print("\n".join(rows))
    if a.png:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, axes = plt.subplots(1, len(curves), figsize=(5 * len(curves), 3.6), squeeze=False)
        for ax, (label, n, s) in zip(axes[0], curves):
            x = [0.5 * (lo + hi) for lo, hi, _, _ in n]
            ax.plot(x, [p for *_, p in n], "o-", label="ns-3 802.11p (YansWifiPhy, NIST)")
            ax.plot(x, [p for *_, p in s], "s--", label="raysweep sinr 802.11p")
            ax.set_title(label)
            ax.set_xlabel("tx-rx distance (m)")
            ax.set_ylim(0, 1.02)
            ax.grid(alpha=0.3)
        axes[0][0].set_ylabel("PRR")
        axes[0][0].legend(fontsize=8, loc="lower left")
        fig.tight_layout()
        fig.savefig(a.png, dpi=110)


if __name__ == "__main__":
    main()

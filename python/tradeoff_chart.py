#!/usr/bin/python3
"""Chart of a `raysweep tradeoff` table: tracer cost against accuracy.

usage: tradeoff_chart.py TRADEOFF.csv OUT.png [--title TITLE]

Two panels sharing a logarithmic x axis (median wall time of one snapshot, s):
the 95th-percentile and the median per-pair path-gain error against the
reference (dB). Every setting is a labelled point; the Pareto front (column
`pareto`: not dominated in time and p95 error) is drawn as a line through its
points on the p95 panel; the reference is a star. The PNG is written to a
temporary name next to OUT.png and renamed when complete.

Exit status 2 with a one-line error when the CSV is missing or lacks a column.
Needs numpy and matplotlib (run with /usr/bin/python3 on Debian).
"""
import argparse
import csv
import math
import os
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

COLUMNS = ("label", "time_per_snapshot_s", "err_median_db", "err_p95_db", "los_agreement", "pareto")


def _float(text):
    try:
        v = float(text)
    except ValueError:
        return math.nan
    return v


def read_rows(path):
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        missing = [c for c in COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(f"{path}: missing column(s) {', '.join(missing)}")
        rows = []
        for r in reader:
            rows.append({
                "label": r["label"],
                "time": _float(r["time_per_snapshot_s"]),
                "p95": _float(r["err_p95_db"]),
                "median": _float(r["err_median_db"]),
                "los": _float(r["los_agreement"]),
                "pareto": r["pareto"].strip() == "1",
                "reference": r["label"] == "reference",
            })
    if not rows:
        raise ValueError(f"{path}: no rows")
    return rows


def draw(rows, png, title):
    fig, axes = plt.subplots(2, 1, figsize=(9, 8.5), sharex=True)
    # An error of 0 (the reference) cannot sit on a log axis; the y axes are linear.
    for ax, key, name in ((axes[0], "p95", "95th-percentile"), (axes[1], "median", "median")):
        pts = [r for r in rows if math.isfinite(r["time"]) and r["time"] > 0 and math.isfinite(r[key])]
        normal = [r for r in pts if not r["reference"]]
        front = [r for r in normal if r["pareto"]]
        other = [r for r in normal if not r["pareto"]]
        ax.scatter([r["time"] for r in other], [r[key] for r in other], s=28, color="tab:blue",
                   label="setting", zorder=3)
        ax.scatter([r["time"] for r in front], [r[key] for r in front], s=42, color="tab:red",
                   label="Pareto front (time vs p95)", zorder=4)
        ref = [r for r in pts if r["reference"]]
        ax.scatter([r["time"] for r in ref], [r[key] for r in ref], s=160, marker="*", color="black",
                   label="reference", zorder=5)
        if key == "p95":
            line = sorted([r for r in pts if r["pareto"]], key=lambda r: r["time"])
            if len(line) > 1:
                ax.step([r["time"] for r in line], [r[key] for r in line], where="post", color="tab:red",
                        linewidth=1.2, alpha=0.7, zorder=2)
        # Settings around one base point sit close together: stagger their labels.
        for i, r in enumerate(sorted(pts, key=lambda r: (r["time"], r[key]))):
            ax.annotate(r["label"], (r["time"], r[key]), textcoords="offset points", xytext=(4, 3 + 7 * (i % 3)),
                        fontsize=7, color="0.25")
        ax.set_xscale("log")
        ax.set_ylabel(f"{name} gain error (dB)")
        ax.grid(True, which="both", alpha=0.3)
        ax.set_ylim(bottom=min(0.0, ax.get_ylim()[0]))
    axes[0].legend(loc="upper right", fontsize=8)
    axes[1].set_xlabel("time per snapshot (s, median; log scale)")
    axes[0].set_title(title)
    fig.tight_layout()
    directory = os.path.dirname(os.path.abspath(png))
    fd, tmp = tempfile.mkstemp(prefix=".tradeoff-", suffix=".png", dir=directory)
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=120)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp's 0600 would stick to the renamed file
        os.replace(tmp, png)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    plt.close(fig)


def main(argv=None):
    p = argparse.ArgumentParser(description="Chart of a raysweep tradeoff table.")
    p.add_argument("csv")
    p.add_argument("png")
    p.add_argument("--title", default="raysweep tradeoff")
    a = p.parse_args(argv)
    try:
        rows = read_rows(a.csv)
    except (OSError, ValueError) as e:
        print(f"tradeoff_chart.py: {e}", file=sys.stderr)
        return 2
    draw(rows, a.png, a.title)
    print(a.png)
    return 0


if __name__ == "__main__":
    sys.exit(main())

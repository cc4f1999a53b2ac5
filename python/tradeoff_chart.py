#!/usr/bin/python3
"""Chart of a `raysweep tradeoff` table: tracer cost against accuracy.

usage: tradeoff_chart.py TRADEOFF.csv OUT.png [--title TITLE] [--coherence TRADEOFF.json OUT2.png]

Panels sharing a logarithmic x axis (median wall time of one snapshot, s):
the 95th-percentile per-pair path-gain error against the reference, the same
with gains floored at the sensitivity (what a receiver sees; column
err_p95_rx_db, with the 1 dB mark), and the median (dB; y axes linear up to
1 dB (0.1 dB for the median), logarithmic above, so a few settings far off do
not flatten the rest). Each setting is a numbered point, its label in the key
on the right (labels written beside crowded points overlapped); the Pareto
front (column `pareto`: not dominated in time and p95 error) is drawn through
its points on the p95 panel, the config's own setting (column `base`) is
ringed, and the reference is a star. With --coherence, the JSON's coherence
toggle too (each sweep's gain difference from the reference at p95 and p99
against its tracing time: coherence off, and on for each lattice_frames K).
Each PNG is written to a temporary name next to it and renamed when complete.

Exit status 2 with a one-line error when the CSV is missing or lacks a column.
Needs numpy and matplotlib (run with /usr/bin/python3 on Debian).
"""
import argparse
import csv
import json
import math
import os
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402

COLUMNS = ("label", "time_per_snapshot_s", "err_median_db", "err_p95_db", "los_agreement", "pareto")
OPTIONAL = ("err_p95_rx_db", "base")  # absent in tables of older versions


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
                "p95rx": _float(r.get("err_p95_rx_db") or "nan"),
                "base": (r.get("base") or "").strip() == "1",
            })
    if not rows:
        raise ValueError(f"{path}: no rows")
    return rows


def draw(rows, png, title):
    panels = [("p95", "95th-percentile gain error (dB)", 1.0)]
    if any(math.isfinite(r["p95rx"]) for r in rows):
        panels.append(("p95rx", "p95 error, gains floored\nat the sensitivity (dB)", 1.0))
    panels.append(("median", "median gain error (dB)", 0.1))
    fig, axes = plt.subplots(len(panels), 1, figsize=(12, 3.4 * len(panels) + 0.8), sharex=True, squeeze=False)
    axes = axes[:, 0]
    # Numbered in order of time, the same numbers in every panel and the key.
    numbered = sorted([r for r in rows if not r["reference"] and math.isfinite(r["time"]) and r["time"] > 0],
                      key=lambda r: (r["time"], r["label"]))
    number = {id(r): i + 1 for i, r in enumerate(numbered)}
    for ax, (key, name, linear_to) in zip(axes, panels):
        # An error of 0 (the reference) cannot sit on a log axis: symlog.
        pts = [r for r in rows if math.isfinite(r["time"]) and r["time"] > 0 and math.isfinite(r[key])]
        normal = [r for r in pts if not r["reference"]]
        front = [r for r in normal if r["pareto"]]
        other = [r for r in normal if not r["pareto"]]
        ax.scatter([r["time"] for r in other], [r[key] for r in other], s=28, color="tab:blue",
                   label="setting", zorder=3)
        ax.scatter([r["time"] for r in front], [r[key] for r in front], s=42, color="tab:red",
                   label="Pareto front (time vs p95)", zorder=4)
        base = [r for r in normal if r["base"]]
        ax.scatter([r["time"] for r in base], [r[key] for r in base], s=150, facecolors="none",
                   edgecolors="black", linewidths=1.3, label="the config's setting", zorder=5)
        ref = [r for r in pts if r["reference"]]
        ax.scatter([r["time"] for r in ref], [r[key] for r in ref], s=160, marker="*", color="black",
                   label="reference", zorder=5)
        if key == "p95":
            line = sorted([r for r in pts if r["pareto"]], key=lambda r: r["time"])
            if len(line) > 1:
                ax.step([r["time"] for r in line], [r[key] for r in line], where="post", color="tab:red",
                        linewidth=1.2, alpha=0.7, zorder=2)
        if key == "p95rx":
            ax.axhline(1.0, color="0.4", linestyle="--", linewidth=1, zorder=1)
            ax.annotate("1 dB", (0.005, 1.0), xycoords=("axes fraction", "data"), xytext=(0, 2),
                        textcoords="offset points", fontsize=7, color="0.3")
        # Neighbours in time alternate above and below their points.
        for r in normal:
            n = number[id(r)]
            ax.annotate(str(n), (r["time"], r[key]), textcoords="offset points", xytext=(3, 3 if n % 2 else -10),
                        fontsize=7, color="0.2")
        ax.set_xscale("log")
        ax.set_yscale("symlog", linthresh=linear_to, linscale=1.0)
        top = max([r[key] for r in pts] + [linear_to])
        ax.set_ylim(bottom=0, top=top * 1.6 if top > linear_to else linear_to * 1.15)
        ax.set_ylabel(name)
        ax.grid(True, which="both", alpha=0.3)
    # Time ticks readable on a short log axis (0.2, 0.3, 0.5, ...).
    axes[-1].xaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
    axes[-1].xaxis.set_minor_formatter(matplotlib.ticker.FuncFormatter(
        lambda v, _: f"{v:g}" if f"{v:.0e}"[0] in "235" else ""))
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time per snapshot (s, median; log scale)")
    axes[0].set_title(title)
    key_text = "\n".join(f"{number[id(r)]:>2}  {r['label']}" + ("  (front)" if r["pareto"] else "")
                         for r in numbered)
    fig.text(0.755, 0.97, key_text, va="top", ha="left", fontsize=7, family="monospace")
    fig.tight_layout(rect=(0, 0, 0.75, 1))
    save_atomic(fig, png)


def save_atomic(fig, png):
    """fig to png through a temporary name in its folder."""
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


def draw_coherence(coherence, png, title):
    """The coherence toggle's sweeps (tradeoff.json's "coherence"): the gain
    difference from the reference at p95 and p99 against the tracing time."""
    sweeps = coherence["sweeps"]
    t = [s["trace_s"] for s in sweeps]
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for key, marker in (("gain_diff_p99_db", "o-"), ("gain_diff_p95_db", "s--")):
        y = [s[key] if s[key] is not None else math.nan for s in sweeps]
        ax.plot(t, y, marker, label=key.replace("gain_diff_", "").replace("_db", ""))
        for ti, yi, s in zip(t, y, sweeps):
            ax.annotate(s["label"], (ti, yi), fontsize=8, xytext=(3, 4), textcoords="offset points")
    ax.set_xlabel(f"tracing time over {coherence['frames']} frames (s)")
    ax.set_ylabel("|gain - reference| (dB, floored at the sensitivity)")
    ax.set_title(f"{title}: coherence against {coherence['reference_rays']} rays", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_atomic(fig, png)


def main(argv=None):
    p = argparse.ArgumentParser(description="Chart of a raysweep tradeoff table.")
    p.add_argument("csv")
    p.add_argument("png")
    p.add_argument("--title", default="raysweep tradeoff")
    p.add_argument("--coherence", nargs=2, metavar=("JSON", "PNG"),
                   help="also chart the coherence toggle of this tradeoff.json into PNG")
    a = p.parse_args(argv)
    try:
        rows = read_rows(a.csv)
        coherence = None
        if a.coherence:
            with open(a.coherence[0]) as f:
                coherence = json.load(f).get("coherence")
    except (OSError, ValueError) as e:
        print(f"tradeoff_chart.py: {e}", file=sys.stderr)
        return 2
    draw(rows, a.png, a.title)
    print(a.png)
    if coherence:
        draw_coherence(coherence, a.coherence[1], a.title)
        print(a.coherence[1])
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/python3
"""Turned lattices with carried sequences ([sweep] lattice_frames = K):
speed and error against a converged reference, K as an axis.

For each city (demo: 50 frames from 60 s; ring road: 50 frames from 70 s,
when ../shared holds it; Bad Hersfeld's recipe from 180 s, when ../shared
holds it), on the same scene, vehicles and traffic (`raysweep run CITY
--until sweep`, coherence off, so that every pair is searched every frame):

  R     the converged reference: 49,152 rays a source, vehicle bundles of
        128 (8x the default's), itself on turned lattices with K = 4;
  K=k   the default tracer with lattice_frames = k, for each k of --ks;
  K=k'  the same on other turns (tracer.lattice_turn = 12345): the sweep's
        own sampling noise is K=k against K=k'.

Reported per city and K: the sweep's tracing seconds per frame and their
ratio to K=1's; the error against R of the wideband gain (gain_incoherent_db,
floored at the sensitivity floor) over the pair-frames either is above the
floor: p95, p99, share > 1 dB, the mean signed difference; the noise (K=k
against K=k'): p99 and share > 1 dB; LoS labels equal to R's; single-frame
spikes (bench/spike_bench.py's definition). With --no-diffuse every sweep
runs with tracer.diffuse = false: the specular, refracted and diffracted
part alone (the diffuse records are the frame's own lattice's at any K).

    /usr/bin/python3 bench/lattice_bench.py [--build build] [--out /tmp/raysweep-lattices]
        [--cases demo,ring,badhersfeld] [--ks 1,2,4,8,16] [--frames 50] [--no-diffuse]

Writes results.json, results.md and tradeoff.png (error p99 against tracing
time per frame relative to K = 1, one line per city) under --out; with
--chart-only, redraws the chart from --out's results.json.
"""
import argparse
import json
import os
import shutil

import h5py
import numpy as np

from coherence_bench import sweep
from spike_bench import selected_cases, spikes
REFERENCE = ["tracer.rays_per_source=49152", "tracer.vehicle_bundle_rays=128", "sweep.lattice_frames=4"]
OTHER_TURN = "tracer.lattice_turn=12345"


def floored(path):
    """Per link-frame: floored wideband gain, LoS class, the floor."""
    with h5py.File(path, "r") as f:
        radio = json.loads(f.attrs["config"])["radio"]
        floor = radio["sensitivity_dbm"] - radio["tx_power_dbm"]
        links = f["links"]
        g = np.maximum(np.nan_to_num(links["gain_incoherent_db"][:].astype(float), neginf=floor), floor)
        key = np.stack([links["frame"][:], links["tx"][:], links["rx"][:]])
        return g, key, links["los_class"][:], floor


def against(ref, path):
    gr, kr, lr, floor = floored(ref)
    g, k, lab, _ = floored(path)
    if k.shape != kr.shape or not (k == kr).all():
        raise SystemExit(f"{path} and {ref} do not hold the same link-frames")
    above = (gr > floor) | (g > floor)
    d = (g - gr)[above]
    a = np.abs(d)
    return {"pair_frames": int(a.size), "p95_db": float(np.percentile(a, 95)), "p99_db": float(np.percentile(a, 99)),
            "max_db": float(a.max()), "over_1db": float(np.mean(a > 1)), "mean_signed_db": float(d.mean()),
            "los_equal": float(np.mean(lab == lr))}


def run(rs, city, out, sets, name):
    r = sweep(rs, city, out, sets)
    kept = os.path.join(out, f"{name}.h5")
    shutil.copyfile(os.path.join(out, "dataset.h5"), kept)
    return r, kept


def chart(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for case in dict.fromkeys(r["case"] for r in rows):
        rs = [r for r in rows if r["case"] == case]
        one = next((r for r in rs if r["k"] == 1), rs[0])["trace_s_per_frame"]
        x = [r["trace_s_per_frame"] / one for r in rs]
        ax.plot(x, [r["error"]["p99_db"] for r in rs], "o-", label=f"{case} ({one:.2f} s a frame at K=1)")
        for xi, r in zip(x, rs):
            ax.annotate(f"K={r['k']}", (xi, r["error"]["p99_db"]), fontsize=8, xytext=(3, 5),
                        textcoords="offset points")
    ax.set_xlabel("tracing time per frame, relative to K = 1 (2 threads)")
    ax.set_ylabel("|gain - converged reference|, p99 (dB)")
    ax.set_title("Turned lattices: error against the converged reference")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", default=os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                                                    "build"))
    ap.add_argument("--out", default="/tmp/raysweep-lattices")
    ap.add_argument("--cases", default="demo,ring,badhersfeld")
    ap.add_argument("--ks", default="1,2,4,8,16")
    ap.add_argument("--frames", type=int, default=50)
    ap.add_argument("--no-diffuse", action="store_true")
    ap.add_argument("--chart-only", action="store_true")
    args = ap.parse_args()
    if args.chart_only:
        with open(os.path.join(args.out, "results.json")) as f:
            chart(json.load(f), os.path.join(args.out, "tradeoff.png"))
        return
    rs = os.path.join(args.build, "raysweep")
    rows = []
    for case, city, begin in selected_cases(args.cases):
        out = os.path.join(args.out, case)
        base = [f"sweep.begin_s={begin}", f"sweep.end_s={begin + args.frames / 10 - 0.05}", "sweep.coherence=false"]
        if args.no_diffuse:
            base.append("tracer.diffuse=false")
        _, ref = run(rs, city, out, base + REFERENCE, "R")
        for k in (int(x) for x in args.ks.split(",")):
            r, path = run(rs, city, out, base + [f"sweep.lattice_frames={k}"], f"K{k}")
            _, other = run(rs, city, out, base + [f"sweep.lattice_frames={k}", OTHER_TURN], f"K{k}-other")
            count, up, total = spikes(path)
            row = {"case": case, "k": k, "frames": r["frames"], "trace_s_per_frame": r["trace_s"] / r["frames"],
                   "error": against(ref, path), "noise": against(other, path), "spikes": count, "spikes_up": up,
                   "link_frames": total}
            print(json.dumps(row), flush=True)
            rows.append(row)
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump(rows, f, indent=1)
    lines = ["| city | K | tracing s / frame | vs K=1 | error p95 / p99 (dB) | > 1 dB | mean signed (dB) "
             "| noise p99 (dB) / > 1 dB | LoS = R | spikes |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        one = next((x for x in rows if x["case"] == r["case"] and x["k"] == 1), r)
        e, n = r["error"], r["noise"]
        lines.append(f"| {r['case']} | {r['k']} | {r['trace_s_per_frame']:.3f} | "
                     f"{r['trace_s_per_frame'] / one['trace_s_per_frame']:.2f} | {e['p95_db']:.2f} / {e['p99_db']:.2f} | "
                     f"{100 * e['over_1db']:.2f} % | {e['mean_signed_db']:+.3f} | {n['p99_db']:.2f} / "
                     f"{100 * n['over_1db']:.2f} % | {100 * e['los_equal']:.2f} % | {r['spikes']} |")
    with open(os.path.join(args.out, "results.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))
    if rows:
        chart(rows, os.path.join(args.out, "tradeoff.png"))


if __name__ == "__main__":
    main()

#!/usr/bin/python3
"""Turned lattices with carried sequences ([sweep] lattice_frames = K):
speed and error against a converged reference, K as an axis.

For each city (demo: 50 frames from 60 s; ring road: 50 frames from 70 s,
when ../shared holds it; Bad Hersfeld's recipe from 180 s, when ../shared
holds it), on the same scene, vehicles and traffic (`raysweep run CITY
--until sweep`, the city's own [sweep] settings otherwise):

  R     the converged reference: 49,152 rays a source, vehicle bundles of
        128 (8x the default's), itself on turned lattices with K = 4;
  K=k   the default tracer with lattice_frames = k, for each k of --ks;
  K=k'  the same on other turns (tracer.lattice_turn = 12345): the sweep's
        own sampling noise is K=k against K=k'.
  D=d   with --diffuse-frames, each K also with [sweep] diffuse_frames = d
        (the diffuse gathering shoots the lattices of the d - 1 frames
        before too), and its own K=k' twin;
  N=n   with --more-rays n, each K also with tracer.rays_per_source = n
        (one diffuse lattice): the same time spent on more rays instead;
  R'    with --reference-noise, R on other turns: the reference's own
        sampling noise (R against R'), the floor under any error against R.

Reported per city and K: the sweep's tracing seconds per frame and their
ratio to K=1's; the error against R of the wideband gain (gain_incoherent_db,
floored at the sensitivity floor) over the pair-frames either is above the
floor: p95, p99, share > 1 dB, the mean signed difference; the noise (K=k
against K=k'): p99 and share > 1 dB; LoS labels equal to R's; single-frame
spikes (bench/spike_bench.py's definition); the median frame-to-frame step
(|gain difference| between consecutive frames of a link, either above the
floor). With --no-diffuse every sweep
runs with tracer.diffuse = false: the specular, refracted and diffracted
part alone (the diffuse records are the frame's own lattice's at any K).

    /usr/bin/python3 bench/lattice_bench.py [--build build] [--out /tmp/raysweep-lattices]
        [--cases demo,ring,badhersfeld] [--ks 1,2,4,8,16] [--diffuse-frames 1,2,4]
        [--more-rays 12288] [--frames 50] [--no-diffuse] [--reference-noise] [--set TABLE.KEY=VALUE ...]

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

from sweep_runs import sweep
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


def step_median(path):
    """Median |gain difference| between consecutive frames of a link, either above the floor."""
    g, key, _, floor = floored(path)
    f, tx, rx = key
    order = np.lexsort((f, rx, tx))
    g, f, tx, rx = g[order], f[order], tx[order], rx[order]
    same = (tx[1:] == tx[:-1]) & (rx[1:] == rx[:-1]) & (f[1:] == f[:-1] + 1)
    above = (g[1:] > floor) | (g[:-1] > floor)
    return float(np.median(np.abs(np.diff(g))[same & above]))


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
        first = baseline(rows, rs[0])
        one = first["trace_s_per_frame"]
        x = [r["trace_s_per_frame"] / one for r in rs]
        ax.plot(x, [r["error"]["p99_db"] for r in rs], "o-",
                label=f"{case} ({one:.2f} s a frame at {label(first)})")
        for xi, r in zip(x, rs):
            ax.annotate(label(r), (xi, r["error"]["p99_db"]), fontsize=8, xytext=(3, 5),
                        textcoords="offset points")
    ax.set_xlabel("tracing time per frame, relative to the first setting (2 threads)")
    ax.set_ylabel("|gain - converged reference|, p99 (dB)")
    ax.set_title("Turned lattices: error against the converged reference")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def label(r):
    return (f"K={r['k']}" + (f" D={r['d']}" if r.get("d", 1) != 1 else "") +
            (f" N={r['rays']}" if r.get("rays") else ""))


def baseline(rows, r):
    """The row a row's time is compared with: K=1 D=1 of its city, else its city's first."""
    same = [x for x in rows if x["case"] == r["case"]]
    return next((x for x in same if x["k"] == 1 and x.get("d", 1) == 1 and not x.get("rays")), same[0])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", default=os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                                                    "build"))
    ap.add_argument("--out", default="/tmp/raysweep-lattices")
    ap.add_argument("--cases", default="demo,ring,badhersfeld")
    ap.add_argument("--ks", default="1,2,4,8,16")
    ap.add_argument("--diffuse-frames", default="1")
    ap.add_argument("--more-rays", type=int, default=0)
    ap.add_argument("--frames", type=int, default=50)
    ap.add_argument("--reference-noise", action="store_true")
    ap.add_argument("--no-diffuse", action="store_true")
    ap.add_argument("--chart-only", action="store_true")
    ap.add_argument("--set", action="append", default=[], metavar="TABLE.KEY=VALUE",
                    help="a setting for every sweep, as raysweep's --set (repeatable)")
    args = ap.parse_args()
    if args.chart_only:
        with open(os.path.join(args.out, "results.json")) as f:
            chart([r for r in json.load(f) if "k" in r], os.path.join(args.out, "tradeoff.png"))
        return
    rs = os.path.join(args.build, "raysweep")
    rows, noise_rows = [], []
    for case, city, begin in selected_cases(args.cases):
        out = os.path.join(args.out, case)
        base = [f"sweep.begin_s={begin}", f"sweep.end_s={begin + args.frames / 10 - 0.05}"] + args.set
        if args.no_diffuse:
            base.append("tracer.diffuse=false")
        _, ref = run(rs, city, out, base + REFERENCE, "R")
        if args.reference_noise:
            _, ref_other = run(rs, city, out, base + REFERENCE + [OTHER_TURN], "R-other")
            row = {"case": case, "reference_noise": against(ref_other, ref), "reference_step_median_db":
                   step_median(ref)}
            print(json.dumps(row), flush=True)
            noise_rows.append(row)
        for k in (int(x) for x in args.ks.split(",")):
            settings = [(d, 0) for d in (int(x) for x in args.diffuse_frames.split(","))]
            if args.more_rays:
                settings.append((1, args.more_rays))
            for d, rays in settings:
                sets = base + [f"sweep.lattice_frames={k}", f"sweep.diffuse_frames={d}"]
                if rays:
                    sets.append(f"tracer.rays_per_source={rays}")
                name = f"K{k}" + (f"D{d}" if d != 1 else "") + (f"N{rays}" if rays else "")
                r, path = run(rs, city, out, sets, name)
                _, other = run(rs, city, out, sets + [OTHER_TURN], f"{name}-other")
                count, up, total = spikes(path)
                row = {"case": case, "k": k, "d": d, "rays": rays, "frames": r["frames"],
                       "trace_s_per_frame": r["trace_s"] / r["frames"], "error": against(ref, path),
                       "noise": against(other, path), "spikes": count, "spikes_up": up, "link_frames": total,
                       "step_median_db": step_median(path)}
                print(json.dumps(row), flush=True)
                rows.append(row)
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump(rows + noise_rows, f, indent=1)
    lines = ["| city | setting | tracing s / frame | ratio | error p95 / p99 (dB) | > 1 dB | mean signed (dB) "
             "| noise p99 (dB) / > 1 dB | LoS = R | spikes | step median (dB) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        one = baseline(rows, r)
        e, n = r["error"], r["noise"]
        lines.append(f"| {r['case']} | {label(r)} | {r['trace_s_per_frame']:.3f} | "
                     f"{r['trace_s_per_frame'] / one['trace_s_per_frame']:.2f} | {e['p95_db']:.2f} / {e['p99_db']:.2f} | "
                     f"{100 * e['over_1db']:.2f} % | {e['mean_signed_db']:+.3f} | {n['p99_db']:.2f} / "
                     f"{100 * n['over_1db']:.2f} % | {100 * e['los_equal']:.2f} % | {r['spikes']} | "
                     f"{r['step_median_db']:.3f} |")
    for r in noise_rows:
        n = r["reference_noise"]
        lines.append(f"\nReference noise, {r['case']} (R against R on other turns): p95 / p99 {n['p95_db']:.2f} / "
                     f"{n['p99_db']:.2f} dB, > 1 dB {100 * n['over_1db']:.2f} %; R's step median "
                     f"{r['reference_step_median_db']:.3f} dB")
    with open(os.path.join(args.out, "results.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))
    if rows:
        chart(rows, os.path.join(args.out, "tradeoff.png"))


if __name__ == "__main__":
    main()

#!/usr/bin/python3
"""Sweep benchmark: real SUMO traffic through `raysweep sweep`, per cache mode.

Cases: the demo city (random trips; the first N vehicles of each frame, or all) and,
when ../shared holds the VaN3Twin data, its ring road with 60 and 120
vehicles (the paper's SUMO configs). Each case sweeps SECONDS of traffic at
10 Hz after a warm-up, once per mode:

  exact      d0 = 0, no cache                 (the reference)
  per_pair   d0 = 0, per-pair invalidation
  global     d0 = 0, global invalidation      (the paper's cache)
  per_pair+d0  d0 = --d0 (2 m), per-pair invalidation
  global+d0    d0 = --d0 (2 m), global invalidation  (the paper's update rule)

and reports frames/s, pair-channels/s, bytes per pair-frame, peak memory
(max RSS), cache hit ratio, and the fidelity cost against `exact`: per-link
path-gain difference (median, 95th percentile; links with paths in both),
links that gained or lost all paths, and LoS-class agreement.
Writes results.csv, results.md and results.png under --out.
"""
import argparse
import csv
import json
import os
import subprocess
import sys
import time

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHARED = os.path.join(os.path.dirname(ROOT), "shared", "data")
RING = os.path.join(SHARED, "van3twin", "DriveX-devs_VaN3Twin", "src")

MODES = [
    ("exact", 0.0, "none"),
    ("per_pair", 0.0, "per_pair"),
    ("global", 0.0, "global"),
    ("per_pair+d0", None, "per_pair"),
    ("global+d0", None, "global"),
]


def run(cmd, **kw):
    print("+", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True, **kw)


def timed(cmd):
    """Wall seconds and max RSS (MB) of a command (GNU time)."""
    t0 = time.monotonic()
    out = subprocess.run(["/usr/bin/time", "-f", "%M"] + cmd, check=True, stderr=subprocess.PIPE, text=True)
    wall = time.monotonic() - t0
    rss_kb = int(out.stderr.strip().splitlines()[-1])
    return wall, rss_kb / 1024.0


def fidelity(ref_path, path):
    with h5py.File(ref_path, "r") as a, h5py.File(path, "r") as b:
        la, lb = a["links"], b["links"]
        if la["tx"].shape != lb["tx"].shape or not (
            np.array_equal(la["tx"][:], lb["tx"][:]) and np.array_equal(la["rx"][:], lb["rx"][:])
        ):
            raise SystemExit(f"{path}: links do not align with {ref_path}")
        ga, gb = la["gain_coherent_db"][:], lb["gain_coherent_db"][:]
        both = np.isfinite(ga) & np.isfinite(gb)
        d = np.abs(ga[both] - gb[both])
        one = np.isfinite(ga) != np.isfinite(gb)
        los = np.mean(la["los_class"][:] == lb["los_class"][:])
        return {
            "gain_err_median_db": float(np.median(d)) if d.size else 0.0,
            "gain_err_p95_db": float(np.percentile(d, 95)) if d.size else 0.0,
            "links_path_presence_differs": int(one.sum()),
            "los_agreement": float(los),
        }


def dataset_stats(build, path):
    info = json.loads(subprocess.run([os.path.join(build, "raysweep"), "info", "--json", path], check=True,
                                     capture_output=True, text=True).stdout)
    with h5py.File(path, "r") as f:
        mean_vehicles = float(np.mean(f["frames/node_count"][:]))
        cached = int(np.count_nonzero(f["links/flags"][:] & 1))
    return info, mean_vehicles, cached


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "bench_sweep"))
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--warmup", type=float, default=70.0)
    # The demo city holds about 35 moving vehicles of random-trip traffic
    # (denser demand gridlocks it); the ring road carries the paper's 60 / 120.
    ap.add_argument("--cases", default="demo-20,demo-all,ring-60,ring-120")
    ap.add_argument("--modes", default=",".join(m[0] for m in MODES))
    ap.add_argument("--d0", type=float, default=2.0, help="d0 of the +d0 modes (m)")
    args = ap.parse_args()
    rs = os.path.join(args.build, "raysweep")
    os.makedirs(args.out, exist_ok=True)
    end = args.warmup + args.seconds
    demo = os.path.join(ROOT, "datasets", "demo")

    scenes = {}
    traffic = {}
    cases = []
    for case in args.cases.split(","):
        city, n = case.split("-")
        n = 0 if n == "all" else int(n)
        if city == "demo":
            if "demo" not in scenes:
                scenes["demo"] = (os.path.join(args.out, "demo_scene"), "")
                if not os.path.exists(os.path.join(scenes["demo"][0], "scene.glb")):
                    run([rs, "-q", "scene", "--no-preview", "--osm", os.path.join(demo, "kirchberg.osm"), "--net",
                         os.path.join(demo, "kirchberg.net.xml"), "--out", scenes["demo"][0]])
                tdir = os.path.join(args.out, "demo_traffic")
                if not os.path.exists(os.path.join(tdir, "fcd.xml.gz")):
                    run([rs, "-q", "traffic", "--net", os.path.join(demo, "kirchberg.net.xml"), "--trips-seed", "1",
                         "--period", "1.5", "--end", str(end + 1), "--out", tdir])
                traffic["demo"] = (os.path.join(tdir, "fcd.xml.gz"), [os.path.join(tdir, "vtypes.add.xml")])
            cases.append((case, "demo", n))
        elif city == "ring":
            sumo_dir = os.path.join(RING, "automotive", "examples", "sumo_files_v2v_map")
            if not os.path.isdir(sumo_dir):
                print(f"{case}: skipped ({sumo_dir} absent)")
                continue
            if "ring" not in scenes:
                scenes["ring"] = (os.path.join(args.out, "ring_scene"), "car_")
                if not os.path.exists(os.path.join(scenes["ring"][0], "scene.glb")):
                    run([rs, "-q", "scene", "--no-preview", "--from-mitsuba",
                         os.path.join(RING, "sionna", "scenarios", "SionnaCircleScenario", "scene.xml"),
                         "--out", scenes["ring"][0]])
            key = f"ring{n}"
            tdir = os.path.join(args.out, f"ring_traffic_{n}")
            cfg = os.path.join(sumo_dir, f"map_{n}.sumo.cfg")
            if not os.path.exists(os.path.join(tdir, "fcd.xml.gz")):
                run([rs, "-q", "traffic", "--net", os.path.join(sumo_dir, "map.net.xml"), "--sumocfg", cfg,
                     "--end", str(end + 1), "--out", tdir])
            traffic[key] = (os.path.join(tdir, "fcd.xml.gz"), [cfg])
            cases.append((case, "ring", n))

    rows = []
    wanted = args.modes.split(",")
    for case, city, n in cases:
        scene, exclude = scenes[city]
        fcd, vtypes = traffic["demo" if city == "demo" else f"ring{n}"]
        ref = None
        for name, d0, cache in MODES:
            if name not in wanted:
                continue
            d0 = args.d0 if d0 is None else d0
            cfg = os.path.join(args.out, f"{case}_{name}.toml")
            with open(cfg, "w") as f:
                f.write(f"[sweep]\nbegin_s = {args.warmup}\nend_s = {end - 0.05}\nd0_m = {d0}\ncache = \"{cache}\"\n"
                        f"block_frames = 100\n")
                if city == "demo" and n:
                    f.write(f"max_vehicles = {n}\n")
                if exclude:
                    f.write(f"exclude_objects = \"{exclude}\"\noutside = \"drop\"\n")
            out = os.path.join(args.out, f"{case}_{name}.h5")
            cmd = [rs, "-q", "sweep", "--scene", scene, "--fcd", fcd, "--config", cfg, "--out", out]
            for v in vtypes:
                cmd += ["--vtypes", v]
            print("+", " ".join(cmd), flush=True)
            wall, rss = timed(cmd)
            info, mean_vehicles, cached = dataset_stats(args.build, out)
            row = {
                "case": case, "mode": name, "d0_m": d0, "cache": cache,
                "frames": info["frames"], "mean_vehicles": round(mean_vehicles, 1), "links": info["links"],
                "wall_s": round(wall, 2), "frames_per_s": round(info["frames"] / wall, 2),
                "pair_channels_per_s": round(info["links"] / wall), "ms_per_frame": round(1e3 * wall / info["frames"], 1),
                "bytes_per_pair_frame": round(info["bytes_per_link"], 1), "peak_rss_mb": round(rss, 1),
                "cache_hit_ratio": round(cached / max(1, info["links"]), 4),
            }
            if name == "exact":
                ref = out
            elif ref:
                row.update(fidelity(ref, out))
            rows.append(row)
            print(json.dumps(row), flush=True)

    keys = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    with open(os.path.join(args.out, "results.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    cols = ["case", "mode", "mean_vehicles", "frames_per_s", "pair_channels_per_s", "bytes_per_pair_frame",
            "peak_rss_mb", "cache_hit_ratio", "gain_err_median_db", "gain_err_p95_db", "los_agreement"]
    with open(os.path.join(args.out, "results.md"), "w") as f:
        f.write("| " + " | ".join(cols) + " |\n|" + "---|" * len(cols) + "\n")
        for r in rows:
            f.write("| " + " | ".join(str(r.get(c, "")) for c in cols) + " |\n")
    print(open(os.path.join(args.out, "results.md")).read())

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
    names = [m[0] for m in MODES if m[0] in wanted]
    case_names = [c[0] for c in cases]
    width = 0.8 / max(1, len(names))
    for k, name in enumerate(names):
        fps = [next((r["frames_per_s"] for r in rows if r["case"] == c and r["mode"] == name), 0) for c in case_names]
        hit = [next((r["cache_hit_ratio"] for r in rows if r["case"] == c and r["mode"] == name), 0) for c in case_names]
        x = np.arange(len(case_names)) + k * width
        ax[0].bar(x, fps, width, label=name)
        ax[1].bar(x, hit, width, label=name)
    for a, t in zip(ax, ["frames per second", "cache hit ratio"]):
        a.set_xticks(np.arange(len(case_names)) + 0.4 - width / 2)
        a.set_xticklabels(case_names)
        a.set_title(t)
        a.grid(axis="y", alpha=0.3)
    ax[0].legend()
    fig.suptitle(f"raysweep sweep: {args.seconds:g} s of SUMO traffic at 10 Hz")
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "results.png"), dpi=120)
    print("wrote", os.path.join(args.out, "results.csv"), "results.md", "results.png")


if __name__ == "__main__":
    sys.exit(main())

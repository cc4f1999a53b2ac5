#!/usr/bin/python3
"""Frame-to-frame coherence: speed and error budget.

For each city, the sweep stage of `raysweep run CITY --until sweep` in one
session with `--set sweep.coherence=false` and with `=true` under each rule of
--variants (the default rule; `every-pair`: every pair re-solved that can be;
`every-pair-no-net`: the same without the interval and margin; `lattice`: not
a rule but the from-scratch sweep on other lattice turns, tracer.lattice_turn =
12345, the reference's own sampling noise), the
from-scratch run first or last alternating per city, on the same scene,
vehicles and traffic:

  sweep wall time and tracing time of each, and their ratio; the share of
  pair-frames searched (the rest re-solved) and the re-solve's time;
  the error budget of the coherent dataset against the from-scratch one:
  the same links in every frame; LoS class and Fresnel class agreement over
  pair-frames; |wideband gain difference| (gain_incoherent_db, both floored
  at the sensitivity floor, sensitivity - tx power) p50 / p99 / max.

With --explain, every sweep stores its paths, and each variant's pair-frames
more than 1 dB weaker than the reference are explained: the reference's paths
the variant does not have (matched by interaction types and objects), by kind
(S specular, R refraction, D diffuse, X diffraction; s static, v vehicle), as
shares of the missing power and as the strongest missing path.

With --scaling, the per-frame cost against the number of vehicles: the first
N vehicles of each frame (`sweep.max_vehicles`) over --scaling-frames frames,
both modes, on the demo city and (when ../shared holds it) the ring road
(120 vehicles: its map_120 scenario).

    /usr/bin/python3 bench/coherence_bench.py                    # demo 300 frames, ring 600
    /usr/bin/python3 bench/coherence_bench.py --cases demo --demo-frames 50 --variants default,every-pair,every-pair-no-net
    /usr/bin/python3 bench/coherence_bench.py --cases demo --demo-frames 50 --variants lattice,every-pair --explain
    /usr/bin/python3 bench/coherence_bench.py --scaling 5,10,20,40,60,120

Writes results.json, results.md and (with --scaling) scaling.png under --out.
"""
import argparse
import json
import os
import re
import shutil
import subprocess
import time

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RING = os.path.join(ROOT, "datasets", "van3twin-ring", "city.toml")
DEMO = os.path.join(ROOT, "datasets", "demo", "city.toml")
RING_SUMO = os.path.join(os.path.dirname(ROOT), "shared", "data", "van3twin", "DriveX-devs_VaN3Twin", "src",
                         "automotive", "examples", "sumo_files_v2v_map")


def sweep(rs, city, out, sets):
    """Runs the city up to its sweep; the sweep's wall and tracing seconds."""
    stamp = os.path.join(out, ".stamps", "sweep.json")  # the sweep runs again every time, the stages before it not
    if os.path.exists(stamp):
        os.remove(stamp)
    cmd = [rs, "run", city, "--out", out, "--until", "sweep"]
    for s in sets:
        cmd += ["--set", s]
    print("+", " ".join(cmd), flush=True)
    t0 = time.monotonic()
    p = subprocess.run(cmd, check=True, capture_output=True, text=True)
    log = p.stdout + p.stderr
    m = re.search(r"swept (\d+) frames .*?, (\d+) pair-channels \((\d+) traced, (\d+) of them searched.*? in "
                  r"([0-9.]+) s \(([0-9.]+) s tracing, ([0-9.]+) s of it re-solving[;)]", log)
    if not m:
        raise SystemExit(f"no sweep summary in the log of {' '.join(cmd)}:\n{log[-2000:]}")
    return {"frames": int(m.group(1)), "traced": int(m.group(3)), "searched": int(m.group(4)),
            "sweep_s": float(m.group(5)), "trace_s": float(m.group(6)), "resolve_s": float(m.group(7)),
            "process_s": time.monotonic() - t0}


def budget(ref_path, path, floor_db):
    with h5py.File(ref_path, "r") as a, h5py.File(path, "r") as b:
        la, lb = a["links"], b["links"]
        same = all(np.array_equal(la[k][:], lb[k][:]) for k in ("frame", "tx", "rx"))
        if not same:
            return {"same_links": False}
        ga = np.maximum(np.nan_to_num(la["gain_incoherent_db"][:].astype(float), neginf=floor_db), floor_db)
        gb = np.maximum(np.nan_to_num(lb["gain_incoherent_db"][:].astype(float), neginf=floor_db), floor_db)
        d = np.abs(ga - gb)
        return {
            "same_links": True,
            "pair_frames": int(d.size),
            "los_agreement": float(np.mean(la["los_class"][:] == lb["los_class"][:])),
            "fresnel_agreement": float(np.mean(la["los_class_fresnel"][:] == lb["los_class_fresnel"][:])),
            "gain_diff_p50_db": float(np.percentile(d, 50)),
            "gain_diff_p99_db": float(np.percentile(d, 99)),
            "gain_diff_max_db": float(d.max()),
            "pair_frames_over_1db": int(np.count_nonzero(d > 1)),
        }


def path_kind(types, objects, static_count):
    """A path's interactions as a word: S(pecular), R(efraction), D(iffuse),
    X (diffraction), each on s(tatic) or v(ehicle); 'direct' for none."""
    if not len(types):
        return "direct"
    return "-".join("SRDX"[t - 1] + ("v" if o >= static_count else "s") for t, o in zip(types, objects))


def missing_paths(ref_path, path, floor_db, worse_db=1.0):
    """On the pair-frames whose gain is more than `worse_db` below the
    reference's, the paths the reference has and the coherent sweep does not
    (matched by their interaction types and objects), by kind: the share of
    the missing power each kind carries, and how often it is the strongest
    missing path (needs store = "paths")."""
    def load(f):
        links, paths, inter = f["links"], f["paths"], f["interactions"]
        return {"g": links["gain_incoherent_db"][:].astype(float), "off": links["path_offset"][:],
                "n": links["path_count"][:], "a": paths["a"][:], "ic": paths["interaction_count"][:],
                "io": paths["interaction_offset"][:], "t": inter["type"][:], "o": inter["object"][:]}

    with h5py.File(ref_path, "r") as fa, h5py.File(path, "r") as fb:
        static_count = len(fa["objects/name"]) - len(fa["nodes/id"])
        a, b = load(fa), load(fb)
    ga = np.maximum(np.nan_to_num(a["g"], neginf=floor_db), floor_db)
    gb = np.maximum(np.nan_to_num(b["g"], neginf=floor_db), floor_db)
    worse = np.flatnonzero(gb - ga < -worse_db)

    def sig(d, p):
        o, n = d["io"][p], d["ic"][p]
        return tuple(d["t"][o:o + n].tolist()), tuple(d["o"][o:o + n].tolist())

    power, strongest = {}, {}
    missing_total = 0.0
    for link in worse:
        ref = {}
        for p in range(a["off"][link], a["off"][link] + a["n"][link]):
            key = sig(a, p)
            ref[key] = ref.get(key, 0.0) + float(abs(a["a"][p]) ** 2)
        have = {sig(b, p) for p in range(b["off"][link], b["off"][link] + b["n"][link])}
        gone = {k: w for k, w in ref.items() if k not in have}
        if not gone:
            continue
        for (types, objects), w in gone.items():
            kind = path_kind(types, objects, static_count)
            power[kind] = power.get(kind, 0.0) + w / sum(ref.values())
        missing_total += sum(gone.values()) / sum(ref.values())
        top = max(gone, key=gone.get)
        kind = path_kind(*top, static_count)
        strongest[kind] = strongest.get(kind, 0) + 1
    kinds = sorted(power, key=power.get, reverse=True)
    return {"worse_db": worse_db, "pair_frames": int(worse.size),
            "kinds": [{"kind": k, "power_share": round(power[k] / max(missing_total, 1e-30), 3),
                       "strongest": strongest.get(k, 0)} for k in kinds[:12]]}


def floor_of(path):
    """sensitivity - tx power of the [radio] the dataset was swept with."""
    with h5py.File(path, "r") as f:
        radio = json.loads(f.attrs["config"])["radio"]
    return radio["sensitivity_dbm"] - radio["tx_power_dbm"]


# The coherence rules compared (--variants): the default rule, and the
# re-solve of every pair it can (thresholds off) with the safety net's
# interval and margin, and without them.
VARIANTS = {
    "default": [],
    # Not a coherence rule: the from-scratch sweep on other lattice turns,
    # the reference's own sampling noise (6143 rays instead of 6144 would be
    # nearly the same directions).
    "lattice": ["sweep.coherence=false", "tracer.lattice_turn=12345"],
    "every-pair": ["sweep.coherence_volatile_share=1", "sweep.coherence_direct_share=0",
                   "sweep.coherence_clear_zone_only=false"],
    "every-pair-no-net": ["sweep.coherence_volatile_share=1", "sweep.coherence_direct_share=0",
                          "sweep.coherence_clear_zone_only=false", "sweep.coherence_frames=100000",
                          "sweep.coherence_margin_m=1e9"],
}


def compare_case(rs, name, city, out, extra, first_on, variants, explain=False):
    """The sweep from scratch, then each variant with coherence on (or the
    reverse order): times, searched share and the error budget of each."""
    os.makedirs(out, exist_ok=True)
    runs = [("off", ["sweep.coherence=false"])] + [(v, ["sweep.coherence=true"] + VARIANTS[v]) for v in variants]
    if explain:
        runs = [(mode, sets + ['sweep.store="paths"']) for mode, sets in runs]
    if first_on:
        runs = runs[1:] + runs[:1]
    result = {}
    for mode, sets in runs:
        r = sweep(rs, city, out, extra + sets)
        shutil.move(os.path.join(out, "dataset.h5"), os.path.join(out, f"coherence_{mode}.h5"))
        result[mode] = r
    rows = []
    off = result["off"]
    for v in variants:
        on = result[v]
        row = {"case": name, "rule": v, "frames": on["frames"], "sweep_s_off": off["sweep_s"],
               "sweep_s_on": on["sweep_s"], "speedup_sweep": round(off["sweep_s"] / on["sweep_s"], 2),
               "trace_s_off": off["trace_s"], "trace_s_on": on["trace_s"], "resolve_s_on": on["resolve_s"],
               "speedup_tracing": round(off["trace_s"] / on["trace_s"], 2),
               "searched_share": round(on["searched"] / max(1, on["traced"]), 3)}
        ref = os.path.join(out, "coherence_off.h5")
        row.update(budget(ref, os.path.join(out, f"coherence_{v}.h5"), floor_of(ref)))
        if explain:
            row["missing"] = missing_paths(ref, os.path.join(out, f"coherence_{v}.h5"), floor_of(ref))
        print(json.dumps(row), flush=True)
        rows.append(row)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "bench_coherence"))
    ap.add_argument("--cases", default="demo,ring")
    ap.add_argument("--ring-frames", type=int, default=600)
    ap.add_argument("--demo-frames", type=int, default=300)
    ap.add_argument("--variants", default="default", help="rules to compare: " + ", ".join(VARIANTS))
    ap.add_argument("--explain", action="store_true",
                    help="store paths and attribute each rule's missing power to kinds of paths")
    ap.add_argument("--scaling", default="", help="vehicle counts for the per-frame cost curve (e.g. 5,10,20)")
    ap.add_argument("--scaling-frames", type=int, default=20)
    ap.add_argument("--set", action="append", default=[], metavar="TABLE.KEY=VALUE",
                    help="a setting for every sweep of every case (repeatable), e.g. tracer.vehicle_bundles=false")
    args = ap.parse_args()
    rs = os.path.join(args.build, "raysweep")
    os.makedirs(args.out, exist_ok=True)
    have_ring = os.path.isdir(RING_SUMO)
    rows = []
    variants = args.variants.split(",")
    for k, case in enumerate(args.cases.split(",")):
        if case == "demo":
            end = 60 + args.demo_frames / 10 - 0.05
            rows += compare_case(rs, "demo", DEMO, os.path.join(args.out, "demo"), [f"sweep.end_s={end}"] + args.set,
                                 k % 2 == 0, variants, args.explain)
        elif case == "ring" and have_ring:
            end = 70 + args.ring_frames / 10 - 0.05
            rows += compare_case(rs, "ring", RING, os.path.join(args.out, "ring"), [f"sweep.end_s={end}"] + args.set,
                                 k % 2 == 0, variants, args.explain)
        elif case == "ring":
            print("ring: skipped (../shared/data absent)")

    scaling = []
    for n in [int(x) for x in args.scaling.split(",") if x]:
        cities = [("demo", DEMO, [f"sweep.end_s={60 + args.scaling_frames / 10 - 0.05}"])]
        if have_ring:
            cfg = os.path.join(RING_SUMO, "map_120.sumo.cfg" if n > 60 else "map_60.sumo.cfg")
            cities.append(("ring", RING, [f"sweep.end_s={70 + args.scaling_frames / 10 - 0.05}",
                                          f"traffic.sumocfg=\"{cfg}\""]))
        for name, city, sets in cities:
            out = os.path.join(args.out, f"scaling_{name}_{'120' if name == 'ring' and n > 60 else 'base'}")
            row = {"case": name, "vehicles": n}
            for on in (False, True):
                r = sweep(rs, city, out, sets + args.set + [f"sweep.max_vehicles={n}",
                                                 f"sweep.coherence={'true' if on else 'false'}"] +
                          (VARIANTS[variants[0]] if on else []))
                row[f"ms_per_frame_{'on' if on else 'off'}"] = round(1e3 * r["trace_s"] / r["frames"], 1)
            print(json.dumps(row), flush=True)
            scaling.append(row)

    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump({"comparisons": rows, "scaling": scaling}, f, indent=1)
    cols = ["case", "rule", "frames", "searched_share", "sweep_s_off", "sweep_s_on", "speedup_sweep", "trace_s_off",
            "trace_s_on", "resolve_s_on", "speedup_tracing", "los_agreement", "fresnel_agreement", "gain_diff_p99_db",
            "gain_diff_max_db"]
    with open(os.path.join(args.out, "results.md"), "w") as f:
        f.write("| " + " | ".join(cols) + " |\n|" + "---|" * len(cols) + "\n")
        for r in rows:
            f.write("| " + " | ".join(str(r.get(c, "")) for c in cols) + " |\n")
        for r in rows:
            if "missing" not in r:
                continue
            m = r["missing"]
            f.write(f"\n{r['case']}, {r['rule']}: paths missing on the {m['pair_frames']} pair-frames more than "
                    f"{m['worse_db']} dB weaker than the reference\n\n| kind | share of the missing power | "
                    "strongest missing path |\n|---|---|---|\n")
            for k in m["kinds"]:
                f.write(f"| {k['kind']} | {k['power_share']:.3f} | {k['strongest']} |\n")
        if scaling:
            f.write("\n| city | vehicles | ms/frame coherence off | on | ratio |\n|---|---|---|---|---|\n")
            for r in scaling:
                ratio = r["ms_per_frame_off"] / max(r["ms_per_frame_on"], 1e-9)
                f.write(f"| {r['case']} | {r['vehicles']} | {r['ms_per_frame_off']} | {r['ms_per_frame_on']} | "
                        f"{ratio:.2f} |\n")
    print(open(os.path.join(args.out, "results.md")).read())
    if scaling:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(6, 4))
        for name in ("demo", "ring"):
            pts = [r for r in scaling if r["case"] == name]
            if not pts:
                continue
            n = [r["vehicles"] for r in pts]
            ax.loglog(n, [r["ms_per_frame_off"] for r in pts], "o--", label=f"{name}, coherence off")
            ax.loglog(n, [r["ms_per_frame_on"] for r in pts], "o-", label=f"{name}, coherence on")
        ax.set_xlabel("vehicles")
        ax.set_ylabel("tracing ms per frame")
        ax.set_title(f"Sweep tracing cost per frame ({args.scaling_frames} frames at 10 Hz)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        fig.tight_layout()
        fig.savefig(os.path.join(args.out, "scaling.png"), dpi=120)


if __name__ == "__main__":
    main()

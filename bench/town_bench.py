#!/usr/bin/python3
"""A real town's snapshot cost against its area and its vehicles (Bad
Hersfeld, from ../shared/data), for one build or two side by side.

The town's recipe (datasets/badhersfeld/city.toml) keeps a 600 m box around the
old town; here the box is also grown around the same centre (--boxes, metres
of side), and each box traced as one snapshot of the recipe's own SUMO
traffic at --time: the first N vehicles of the FCD inside the box (--vehicles;
fewer when the box holds fewer), with every tracer setting of the recipe.

For every (box, N) each build (--builds, the first one's `raysweep` also
prepares the inputs) traces the snapshot --rounds times, alternating, and the
medians are reported: the process's wall seconds, the tracing seconds it
logs, ms per pair and per pair above the sensitivity floor (does the cost
follow all pairs or the pairs that matter?), and, with two builds, the
second against the first on the same snapshot: the ratio of their tracing
times (1 / 0: how much faster the first is), label differences, pairs that
cross the floor, and the gain difference above it (p99, max: 0 when the two
builds find the same paths).

  /usr/bin/python3 bench/town_bench.py [--builds build[,OTHER_BUILD]] [--out /tmp/raysweep-town]
      [--boxes 600,1200] [--vehicles 20,42,80,120] [--time 180] [--rounds 3] [--threads N]
      [--set TABLE.KEY=VALUE ...]

Writes results.json, results.md and cost.png under --out. The first run of a
box builds its scene, and the first run of the bench the recipe's traffic
(SUMO over the whole town: minutes).
"""
import argparse
import gzip
import json
import math
import os
import re
import statistics
import subprocess
import sys
import time
import xml.etree.ElementTree as ET

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RECIPE = os.path.join(ROOT, "datasets", "badhersfeld", "city.toml")
DATA = os.path.join(os.path.dirname(ROOT), "shared", "data", "dlr-sumo-scenarios-badhersfeld")
OSM = os.path.join(DATA, "osm_bbox.osm.xml.gz")
NET = os.path.join(DATA, "osm_edited.net.xml.gz")
CENTRE = (6700.0, 7850.0)  # the recipe's box [6400, 7550, 7000, 8150]


def run(cmd, env=None):
    r = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if r.returncode != 0:
        sys.exit(f"failed ({r.returncode}): {' '.join(cmd)}\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}")
    return r.stdout + r.stderr


def box_of(side):
    h = side / 2
    return [CENTRE[0] - h, CENTRE[1] - h, CENTRE[0] + h, CENTRE[1] + h]


def traffic(raysweep, work):
    """The recipe's traffic (its scene stage too: `run` starts there)."""
    out = os.path.join(work, "recipe")
    fcd = os.path.join(out, "traffic", "fcd.xml.gz")
    if not os.path.exists(fcd):
        run([raysweep, "-q", "run", RECIPE, "--until", "traffic", "--out", out])
    return fcd


def scene(raysweep, work, side):
    """The town's scene clipped to the box."""
    out = os.path.join(work, f"scene-{side}")
    if not os.path.exists(os.path.join(out, "scene.glb")):
        cfg = os.path.join(work, f"scene-{side}.toml")
        with open(cfg, "w") as f:
            f.write("[scene]\nclip_bbox = [%s]\n" % ", ".join(str(v) for v in box_of(side)))
        run([raysweep, "-q", "scene", "--osm", OSM, "--net", NET, "--config", cfg, "--no-preview", "--out", out])
    return out


def poses(fcd, t, box, count, path):
    """The first `count` vehicles of the FCD inside the box at time t (front-bumper poses)."""
    x0, y0, x1, y1 = box
    rows = []
    with gzip.open(fcd) as f:
        for _, el in ET.iterparse(f):
            if el.tag != "timestep":
                continue
            if abs(float(el.get("time")) - t) < 1e-6:
                for v in el.findall("vehicle"):
                    x, y = float(v.get("x")), float(v.get("y"))
                    if x0 <= x <= x1 and y0 <= y <= y1 and len(rows) < count:
                        rows.append(f"{v.get('id')},{v.get('type')},{x},{y},{v.get('angle')},{v.get('speed')}")
                break
            el.clear()
    with open(path, "w") as f:
        f.write("id,class,x,y,heading_deg,speed_mps\n" + "\n".join(rows) + "\n")
    return len(rows)


def trace(raysweep, scene_dir, poses_path, out, threads, sets=()):
    """Wall seconds of the process and the tracing seconds it logs."""
    if os.path.exists(out):
        os.remove(out)
    cmd = [raysweep, "trace", "--scene", scene_dir, "--poses", poses_path, "--config", RECIPE, "--out", out]
    for s in sets:
        cmd += ["--set", s]
    if threads:
        cmd[1:1] = ["-j", str(threads)]
    t0 = time.perf_counter()
    log = run(cmd)
    wall = time.perf_counter() - t0
    m = re.search(r"paths in ([0-9.]+) ms", log)
    if not m:
        sys.exit("no tracing time in the log:\n" + log)
    return wall, float(m.group(1)) / 1e3


def gains(path):
    with open(path) as f:
        doc = json.load(f)
    out = {}
    for p in doc["pairs"]:
        g = p["path_gain_incoherent_db"]
        out[(p["tx"], p["rx"])] = (p["los_class"], p["los_class_fresnel"], -math.inf if g is None else g)
    return out


def accuracy(ref, test, floor_db):
    """One build's snapshot (test) against another's (ref)."""
    r, t = gains(ref), gains(test)
    labels = sum(r[k][:2] != t[k][:2] for k in r)
    above_r = {k for k in r if r[k][2] >= floor_db}
    above_t = {k for k in t if t[k][2] >= floor_db}
    err = sorted(abs(t[k][2] - r[k][2]) for k in above_r & above_t)
    pct = lambda q: err[min(len(err) - 1, int(math.ceil(q * len(err))) - 1)] if err else 0.0
    return {"pairs": len(r), "above_floor": len(above_r), "label_differences": labels,
            "above_floor_only_ref": len(above_r - above_t), "above_floor_only_test": len(above_t - above_r),
            "gain_err_p99_db": pct(0.99), "gain_err_max_db": err[-1] if err else 0.0}


def chart(result, path):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for side, cases in result["boxes"].items():
        for k, build in enumerate(result["builds"]):
            xs = [c["vehicles"] for c in cases]
            name = f"{side} m" + (f", {build}" if len(result["builds"]) > 1 else "")
            ax[0].plot(xs, [c["runs"][k]["tracing_s"] for c in cases], "o-", label=name)
            ax[1].plot(xs, [c["runs"][k]["ms_per_pair"] for c in cases], "o-", label=name)
    ax[0].set_xlabel("vehicles")
    ax[0].set_ylabel("tracing s (median)")
    ax[1].set_xlabel("vehicles")
    ax[1].set_ylabel("ms per pair")
    ax[0].legend(fontsize=7)
    fig.suptitle("Bad Hersfeld snapshot cost by box and vehicles")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def measure(builds, scene_dir, pp, out_prefix, rounds, threads, sets=()):
    """Each build's snapshot `rounds` times, alternating: medians and the last outputs."""
    runs = [[] for _ in builds]
    for r in range(rounds):
        order = range(len(builds)) if r % 2 == 0 else reversed(range(len(builds)))
        for k in order:
            runs[k].append(trace(os.path.join(builds[k], "raysweep"), scene_dir, pp, f"{out_prefix}-{k}.json", threads,
                                 sets))
    return runs


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--builds", default=os.path.join(ROOT, "build"), help="build folders, comma-separated (1 or 2)")
    ap.add_argument("--out", default="/tmp/raysweep-town")
    ap.add_argument("--boxes", default="600,1200")
    ap.add_argument("--vehicles", default="20,42,80,120")
    ap.add_argument("--time", type=float, default=180)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--threads", type=int, default=0, help="raysweep -j (0: all cores)")
    ap.add_argument("--floor-db", type=float, default=-123.0, help="sensitivity - tx power of the recipe's radio")
    ap.add_argument("--set", action="append", default=[], metavar="TABLE.KEY=VALUE",
                    help="a setting for every trace, as raysweep's --set (repeatable)")
    a = ap.parse_args()
    if not os.path.exists(OSM):
        print(f"town_bench: skipped: {OSM} is absent (../shared/data)")
        return
    builds = a.builds.split(",")
    raysweep = os.path.join(builds[0], "raysweep")
    os.makedirs(a.out, exist_ok=True)
    fcd = traffic(raysweep, a.out)
    result = {"time_s": a.time, "rounds": a.rounds, "threads": a.threads, "builds": builds, "boxes": {}}
    cols = " | ".join(f"tracing s {k} | ms/pair {k} | ms/pair above floor {k}" for k in range(len(builds)))
    lines = [f"| box | vehicles | pairs | above floor | {cols} |" + (" 1 / 0 | labels, floor, err p99 / max dB |"
                                                                  if len(builds) > 1 else ""),
             "|---" * (4 + 3 * len(builds) + (2 if len(builds) > 1 else 0)) + "|"]
    for side in [int(s) for s in a.boxes.split(",")]:
        scene_dir = scene(raysweep, a.out, side)
        cases = []
        for want in [int(v) for v in a.vehicles.split(",")]:
            pp = os.path.join(a.out, f"poses-{side}-{want}.csv")
            n = poses(fcd, a.time, box_of(side), want, pp)
            if cases and n == cases[-1]["vehicles"]:
                continue  # the box holds no more vehicles
            prefix = os.path.join(a.out, f"trace-{side}-{n}")
            runs = measure(builds, scene_dir, pp, prefix, a.rounds, a.threads, a.set)
            pairs = n * (n - 1) // 2
            above = accuracy(f"{prefix}-0.json", f"{prefix}-0.json", a.floor_db)["above_floor"]
            case = {"vehicles": n, "pairs": pairs, "above_floor": above, "runs": []}
            for k in range(len(builds)):
                tr = statistics.median(t for _, t in runs[k])
                case["runs"].append({"wall_s": statistics.median(w for w, _ in runs[k]), "tracing_s": tr,
                                     "ms_per_pair": 1e3 * tr / max(1, pairs),
                                     "ms_per_pair_above_floor": 1e3 * tr / max(1, above),
                                     "rounds": [list(x) for x in runs[k]]})
            row = f"| {side} m | {n} | {pairs} | {above} | " + " | ".join(
                f"{r['tracing_s']:.2f} | {r['ms_per_pair']:.2f} | {r['ms_per_pair_above_floor']:.2f}" for r in case["runs"])
            if len(builds) > 1:
                acc = accuracy(f"{prefix}-0.json", f"{prefix}-1.json", a.floor_db)
                case["accuracy"] = acc
                case["ratio"] = case["runs"][1]["tracing_s"] / case["runs"][0]["tracing_s"]
                row += (f" | {case['ratio']:.2f} | {acc['label_differences']}, "
                        f"{acc['above_floor_only_ref'] + acc['above_floor_only_test']}, "
                        f"{acc['gain_err_p99_db']:.3f} / {acc['gain_err_max_db']:.3f}")
            lines.append(row + " |")
            print(lines[-1], flush=True)
            cases.append(case)
        result["boxes"][str(side)] = cases
    with open(os.path.join(a.out, "results.json"), "w") as f:
        json.dump(result, f, indent=1)
    with open(os.path.join(a.out, "results.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    chart(result, os.path.join(a.out, "cost.png"))
    print("\n".join(lines))


if __name__ == "__main__":
    main()

#!/usr/bin/python3
"""One-shot traces as a user runs them: `raysweep trace` as a whole process
against the tracing inside it.

Cases (each run --rounds times, alternating, medians reported; the first demo
trace runs once more before them with the scene's cache/ of model tables
removed, as a user's first trace of a scene):
  demo/60        60 vehicles on the demo city (poses: place_on_lanes seed 1,
                 passenger:truck:bus 8:1:1, the built-in models: exactly the
                 vehicles of bench_tracer's BM_Snapshot/demo/60/3), default
                 settings, JSON and HDF5 output; against the steady-state
                 snapshot BM_Snapshot/demo/60/3 of bench_tracer, run in the
                 same rounds.
  ring/60-static 60 antennas 1.5 m above the VaN3Twin ring road's lanes (when
                 ../shared is present), specular + refraction only (no
                 diffraction, no diffuse), JSON and HDF5 output; against its
                 own tracing time.

For each: the process's wall time, the tracing time it logs (trace_snapshot),
and the ratios. Each run writes a new file (the old one removed before the
clock starts), and the ring road's JSON once more over the previous file. Writes results.json and results.md under --out.

  /usr/bin/python3 bench/trace_overhead.py [--build build] [--rounds 3] [--out /tmp/raysweep-trace-overhead]
"""
import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RING_NET = os.path.join(os.path.dirname(ROOT), "shared", "data", "van3twin", "DriveX-devs_VaN3Twin", "src",
                        "automotive", "examples", "sumo_files_v2v_map", "map.net.xml")
RING_XML = os.path.join(os.path.dirname(ROOT), "shared", "data", "van3twin", "DriveX-devs_VaN3Twin", "src",
                        "sionna", "scenarios", "SionnaCircleScenario", "scene.xml")


def run(cmd, **kw):
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        sys.exit(f"failed ({r.returncode}): {' '.join(cmd)}\n{r.stdout}\n{r.stderr}")
    return r.stdout + r.stderr


def timed_trace(raysweep, args, replace=False):
    """Wall seconds of the whole process and the tracing ms it logs. The
    output (after --out) is removed first unless `replace`: replacing a file
    costs the rename the new file's block allocation on ext4 (auto_da_alloc)."""
    out_file = args[args.index("--out") + 1]
    if not replace and os.path.exists(out_file):
        os.remove(out_file)
    t0 = time.perf_counter()
    out = run([raysweep, "trace"] + args)
    wall = time.perf_counter() - t0
    m = re.search(r"paths in ([0-9.]+) ms", out)
    if not m:
        sys.exit("no tracing time in the log:\n" + out)
    return wall, float(m.group(1)) / 1e3


def steady_snapshot(bench, name):
    """bench_tracer's median wall seconds of BM_Snapshot/NAME/60/3 (3 repetitions)."""
    out = run([bench, f"--benchmark_filter=BM_Snapshot/{name}/60/3/", "--benchmark_repetitions=3",
               "--benchmark_format=json", "--benchmark_report_aggregates_only=true"])
    data = json.loads(out[out.index("{"):])
    for b in data["benchmarks"]:
        if b.get("aggregate_name") == "median":
            return b["real_time"] / 1e3 if b["time_unit"] == "ms" else b["real_time"] / 1e9
    sys.exit("no median in bench_tracer's output")


def prepare(raysweep, work):
    """The demo scene and poses; the ring road's scene and 60 antennas on its lanes."""
    demo = os.path.join(ROOT, "datasets", "demo")
    if not os.path.exists(os.path.join(work, "demo", "scene.glb")):
        run([raysweep, "-q", "scene", "--osm", os.path.join(demo, "kirchberg.osm"), "--net",
             os.path.join(demo, "kirchberg.net.xml"), "--no-preview", "--out", os.path.join(work, "demo")])
    run([raysweep, "-q", "poses", "--net", os.path.join(demo, "kirchberg.net.xml"), "--count", "60", "--seed", "1",
         "--classes", "passenger:8,truck:1,bus:1", "--out", os.path.join(work, "demo-poses.csv")])
    if not os.path.exists(RING_XML):
        return False
    if not os.path.exists(os.path.join(work, "ring", "scene.glb")):
        run([raysweep, "-q", "scene", "--from-mitsuba", RING_XML, "--out", os.path.join(work, "ring")])
    poses = os.path.join(work, "ring-poses.csv")
    run([raysweep, "-q", "poses", "--net", RING_NET, "--count", "60", "--seed", "1", "--out", poses])
    with open(poses) as f, open(os.path.join(work, "ring-nodes.csv"), "w") as out:
        for line in f:
            p = line.strip().split(",")
            if p[0] != "id":
                out.write(f"{p[0]},{p[2]},{p[3]},1.5\n")
    with open(os.path.join(work, "gos.toml"), "w") as f:
        f.write("[tracer]\ndiffraction = false\ndiffuse = false\n")
    return True


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--out", default="/tmp/raysweep-trace-overhead")
    a = ap.parse_args()
    raysweep = os.path.join(a.build, "raysweep")
    bench = os.path.join(a.build, "bench", "bench_tracer")
    os.makedirs(a.out, exist_ok=True)
    ring = prepare(raysweep, a.out)
    demo_args = ["--scene", os.path.join(a.out, "demo"), "--poses", os.path.join(a.out, "demo-poses.csv")]
    ring_args = ["--scene", os.path.join(a.out, "ring"), "--nodes", os.path.join(a.out, "ring-nodes.csv"),
                 "--exclude-objects", "car_", "--config", os.path.join(a.out, "gos.toml")]
    rows = {"demo/60 json, cold cache": [], "demo/60 json": [], "demo/60 h5": [], "ring/60-static json": [],
            "ring/60-static json, replacing the output": [], "ring/60-static h5": []}
    steady = []
    # Cold: the scene's cache/ of model tables (tracer/precompute.hpp) absent, as in a user's first trace.
    shutil.rmtree(os.path.join(a.out, "demo", "cache"), ignore_errors=True)
    rows["demo/60 json, cold cache"].append(timed_trace(raysweep, demo_args + ["--out", os.path.join(a.out, "t.json")]))
    for r in range(a.rounds):
        steady.append(steady_snapshot(bench, "demo"))
        rows["demo/60 json"].append(timed_trace(raysweep, demo_args + ["--out", os.path.join(a.out, "t.json")]))
        rows["demo/60 h5"].append(timed_trace(raysweep, demo_args + ["--out", os.path.join(a.out, "t.h5")]))
        if ring:
            rows["ring/60-static json"].append(timed_trace(raysweep, ring_args + ["--out", os.path.join(a.out, "r.json")]))
            rows["ring/60-static json, replacing the output"].append(
                timed_trace(raysweep, ring_args + ["--out", os.path.join(a.out, "r.json")], replace=True))
            rows["ring/60-static h5"].append(timed_trace(raysweep, ring_args + ["--out", os.path.join(a.out, "r.h5")]))
    med = statistics.median
    result = {"steady_snapshot_s": med(steady), "rounds": a.rounds, "cases": {}}
    lines = ["| case | process s | tracing s | process / tracing (rounds' range) | process / steady snapshot |",
             "|---|---|---|---|---|"]
    for name, runs in rows.items():
        if not runs:
            continue
        wall, trace = med(w for w, _ in runs), med(t for _, t in runs)
        each = [w / t for w, t in runs]  # the machine's noise: each round's own ratio
        case = {"process_s": wall, "tracing_s": trace, "process_over_tracing": wall / trace,
                "process_over_tracing_range": [min(each), max(each)]}
        if name.startswith("demo"):
            case["process_over_steady"] = wall / result["steady_snapshot_s"]
        result["cases"][name] = case
        lines.append(f"| {name} | {wall:.2f} | {trace:.2f} | {wall / trace:.2f} ({min(each):.2f}-{max(each):.2f}) | "
                     f"{case.get('process_over_steady', float('nan')):.2f} |")
    lines.append(f"\nBM_Snapshot/demo/60/3 steady state: {result['steady_snapshot_s']:.3f} s (median of {a.rounds} rounds' medians)")
    with open(os.path.join(a.out, "results.json"), "w") as f:
        json.dump(result, f, indent=1)
    with open(os.path.join(a.out, "results.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()

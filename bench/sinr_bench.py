#!/usr/bin/python3
"""SINR benchmark: outcomes for the VaN3Twin ring road with 120 vehicles over 60 s.

Builds (once, cached under --out) the ring scene, the paper's 120-vehicle SUMO
traffic and a 60 s channel dataset at 10 Hz (per-pair cache), then times
`raysweep sinr` with every vehicle active (half 802.11p, half NR-V2X) for each
channel model, REPEAT times, and reports the median wall time, peak memory
(max RSS), transmissions, reception attempts, decoded share and file size.
Writes results.csv and results.md under --out. Needs ../shared/data.
"""
import argparse
import csv
import json
import os
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RING = os.path.join(os.path.dirname(ROOT), "shared", "data", "van3twin", "DriveX-devs_VaN3Twin", "src")


def run(cmd):
    print("+", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True)


def timed(cmd):
    t0 = time.monotonic()
    out = subprocess.run(["/usr/bin/time", "-f", "%M"] + cmd, check=True, stderr=subprocess.PIPE, text=True)
    return time.monotonic() - t0, int(out.stderr.strip().splitlines()[-1]) / 1024.0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "bench_sinr"))
    ap.add_argument("--vehicles", type=int, default=120, choices=[60, 120])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--warmup", type=float, default=70.0)
    ap.add_argument("--models", default="ray,tr37885-urban,tr36885")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--threads", default="0", help="comma-separated -j values (0: all cores)")
    args = ap.parse_args()
    sumo_dir = os.path.join(RING, "automotive", "examples", "sumo_files_v2v_map")
    if not os.path.isdir(sumo_dir):
        print(f"skipped: {sumo_dir} absent (the benchmark needs ../shared/data)")
        return 0
    rs = os.path.join(args.build, "raysweep")
    os.makedirs(args.out, exist_ok=True)
    end = args.warmup + args.seconds

    scene = os.path.join(args.out, "ring_scene")
    if not os.path.exists(os.path.join(scene, "scene.glb")):
        run([rs, "-q", "scene", "--no-preview", "--from-mitsuba",
             os.path.join(RING, "sionna", "scenarios", "SionnaCircleScenario", "scene.xml"), "--out", scene])
    cfg = os.path.join(sumo_dir, f"map_{args.vehicles}.sumo.cfg")
    tdir = os.path.join(args.out, f"traffic_{args.vehicles}")
    if not os.path.exists(os.path.join(tdir, "fcd.xml.gz")):
        run([rs, "-q", "traffic", "--net", os.path.join(sumo_dir, "map.net.xml"), "--sumocfg", cfg,
             "--end", str(end + 1), "--out", tdir])
    channels = os.path.join(args.out, f"channels_{args.vehicles}.h5")
    if not os.path.exists(channels):
        sweep_cfg = os.path.join(args.out, "sweep.toml")
        with open(sweep_cfg, "w") as f:
            f.write(f"[sweep]\nbegin_s = {args.warmup}\nend_s = {end - 0.05}\ncache = \"per_pair\"\n"
                    "block_frames = 100\nexclude_objects = \"car_\"\noutside = \"drop\"\n")
        wall, rss = timed([rs, "-q", "sweep", "--scene", scene, "--fcd", os.path.join(tdir, "fcd.xml.gz"),
                           "--vtypes", cfg, "--config", sweep_cfg, "--out", channels])
        print(f"channel dataset: {wall:.1f} s, {rss:.0f} MB peak", flush=True)
    info = json.loads(subprocess.run([rs, "info", "--json", channels], check=True, capture_output=True,
                                     text=True).stdout)

    sinr_cfg = os.path.join(args.out, "sinr.toml")
    with open(sinr_cfg, "w") as f:
        f.write("[sinr]\nseed = 1\nnr_fraction = 0.5\n")
    rows = []
    for threads in args.threads.split(","):
        for model in args.models.split(","):
            out = os.path.join(args.out, f"sinr_{model}.h5")
            walls, rsss = [], []
            for _ in range(args.repeat):
                cmd = [rs, "-q", "-j", threads, "sinr", "--channels", channels, "--out", out, "--config", sinr_cfg,
                       "--channel-model", model]
                print("+", " ".join(cmd), flush=True)
                w, r = timed(cmd)
                walls.append(w)
                rsss.append(r)
            s = json.loads(subprocess.run([rs, "info", "--json", out], check=True, capture_output=True,
                                          text=True).stdout)
            row = {
                "model": model, "threads": threads, "vehicles": info["vehicles"], "frames": info["frames"],
                "channel_links": info["links"], "transmissions": s["transmissions"], "receptions": s["receptions"],
                "decoded_share": round(s["decoded"] / max(1, s["receptions"]), 4),
                "wall_s_median": round(statistics.median(walls), 2), "wall_s_min": round(min(walls), 2),
                "receptions_per_s": round(s["receptions"] / statistics.median(walls)),
                "peak_rss_mb": round(max(rsss), 1), "file_mb": round(os.path.getsize(out) / 2**20, 1),
            }
            for rat, v in s.get("prr", {}).items():
                row[f"prr_{rat}"] = round(v["prr"], 4)
            rows.append(row)
            print(json.dumps(row), flush=True)

    keys = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    with open(os.path.join(args.out, "results.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    with open(os.path.join(args.out, "results.md"), "w") as f:
        f.write("| " + " | ".join(keys) + " |\n|" + "---|" * len(keys) + "\n")
        for r in rows:
            f.write("| " + " | ".join(str(r.get(k, "")) for k in keys) + " |\n")
    print(open(os.path.join(args.out, "results.md")).read())
    return 0


if __name__ == "__main__":
    sys.exit(main())

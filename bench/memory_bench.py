#!/usr/bin/python3
"""Sweep memory benchmark: peak RSS of `raysweep sweep` against block_frames and
sweep length (a benchmark, not a timed test).

Frames are streamed to their block file as they are traced and streamed back
into the dataset, so the peak should stay flat as either grows (a whole block
held in memory would be 1,056 MB for the ring road's 60 vehicles at
block_frames = 100).

Inputs: a scene folder, an FCD file, vType files and (optionally) a vehicle
library, by default those `raysweep run datasets/van3twin-ring/city.toml` leaves
in out/van3twin-ring (60 vehicles). Each (block_frames, seconds) case sweeps
SECONDS of traffic at 10 Hz from --begin with the ring road's settings and
records peak RSS (GNU time's %M) and wall time. --binary compares another build
(e.g. one from before the change). Writes memory.csv and memory.md under --out.

  /usr/bin/python3 bench/memory_bench.py --block-frames 10,50,100,200 --seconds 5,10,20
"""
import argparse
import csv
import os
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RING_OUT = os.path.join(ROOT, "out", "van3twin-ring")
RING_SUMO = os.path.join(os.path.dirname(ROOT), "shared", "data", "van3twin", "DriveX-devs_VaN3Twin", "src",
                         "automotive", "examples", "sumo_files_v2v_map")

CONFIG = """[sweep]
begin_s = {begin}
end_s = {end}
exclude_objects = "car_"
outside = "drop"
cache = "per_pair"
block_frames = {block_frames}
[radio]
frequency_hz = 5.9e9
bandwidth_hz = 10e6
antenna = "dipole"
[tracer]
max_depth = 3
rays_per_source = {rays}
"""


def peak_rss(cmd):
    """Wall seconds and max RSS (MB) of a command (GNU time)."""
    t0 = time.monotonic()
    out = subprocess.run(["/usr/bin/time", "-f", "%M"] + cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         text=True)
    if out.returncode != 0:
        sys.exit(f"failed ({out.returncode}): {' '.join(cmd)}\n{out.stderr}")
    return time.monotonic() - t0, int(out.stderr.strip().splitlines()[-1]) / 1024.0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--binary", default=os.path.join(ROOT, "build", "raysweep"))
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "bench_memory"))
    ap.add_argument("--scene", default=os.path.join(RING_OUT, "scene"))
    ap.add_argument("--fcd", default=os.path.join(RING_OUT, "traffic", "fcd.xml.gz"))
    ap.add_argument("--vtypes", action="append", default=None,
                    help="vType file(s) (default: the ring road's map_60.sumo.cfg)")
    ap.add_argument("--vehicles", default=os.path.join(RING_OUT, "vehicles"), help="vehicle library ('' for none)")
    ap.add_argument("--begin", type=float, default=70.0)
    ap.add_argument("--block-frames", default="10,50,100,200")
    ap.add_argument("--seconds", default="5,10,20")
    ap.add_argument("--rays", type=int, default=4096)
    args = ap.parse_args()
    vtypes = args.vtypes or [os.path.join(RING_SUMO, "map_60.sumo.cfg")]
    for p in [args.binary, args.scene, args.fcd] + vtypes:
        if not os.path.exists(p):
            sys.exit(f"{p}: not found (run `raysweep run datasets/van3twin-ring/city.toml` first, or pass it)")
    os.makedirs(args.out, exist_ok=True)

    rows = []
    for seconds in [float(s) for s in args.seconds.split(",")]:
        for block_frames in [int(b) for b in args.block_frames.split(",")]:
            case = f"b{block_frames}_s{seconds:g}"
            cfg = os.path.join(args.out, case + ".toml")
            with open(cfg, "w") as f:
                f.write(CONFIG.format(begin=args.begin, end=args.begin + seconds - 0.05, block_frames=block_frames,
                                      rays=args.rays))
            h5 = os.path.join(args.out, case + ".h5")
            cmd = [args.binary, "-q", "sweep", "--scene", args.scene, "--fcd", args.fcd, "--config", cfg, "--out", h5]
            for v in vtypes:
                cmd += ["--vtypes", v]
            if args.vehicles:
                cmd += ["--vehicles", args.vehicles]
            wall, rss = peak_rss(cmd)
            row = {"block_frames": block_frames, "seconds": seconds, "frames": round(seconds * 10),
                   "peak_rss_mb": round(rss, 1), "wall_s": round(wall, 1), "file_mb": round(os.path.getsize(h5) / 2**20, 1)}
            print(row, flush=True)
            rows.append(row)
            os.remove(h5)

    with open(os.path.join(args.out, "memory.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    with open(os.path.join(args.out, "memory.md"), "w") as f:
        f.write(f"Peak RSS of `raysweep sweep` ({args.binary}), {args.fcd}\n\n")
        f.write("| " + " | ".join(rows[0]) + " |\n|" + "---|" * len(rows[0]) + "\n")
        for r in rows:
            f.write("| " + " | ".join(str(v) for v in r.values()) + " |\n")
    print(f"wrote {os.path.join(args.out, 'memory.md')}")


if __name__ == "__main__":
    main()

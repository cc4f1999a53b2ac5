#!/usr/bin/python3
"""Dataset store levels: size and the sweep's time outside tracing per level.

Sweeps a city (`raysweep run CITY --until sweep`, the stages before it built
once) with `--set sweep.store=LEVEL` for each level, on the same scene, vehicles
and traffic, and reports per level:

  bytes per pair-frame of the file, and by group (links, cfr, paths,
  interactions, the rest); the sweep's wall and tracing time; its time outside
  tracing: records (turning traced results into dataset records, frequency
  responses included), blocks (reducing them to the level and writing the
  crash-safe blocks) and writing (reading the blocks back, compressing, writing
  the HDF5 file); and whether /links and /cfr are the same, bit for bit, as in
  the `full` file.

    /usr/bin/python3 bench/store_levels.py                      # the demo city, its 300 frames
    /usr/bin/python3 bench/store_levels.py --end-s 64.95        # its first 50 frames

Writes results.json and results.md under --out.
"""
import argparse
import json
import os
import re
import subprocess

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEMO = os.path.join(ROOT, "datasets", "demo", "city.toml")
LEVELS = ("links", "cfr", "paths", "full")
SUMMARY = re.compile(r"swept (\d+) frames .*?, (\d+) pair-channels .*? in ([0-9.]+) s \(([0-9.]+) s tracing; "
                     r"outside tracing ([0-9.]+) s records, ([0-9.]+) s blocks, "
                     r"([0-9.]+) s writing\); .* at level (\w+) \(([0-9.]+) bytes per pair-frame\)")


def sweep(rs, city, out, level, sets):
    stamp = os.path.join(out, ".stamps", "sweep.json")  # the sweep runs again, the stages before it not
    if os.path.exists(stamp):
        os.remove(stamp)
    cmd = [rs, "run", city, "--out", out, "--until", "sweep", "--set", "sweep.store=" + level]
    for s in sets:
        cmd += ["--set", s]
    print("+", " ".join(cmd), flush=True)
    p = subprocess.run(cmd, check=True, capture_output=True, text=True)
    log = p.stdout + p.stderr
    m = SUMMARY.search(log)
    if not m or m.group(8) != level:
        raise SystemExit(f"no sweep summary at level {level} in the log of {' '.join(cmd)}:\n{log[-2000:]}")
    return {"frames": int(m.group(1)), "pair_frames": int(m.group(2)), "sweep_s": float(m.group(3)),
            "trace_s": float(m.group(4)), "record_s": float(m.group(5)), "block_s": float(m.group(6)),
            "write_s": float(m.group(7)), "bytes_per_pair_frame": float(m.group(9))}


def group_bytes(path):
    """Stored (compressed) bytes per top-level group."""
    out = {}
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                g = name.split("/")[0]
                out[g] = out.get(g, 0) + obj.id.get_storage_size()
        f.visititems(visit)
    return out


def same_bits(a, b, group):
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        if group not in fa or group not in fb:
            return group not in fa and group not in fb
        names = [n for n in fb[group] if n != "path_offset"]
        return all(n in fa[group] and fa[group][n][...].tobytes() == fb[group][n][...].tobytes() for n in names)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--raysweep", default=os.path.join(ROOT, "build", "raysweep"))
    ap.add_argument("--city", default=DEMO)
    ap.add_argument("--end-s", type=float, help="sweep.end_s (default: the city's)")
    ap.add_argument("--out", default="/tmp/raysweep-store-levels")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    work = os.path.join(a.out, "city")
    sets = [f"sweep.end_s={a.end_s}"] if a.end_s is not None else []
    rows = {}
    for level in ("full",) + tuple(l for l in LEVELS if l != "full"):  # full first: the reference
        r = sweep(a.raysweep, a.city, work, level, sets)
        path = os.path.join(a.out, level + ".h5")
        os.replace(os.path.join(work, "dataset.h5"), path)
        r["file_bytes"] = os.path.getsize(path)
        r["group_bytes_per_pair_frame"] = {g: b / r["pair_frames"] for g, b in group_bytes(path).items()}
        r["outside_tracing_s"] = r["record_s"] + r["block_s"] + r["write_s"]
        rows[level] = r
    full = os.path.join(a.out, "full.h5")
    for level in LEVELS:
        path = os.path.join(a.out, level + ".h5")
        rows[level]["links_identical"] = same_bits(path, full, "links")
        rows[level]["cfr_identical"] = level == "links" or same_bits(path, full, "cfr")
    with open(os.path.join(a.out, "results.json"), "w") as f:
        json.dump({"city": a.city, "levels": rows}, f, indent=1)

    lines = ["| level | bytes per pair-frame | links | cfr | paths | interactions | tracing s | records s | "
             "blocks s | writing s | /links, /cfr as full |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for level in LEVELS:
        r = rows[level]
        g = r["group_bytes_per_pair_frame"]
        lines.append(f"| {level} | {r['bytes_per_pair_frame']:.0f} | {g.get('links', 0):.0f} | {g.get('cfr', 0):.0f} | "
                     f"{g.get('paths', 0):.0f} | {g.get('interactions', 0):.0f} | {r['trace_s']:.1f} | "
                     f"{r['record_s']:.1f} | {r['block_s']:.2f} | {r['write_s']:.2f} | "
                     f"{'yes' if r['links_identical'] and r['cfr_identical'] else 'NO'} |")
    frames = rows["full"]["frames"]
    text = f"{a.city}: {frames} frames, {rows['full']['pair_frames']} pair-frames\n\n" + "\n".join(lines) + "\n"
    with open(os.path.join(a.out, "results.md"), "w") as f:
        f.write(text)
    print(text)
    if not all(r["links_identical"] and r["cfr_identical"] for r in rows.values()):
        raise SystemExit("link columns or CFR differ between levels")


if __name__ == "__main__":
    main()

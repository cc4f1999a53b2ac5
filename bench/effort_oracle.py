#!/usr/bin/python3
"""What a perfect per-pair oracle could skip: each mechanism turned off in
turn on one snapshot, and per mechanism the pairs whose wideband gain it moves
(by more than --tolerance dB above the sensitivity floor, or across the floor)
and the sources (a pair's lower end, whose enumeration serves it) those pairs
touch. A source with one such pair runs that mechanism's whole enumeration, so
the sources touched bound what skipping per source can save.

    /usr/bin/python3 bench/effort_oracle.py --scene SCENE_DIR --poses POSES.csv --config CITY.toml
        [--build build] [--out /tmp/raysweep-oracle] [--tolerance 0.1]

Writes one line per mechanism and oracle.json under --out.
"""
import argparse
import json
import math
import os
import subprocess

MECHANISMS = {
    "diffraction with a reflection": "tracer.diffraction_reflection=false",
    "diffraction": "tracer.diffraction=false",
    "diffuse scattering": "tracer.diffuse=false",
    "refraction": "tracer.refraction=false",
}


def trace(a, name, setting):
    out = os.path.join(a.out, name.replace(" ", "_") + ".json")
    cmd = [os.path.join(a.build, "raysweep"), "-q", "trace", "--scene", a.scene, "--poses", a.poses,
           "--config", a.config, "--out", out]
    if setting:
        cmd += ["--set", setting]
    subprocess.run(cmd, check=True)
    with open(out) as f:
        doc = json.load(f)
    radio = doc["radio"]
    floor = radio["sensitivity_dbm"] - radio["tx_power_dbm"]
    gains = {}
    for p in doc["pairs"]:
        g = p["path_gain_incoherent_db"]
        gains[(p["tx"], p["rx"])] = g if g is not None and math.isfinite(g) else -math.inf
    return gains, floor


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", required=True)
    ap.add_argument("--poses", required=True)
    ap.add_argument("--config", required=True)
    ap.add_argument("--build", default=os.path.join(root, "build"))
    ap.add_argument("--out", default="/tmp/raysweep-oracle")
    ap.add_argument("--tolerance", type=float, default=0.1)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    full, floor = trace(a, "full", None)
    sources = {p[0] for p in full}
    result = {"pairs": len(full), "sources": len(sources), "tolerance_db": a.tolerance, "mechanisms": {}}
    for name, setting in MECHANISMS.items():
        off, _ = trace(a, name, setting)
        need = [p for p in full
                if (full[p] >= floor) != (off[p] >= floor)
                or abs(max(full[p], floor) - max(off[p], floor)) > a.tolerance]
        touched = sorted({p[0] for p in need})
        result["mechanisms"][name] = {"pairs": len(need), "sources": len(touched)}
        print(f"{name}: {len(need)} of {len(full)} pairs need it; their lower ends are "
              f"{len(touched)} of the {len(sources)} sources")
    with open(os.path.join(a.out, "oracle.json"), "w") as f:
        json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()

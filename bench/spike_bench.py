#!/usr/bin/python3
"""Single-frame spikes of the wideband gain, with vehicle faces reflecting by
physical optics (`tracer.facet_reflection = "po"`) and as infinite mirrors
("go", the default).

A spike is a link-frame whose wideband gain (gain_incoherent_db, floored at
the sensitivity floor) is more than 6 dB away from both its neighbours (the
same pair 100 ms before and after), while the neighbours agree within 2 dB and
neither the LoS class nor the Fresnel class changes over the three frames:
a jump that nothing in the geometry's labels explains.

For each city (demo: frames from 60 s; ring road: from 70 s, when
../shared holds it; Bad Hersfeld's recipe from 180 s, when ../shared holds it)
the sweep runs with each setting on the same scene, vehicles and traffic
(`raysweep run CITY --until sweep`, the city's own [sweep] settings), and the bench reports the spikes (all, upwards), the link-frames
they are counted over, the sweep's tracing seconds per frame and their ratio.

    /usr/bin/python3 bench/spike_bench.py [--build build] [--out /tmp/raysweep-spikes]
        [--cases demo,ring,badhersfeld] [--frames demo=50,ring=200,badhersfeld=20]

Writes results.json and results.md under --out.
"""
import argparse
import json
import os

import h5py
import numpy as np

from sweep_runs import DEMO, RING, RING_SUMO, floor_of, sweep

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BH = os.path.join(ROOT, "datasets", "badhersfeld", "city.toml")
BH_DATA = os.path.join(os.path.dirname(ROOT), "shared", "data", "dlr-sumo-scenarios-badhersfeld")
CASES = {"demo": (DEMO, 60.0, None), "ring": (RING, 70.0, RING_SUMO), "badhersfeld": (BH, 180.0, BH_DATA)}


def selected_cases(names):
    """(case, city file, first second) of each named case whose data is here."""
    for case in names.split(","):
        city, begin, data = CASES[case]
        if data and not os.path.isdir(data):
            print(f"{case}: skipped (../shared/data absent)")
            continue
        yield case, city, begin


def spikes(path, jump_db=6.0, agree_db=2.0):
    """(spikes, upward spikes, link-frames with both neighbours) of a dataset."""
    floor = floor_of(path)
    with h5py.File(path, "r") as f:
        links = f["links"]
        frame = links["frame"][:].astype(np.int64)
        key = links["tx"][:].astype(np.int64) * (1 << 32) + links["rx"][:].astype(np.int64)
        g = np.maximum(np.nan_to_num(links["gain_incoherent_db"][:].astype(float), neginf=floor), floor)
        los = links["los_class"][:]
        fz = links["los_class_fresnel"][:]
    order = np.lexsort((frame, key))
    frame, key, g, los, fz = frame[order], key[order], g[order], los[order], fz[order]
    # Row i has both neighbours when rows i-1 and i+1 are the same pair one frame apart.
    mid = np.arange(1, len(g) - 1)
    ok = (key[mid - 1] == key[mid]) & (key[mid + 1] == key[mid]) & (frame[mid - 1] == frame[mid] - 1) & \
         (frame[mid + 1] == frame[mid] + 1)
    mid = mid[ok]
    prev, nxt = mid - 1, mid + 1
    same_labels = (los[prev] == los[mid]) & (los[nxt] == los[mid]) & (fz[prev] == fz[mid]) & (fz[nxt] == fz[mid])
    spike = (np.abs(g[mid] - g[prev]) > jump_db) & (np.abs(g[mid] - g[nxt]) > jump_db) & \
            (np.abs(g[prev] - g[nxt]) <= agree_db) & same_labels
    up = spike & (g[mid] > g[prev])
    return int(spike.sum()), int(up.sum()), int(len(mid))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--out", default="/tmp/raysweep-spikes")
    ap.add_argument("--cases", default="demo,ring,badhersfeld")
    ap.add_argument("--frames", default="demo=50,ring=200,badhersfeld=20")
    ap.add_argument("--modes", default="po,go")
    args = ap.parse_args()
    rs = os.path.join(args.build, "raysweep")
    frames = dict((k, int(v)) for k, v in (kv.split("=") for kv in args.frames.split(",")))
    rows = []
    for case, city, begin in selected_cases(args.cases):
        n = frames.get(case, 50)
        out = os.path.join(args.out, case)
        for mode in args.modes.split(","):
            sets = [f"sweep.begin_s={begin}", f"sweep.end_s={begin + n / 10 - 0.05}",
                    f'tracer.facet_reflection="{mode}"']
            r = sweep(rs, city, out, sets)
            count, up, total = spikes(os.path.join(out, "dataset.h5"))
            row = {"case": case, "mode": mode, "frames": r["frames"], "link_frames": total, "spikes": count,
                   "spikes_up": up, "share": count / max(total, 1), "trace_s_per_frame": r["trace_s"] / r["frames"]}
            print(json.dumps(row), flush=True)
            rows.append(row)
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump(rows, f, indent=1)
    lines = ["| city | facet_reflection | frames | link-frames | spikes (up) | share | tracing s / frame | vs go |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        go = next((x for x in rows if x["case"] == r["case"] and x["mode"] == "go"), None)
        ratio = f"{r['trace_s_per_frame'] / go['trace_s_per_frame']:.2f}" if go else "-"
        lines.append(f"| {r['case']} | {r['mode']} | {r['frames']} | {r['link_frames']} | {r['spikes']} "
                     f"({r['spikes_up']}) | {100 * r['share']:.3f} % | {r['trace_s_per_frame']:.3f} | {ratio} |")
    with open(os.path.join(args.out, "results.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()

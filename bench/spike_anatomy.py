#!/usr/bin/python3
"""What a single-frame spike is made of: each spike of a 10 Hz sweep swept
again at --step-ms (5 ms) over the frames around it, to see whether the
excursion is an event shorter than the frame interval, which any 10 Hz
sampling of the same field writes into one frame, or a jump the model makes
at any sampling rate.

A spike is spike_bench.py's: a link-frame whose wideband gain is more than
6 dB from both neighbours (100 ms before and after) that agree within 2 dB,
the LoS and Fresnel classes unchanged over the three frames. For each frame
holding spikes, the city's FCD is interpolated between its 10 Hz rows (the
position linearly, the heading along the shorter arc; vehicles present at
both rows) to --step-ms over +-100 ms, and `raysweep sweep` traces those
frames on the same scene, vehicles and settings. For each spike the bench
reads its link's gain over the fine frames and reports:

- width: how long the gain stays more than 3 dB (half the spike's threshold)
  beyond the neighbours' mean, on the spike's side, around the spike's own
  time; shorter than 100 ms means no 10 Hz sampling can catch it twice;
- largest step: the largest gain change between consecutive fine frames
  (more than 3 dB at 5 ms: the model switches the event on or off, a jump
  at any rate);
- the reflecting vehicles' turn rate (degrees a frame) and speed.

    /usr/bin/python3 bench/spike_anatomy.py [--build build] [--out /tmp/raysweep-anatomy]
        [--case demo] [--frames 50] [--modes po,go] [--step-ms 5] [--max-frames 0]

Writes results.json, results.md and anatomy.png under --out.
"""
import argparse
import gzip
import json
import math
import os
import subprocess
import xml.etree.ElementTree as ET

import h5py
import numpy as np

from spike_bench import CASES
from sweep_runs import floor_of, sweep

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def gains(path):
    """(rows: frame, tx id, rx id, gain, LoS, Fresnel class; frame times; node ids) of a dataset."""
    floor = floor_of(path)
    with h5py.File(path, "r") as f:
        links = f["links"]
        ids = [n.decode() if isinstance(n, bytes) else n for n in f["nodes/id"][:]]
        g = np.maximum(np.nan_to_num(links["gain_incoherent_db"][:].astype(float), neginf=floor), floor)
        rows = list(zip(links["frame"][:].tolist(), links["tx"][:].tolist(), links["rx"][:].tolist(), g.tolist(),
                        links["los_class"][:].tolist(), links["los_class_fresnel"][:].tolist()))
        times = f["frames/time_s"][:].tolist()
    return rows, times, ids


def find_spikes(rows, jump_db=6.0, agree_db=2.0):
    """[(frame, tx, rx, g_before, g, g_after)] by spike_bench's rule."""
    at = {(r[0], r[1], r[2]): r for r in rows}
    out = []
    for fr, a, b, g, los, fz in rows:
        p, n = at.get((fr - 1, a, b)), at.get((fr + 1, a, b))
        if not p or not n or not (p[4] == los == n[4] and p[5] == fz == n[5]):
            continue
        if abs(g - p[3]) > jump_db and abs(g - n[3]) > jump_db and abs(p[3] - n[3]) <= agree_db:
            out.append((fr, a, b, p[3], g, n[3]))
    return out


def read_fcd(path):
    """time -> {vehicle id: attributes} of a SUMO FCD file."""
    out = {}
    with gzip.open(path) if path.endswith(".gz") else open(path, "rb") as f:
        for _, el in ET.iterparse(f):
            if el.tag == "timestep":
                out[round(float(el.get("time")), 3)] = {v.get("id"): dict(v.attrib) for v in el.findall("vehicle")}
                el.clear()
    return out


def fine_fcd(fcd, t0, t1, step, path):
    """The FCD between t0 and t1 (10 Hz rows) interpolated to `step` seconds."""
    rows = sorted(t for t in fcd if t0 - 1e-9 <= t <= t1 + 1e-9)
    n = int(round(0.1 / step))
    with open(path, "w") as out:
        out.write('<?xml version="1.0" encoding="UTF-8"?>\n<fcd-export>\n')
        for ta, tb in zip(rows, rows[1:] + [None]):
            for j in range(n if tb is not None else 1):
                u = j / n
                out.write(f'    <timestep time="{ta + u * 0.1:.4f}">\n')
                for vid, a in fcd[ta].items():
                    b = fcd[tb].get(vid) if tb is not None else None
                    if j > 0 and b is None:
                        continue
                    v = dict(a)
                    if j > 0:
                        for k in ("x", "y", "speed"):
                            v[k] = f"{float(a[k]) + u * (float(b[k]) - float(a[k])):.4f}"
                        da = (float(b["angle"]) - float(a["angle"]) + 180) % 360 - 180
                        v["angle"] = f"{(float(a['angle']) + u * da) % 360:.4f}"
                    out.write("        <vehicle " + " ".join(f'{k}="{val}"' for k, val in v.items()) + "/>\n")
                out.write("    </timestep>\n")
        out.write("</fcd-export>\n")


def turn_rates(fcd, t, vehicles):
    """{vehicle: (degrees a frame over t-0.1..t+0.1, speed)} of the named SUMO vehicles."""
    out = {}
    a, b = fcd.get(round(t - 0.1, 3), {}), fcd.get(round(t + 0.1, 3), {})
    for v in vehicles:
        if v in a and v in b:
            d = (float(b[v]["angle"]) - float(a[v]["angle"]) + 180) % 360 - 180
            out[v] = (d / 2, float(fcd[round(t, 3)][v]["speed"]) if v in fcd.get(round(t, 3), {}) else None)
    return out


def strongest_vehicles(path, frame, tx, rx, frame_before):
    """SUMO ids of the vehicles on the path that makes the spike (the link's
    strongest at the spike, or for a dip the strongest of the frame before)."""
    with h5py.File(path, "r") as f:
        if "paths" not in f:
            return []
        links = f["links"]
        fr, a, b = links["frame"][:], links["tx"][:], links["rx"][:]
        pick = frame_before if frame_before is not None else frame
        i = np.flatnonzero((fr == pick) & (a == tx) & (b == rx))
        if len(i) == 0:
            return []
        i = int(i[0])
        off, cnt = int(links["path_offset"][i]), int(links["path_count"][i])
        if cnt == 0:
            return []
        amp = np.abs(f["paths/a"][off:off + cnt])
        p = off + int(np.argmax(amp))
        io, ic = int(f["paths/interaction_offset"][p]), int(f["paths/interaction_count"][p])
        names = [n.decode() if isinstance(n, bytes) else n for n in f["objects/name"][:]]
        objs = [names[o] for o in f["interactions/object"][io:io + ic]]
    return sorted({o.split("/", 1)[1] for o in objs if o.startswith("vehicle/")})


def anatomy(series, t, level, up, frame_s=0.1, half_db=3.0):
    """(width s, largest step dB) of the excursion around time t in (time, gain) pairs."""
    ts = np.array([s[0] for s in series])
    gs = np.array([s[1] for s in series])
    k = int(np.argmin(np.abs(ts - t)))
    beyond = (gs - level > half_db) if up else (level - gs > half_db)
    width = 0.0
    if beyond[k]:
        lo = hi = k
        while lo > 0 and beyond[lo - 1]:
            lo -= 1
        while hi + 1 < len(gs) and beyond[hi + 1]:
            hi += 1
        step = (ts[-1] - ts[0]) / max(len(ts) - 1, 1)
        width = float((hi - lo + 1) * step)
    steps = np.abs(np.diff(gs))
    return float(width), float(steps.max()) if len(steps) else 0.0


def chart(results, path, count=6):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    shown = [s for s in results["spikes"] if s["series"]][:count]
    if not shown:
        return
    cols = 3
    rws = (len(shown) + cols - 1) // cols
    fig, axes = plt.subplots(rws, cols, figsize=(4 * cols, 3 * rws), squeeze=False)
    for ax, s in zip(axes.flat, shown):
        t = np.array([p[0] for p in s["series"]]) - s["time_s"]
        ax.plot(1000 * t, [p[1] for p in s["series"]], lw=1, label=f"{results['step_ms']:g} ms frames")
        ax.plot([-100, 0, 100], [s["gain_before"], s["gain"], s["gain_after"]], "o", label="10 Hz frames")
        ax.set_title(f"{s['mode']} {s['tx']}-{s['rx']} at {s['time_s']:.1f} s: {1000 * s['width_s']:.0f} ms",
                     fontsize=9)
        ax.set_xlabel("ms from the spike's frame")
        ax.set_ylabel("gain (dB)")
    axes.flat[0].legend(fontsize=7)
    for ax in list(axes.flat)[len(shown):]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def run(cmd):
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"failed ({p.returncode}): {' '.join(cmd)}\n{p.stderr[-2000:]}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--out", default="/tmp/raysweep-anatomy")
    ap.add_argument("--case", default="demo")
    ap.add_argument("--frames", type=int, default=50)
    ap.add_argument("--modes", default="po,go")
    ap.add_argument("--step-ms", type=float, default=5.0)
    ap.add_argument("--max-frames", type=int, default=0, help="re-sweep at most this many spike frames (0: all)")
    a = ap.parse_args()
    rs = os.path.join(a.build, "raysweep")
    city, begin, _ = CASES[a.case]
    out = os.path.join(a.out, a.case)
    results = {"case": a.case, "step_ms": a.step_ms, "frames": a.frames, "spikes": [], "modes": {}}
    for mode in a.modes.split(","):
        sets = [f"sweep.begin_s={begin}", f"sweep.end_s={begin + a.frames / 10 - 0.05}",
                f'tracer.facet_reflection="{mode}"', 'sweep.store="paths"']
        sweep(rs, city, out, sets)
        coarse = os.path.join(a.out, f"{a.case}-{mode}.h5")
        os.replace(os.path.join(out, "dataset.h5"), coarse)
        rows, times, ids = gains(coarse)
        spikes = find_spikes(rows)
        fcd = read_fcd(os.path.join(out, "traffic", "fcd.xml.gz"))
        frames = sorted({s[0] for s in spikes})
        if a.max_frames:
            frames = frames[:a.max_frames]
        mode_rows = []
        for fr in frames:
            t = round(times[fr], 3)
            fine_xml = os.path.join(a.out, "fine.xml")
            fine_fcd(fcd, round(t - 0.1, 3), round(t + 0.1, 3), a.step_ms / 1000, fine_xml)
            fine = os.path.join(a.out, "fine.h5")
            run([rs, "-q", "sweep", "--scene", os.path.join(out, "scene"), "--vehicles", os.path.join(out, "vehicles"),
                 "--fcd", fine_xml, "--vtypes", os.path.join(out, "traffic", "vtypes.add.xml"), "--config", city,
                 "--out", fine, "--set", f"sweep.begin_s={t - 0.1 - 1e-6}", "--set", f"sweep.end_s={t + 0.1 + 1e-6}",
                 "--set", f'tracer.facet_reflection="{mode}"'])
            frows, ftimes, fids = gains(fine)
            for s in (x for x in spikes if x[0] == fr):
                _, tx, rx, gb, g, ga = s
                key = (fids.index(ids[tx]), fids.index(ids[rx]))
                series = sorted((ftimes[r[0]], r[3]) for r in frows if (r[1], r[2]) == key)
                up = g > gb
                width, step = anatomy(series, t, (gb + ga) / 2, up)
                vehicles = strongest_vehicles(coarse, fr, tx, rx, None if up else fr - 1)
                row = {"mode": mode, "frame": fr, "time_s": t, "tx": ids[tx], "rx": ids[rx], "up": up,
                       "gain_before": gb, "gain": g, "gain_after": ga, "width_s": width, "largest_step_db": step,
                       "vehicles": vehicles, "turn": turn_rates(fcd, t, vehicles), "series": series}
                mode_rows.append(row)
                print(json.dumps({k: v for k, v in row.items() if k != "series"}), flush=True)
        results["spikes"] += mode_rows
        widths = [r["width_s"] for r in mode_rows]
        results["modes"][mode] = {
            "spikes": len(spikes), "resampled": len(mode_rows),
            "shorter_than_frame": sum(0 < w < 0.1 for w in widths),
            "not_reproduced": sum(w == 0 for w in widths),
            "steps_over_3db": sum(r["largest_step_db"] > 3 for r in mode_rows),
            "on_a_vehicle": sum(bool(r["vehicles"]) for r in mode_rows),
            "vehicle_turning_over_3deg": sum(any(abs(v[0]) > 3 for v in r["turn"].values()) for r in mode_rows),
            "width_ms_median": 1000 * float(np.median([w for w in widths if w > 0])) if any(widths) else 0}
    os.makedirs(a.out, exist_ok=True)
    with open(os.path.join(a.out, "results.json"), "w") as f:
        json.dump(results, f, indent=1)
    lines = [f"{a.case}, {a.frames} frames at 10 Hz, spikes swept again at {a.step_ms:g} ms", "",
             "| facet_reflection | spikes | re-swept | shorter than a frame | not reproduced | with a step > 3 dB "
             "| on a vehicle | that vehicle turning > 3 deg / frame | median width (ms) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for mode, m in results["modes"].items():
        lines.append(f"| {mode} | {m['spikes']} | {m['resampled']} | {m['shorter_than_frame']} | "
                     f"{m['not_reproduced']} | {m['steps_over_3db']} | {m['on_a_vehicle']} | "
                     f"{m['vehicle_turning_over_3deg']} | {m['width_ms_median']:.0f} |")
    with open(os.path.join(a.out, "results.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    chart(results, os.path.join(a.out, "anatomy.png"))
    print("\n".join(lines))


if __name__ == "__main__":
    main()

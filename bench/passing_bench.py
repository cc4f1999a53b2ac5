#!/usr/bin/python3
"""A car passing a fixed link, sampled at 100 Hz: how much the link's gain
jumps from one sample to the next with vehicle facets as infinite mirrors
(`tracer.facet_reflection = "go"`, the default) and by physical optics ("po").

One vehicle of the demo's own SUMO traffic (the first one that drives
straight at --min-speed or more for the whole window) is followed for
--seconds, its 10 Hz trajectory interpolated to --rate Hz. Two fixed antennas
at 1.5 m stand --offset metres to the side of its lane, --spacing metres
apart about the window's midpoint, so that the car's side reflects towards
them as it passes. Each sample is one `raysweep trace` of the car and the
two antennas on the demo scene; the bench reads the fixed link's wideband
gain (gain_incoherent_db, floored at the sensitivity floor) and its LoS and
Fresnel classes.

A step is the gain difference between consecutive samples (the car moves
speed / rate between them: 0.1-0.2 m at 100 Hz, a few per cent of a first
Fresnel zone). Steps over --jump-db (3 dB) where neither class changes are
what the geometry does not explain: the bench counts them per mode for the
link's gain and for the power of its paths that touch the car (where a glint
shows even when the direct path dominates the link), gives the largest,
and charts both against the car's position.

    /usr/bin/python3 bench/passing_bench.py [--build build] [--out /tmp/raysweep-passing]
        [--seconds 2.5] [--rate 100] [--offset 6] [--spacing 20] [--modes go,po]

Writes results.json, results.md and passing.png under --out; the demo's
scene, vehicles and traffic are built there on the first run.
"""
import argparse
import gzip
import json
import math
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEMO = os.path.join(ROOT, "datasets", "demo", "city.toml")
FLOOR_DB = -123.0  # the demo's sensitivity (-93 dBm) less its transmit power (30 dBm)


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"failed ({r.returncode}): {' '.join(cmd)}\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}")
    return r.stdout + r.stderr


def trajectories(fcd):
    """vehicle id -> [(time, x, y, angle_deg, speed, type)] from SUMO's FCD."""
    out = {}
    with gzip.open(fcd) as f:
        for _, el in ET.iterparse(f):
            if el.tag != "timestep":
                continue
            t = float(el.get("time"))
            for v in el.findall("vehicle"):
                out.setdefault(v.get("id"), []).append(
                    (t, float(v.get("x")), float(v.get("y")), float(v.get("angle")), float(v.get("speed")),
                     v.get("type")))
            el.clear()
    return out


def straight_window(traj, seconds, min_speed):
    """The first vehicle and start index whose next `seconds` at 10 Hz keep
    the speed and the heading (within 2 degrees)."""
    n = int(round(seconds * 10)) + 1
    for vid in sorted(traj):
        rows = traj[vid]
        for s in range(0, len(rows) - n):
            w = rows[s:s + n]
            if any(abs(w[k + 1][0] - w[k][0] - 0.1) > 1e-6 for k in range(n - 1)):
                continue
            if min(r[4] for r in w) < min_speed:
                continue
            if max(abs((r[3] - w[0][3] + 180) % 360 - 180) for r in w) > 2:
                continue
            return vid, w
    sys.exit("no vehicle drives straight long enough in the demo's traffic")


def samples(window, rate):
    """(x, y, angle, speed) at `rate` Hz, linearly between the 10 Hz rows."""
    out = []
    steps = int(round(rate / 10))
    for k in range(len(window) - 1):
        a, b = window[k], window[k + 1]
        for j in range(steps):
            u = j / steps
            ang = a[3] + u * ((b[3] - a[3] + 180) % 360 - 180)
            out.append((a[1] + u * (b[1] - a[1]), a[2] + u * (b[2] - a[2]), ang, a[4] + u * (b[4] - a[4])))
    return out


def link(doc, a, b):
    """The fixed link's (gain, LoS class, Fresnel class, power of the paths
    that touch the car), dB, floored."""
    for p in doc["pairs"]:
        if {p["tx"], p["rx"]} == {a, b}:
            g = p["path_gain_incoherent_db"]
            car = sum(q["a_re"] ** 2 + q["a_im"] ** 2 for q in p["paths"]
                      if any(i["object"].startswith("vehicle/") for i in q["interactions"]))
            car_db = 10 * math.log10(car) if car > 0 else -math.inf
            return (max(FLOOR_DB, -math.inf if g is None else g), p["los_class"], p["los_class_fresnel"],
                    max(FLOOR_DB, car_db))
    sys.exit("the fixed link is missing from the trace")


def sweep_mode(rs, scene, vtype, pts, nodes_csv, mode, work):
    """Each sample's (gain, LoS class, Fresnel class) of the fixed link."""
    rows = []
    poses = os.path.join(work, "pose.csv")
    out = os.path.join(work, "t.json")
    for x, y, ang, speed in pts:
        with open(poses, "w") as f:
            f.write(f"id,class,x,y,heading_deg,speed_mps\ncar,{vtype},{x},{y},{ang},{speed}\n")
        run([rs, "-q", "-j", "2", "trace", "--scene", scene, "--poses", poses, "--nodes", nodes_csv, "--out", out,
             "--config", DEMO, "--set", f'tracer.facet_reflection="{mode}"'])
        with open(out) as f:
            rows.append(link(json.load(f), "A", "B"))
    return rows


def steps(rows, jump_db, column=0):
    """(unexplained steps over jump_db, largest unexplained step, every step)
    of one column of the rows (0: the link's gain, 3: the car's paths)."""
    big, worst, all_steps = 0, 0.0, []
    for r0, r1 in zip(rows, rows[1:]):
        (l0, f0), (l1, f1) = r0[1:3], r1[1:3]
        d = r1[column] - r0[column]
        all_steps.append(d)
        if l0 == l1 and f0 == f1:
            worst = max(worst, abs(d))
            big += abs(d) > jump_db
    return big, worst, all_steps


def chart(result, path):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, ax = plt.subplots(figsize=(9, 4))
    for mode, r in result["modes"].items():
        line, = ax.plot(result["along_m"], [row[0] for row in r["rows"]], lw=1,
                        label=f"{mode}, the link: largest step {r['largest_step_db']:.1f} dB")
        ax.plot(result["along_m"], [row[3] for row in r["rows"]], lw=1, ls="--", color=line.get_color(),
                label=f"{mode}, its paths via the car: {r['car_steps']} steps > {result['jump_db']:g} dB")
    ax.set_xlabel("car position along its lane (m, 0 = between the antennas)")
    ax.set_ylabel("gain (dB)")
    ax.set_title(f"A car passing a fixed link, {result['rate_hz']:g} Hz samples")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--out", default="/tmp/raysweep-passing")
    ap.add_argument("--seconds", type=float, default=2.5)
    ap.add_argument("--rate", type=float, default=100)
    ap.add_argument("--offset", type=float, default=6.0, help="antennas' distance from the car's lane (m)")
    ap.add_argument("--spacing", type=float, default=20.0, help="distance between the two antennas (m)")
    ap.add_argument("--min-speed", type=float, default=8.0)
    ap.add_argument("--jump-db", type=float, default=3.0)
    ap.add_argument("--modes", default="go,po")
    a = ap.parse_args()
    rs = os.path.join(a.build, "raysweep")
    demo = os.path.join(a.out, "demo")
    fcd = os.path.join(demo, "traffic", "fcd.xml.gz")
    if not os.path.exists(fcd):
        run([rs, "-q", "run", DEMO, "--until", "traffic", "--out", demo])
    vid, window = straight_window(trajectories(fcd), a.seconds, a.min_speed)
    pts = samples(window, a.rate)
    mid = pts[len(pts) // 2]
    ang = math.radians(mid[2])
    fwd, right = (math.sin(ang), math.cos(ang)), (math.cos(ang), -math.sin(ang))  # SUMO: clockwise from north
    nodes_csv = os.path.join(a.out, "nodes.csv")
    with open(nodes_csv, "w") as f:
        for name, s in (("A", -0.5), ("B", 0.5)):
            x = mid[0] + a.offset * right[0] + s * a.spacing * fwd[0]
            y = mid[1] + a.offset * right[1] + s * a.spacing * fwd[1]
            f.write(f"{name},{x},{y},1.5\n")
    along = [(p[0] - mid[0]) * fwd[0] + (p[1] - mid[1]) * fwd[1] for p in pts]
    result = {"vehicle": vid, "vtype": window[0][5], "rate_hz": a.rate, "seconds": a.seconds, "offset_m": a.offset,
              "spacing_m": a.spacing, "jump_db": a.jump_db, "along_m": along, "modes": {}}
    lines = [f"car `{vid}` ({window[0][5]}), {len(pts)} samples at {a.rate:g} Hz, antennas {a.offset:g} m off its "
             f"lane, {a.spacing:g} m apart", "",
             "| facet_reflection | the link: unexplained steps > %g dB, largest | its paths via the car: "
             "steps > %g dB, largest | samples with a path via the car |" % (a.jump_db, a.jump_db),
             "|---|---|---|---|"]
    for mode in a.modes.split(","):
        rows = sweep_mode(rs, os.path.join(demo, "scene"), "passenger", pts, nodes_csv, mode, a.out)
        big, worst, _ = steps(rows, a.jump_db)
        car_big, car_worst, _ = steps(rows, a.jump_db, 3)
        lit = sum(r[3] > FLOOR_DB for r in rows)
        result["modes"][mode] = {"rows": rows, "unexplained_steps": big, "largest_step_db": worst,
                                 "car_steps": car_big, "car_largest_step_db": car_worst, "car_samples": lit}
        lines.append(f"| {mode} | {big}, {worst:.2f} dB | {car_big}, {car_worst:.1f} dB | {lit} of {len(rows)} |")
        print(lines[-1], flush=True)
    with open(os.path.join(a.out, "results.json"), "w") as f:
        json.dump(result, f)
    with open(os.path.join(a.out, "results.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    chart(result, os.path.join(a.out, "passing.png"))
    print("\n".join(lines))


if __name__ == "__main__":
    main()

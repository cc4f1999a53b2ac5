#!/usr/bin/python3
"""Checks python/sinr_report.py on small hand-made SINR outcome files.

usage: /usr/bin/python3 tests/python/test_sinr_report.py
Builds the files with h5py in a temporary folder, runs the report (with
sys.executable) and compares its numbers with values computed by hand below.
Exits 0 when every check passes; prints the failures and exits 1 otherwise.
"""
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPT = os.path.join(HERE, "..", "..", "python", "sinr_report.py")

failures = []


def check(cond, what):
    if not cond:
        failures.append(what)
        print("FAIL:", what)


def close(a, b, tol=1e-9):
    return a is not None and b is not None and abs(a - b) <= tol


# --------------------------------------------------------------------------------------
# The scenario. Nodes 0, 1, 2 and 6 use 802.11p (rat 1), nodes 3, 4, 5 NR-V2X (rat 2).
#   t0: node 0, packet 10, attempt 0 (rat 1)    t1: node 3, packet 11, attempt 0 (rat 2)
#   t2: node 3, packet 11, attempt 1 (rat 2)    t3: node 1, packet 12, attempt 0 (rat 1)
# Receptions (transmission, rx), rows r0..r7 of file A:
#   r0 (0,1)  r1 (0,2)  r2 (1,4)  r3 (1,5)  r4 (2,4)  r5 (2,5)  r6 (3,0)  r7 (3,2)
# File B has the same schedule and one more reception, (0,6), only in B.
# --------------------------------------------------------------------------------------
NODE_RAT = [1, 1, 1, 2, 2, 2, 1]
TRANSMISSIONS = [  # node, rat, packet, attempt, start_s
    (0, 1, 10, 0, 0.000),
    (3, 2, 11, 0, 0.001),
    (3, 2, 11, 1, 0.002),
    (1, 1, 12, 0, 0.003),
]
KEYS_A = [(0, 1), (0, 2), (1, 4), (1, 5), (2, 4), (2, 5), (3, 0), (3, 2)]
DIST_A = [10, 30, 40, 80, 40, 80, 12, 60]
# SINR and received power: rat 1 all usable (SINR 12, 10, 0, -2); rat 2: r2 below sensitivity, r4 -inf.
SINR_A = [12, 10, 5, 8, -np.inf, 3, 0, -2]
PRX_A = [-60, -62, -95, -70, -200, -75, -65, -80]
DEC_A = [1, 1, 0, 1, 1, 0, 0, 0]
# Overlaps per reception: (interferer transmission, inter_rat, counted).
OVL_A = [[(1, 1, 1), (3, 0, 1)], [(1, 1, 0)], [(0, 1, 1)], [(0, 1, 1)], [], [(3, 1, 1)],
         [(0, 0, 1), (2, 1, 0)], [(2, 1, 1)]]

KEYS_B = [(0, 1), (0, 2), (0, 6), (1, 4), (1, 5), (2, 4), (2, 5), (3, 0), (3, 2)]
DIST_B = [10, 30, 200, 40, 80, 40, 80, 12, 60]
SINR_B = [-5, 3, 4, -1, 9, 6, 7, 4, -9]
PRX_B = [-70] * 9
DEC_B = [0, 1, 1, 0, 1, 1, 1, 1, 0]
OVL_B = [[(1, 1, 1), (3, 0, 1)], [(1, 1, 1)], [(1, 1, 1)], [(0, 1, 0)], [(0, 1, 1)], [], [(3, 1, 0)],
         [(0, 0, 1), (2, 1, 0)], [(2, 1, 0)]]

# Hand-computed disagreement of B with A (reference), over the 8 common keys:
#   decoded A = {r0, r1, r3, r4}, decoded B = {r1, r3, r4, r5, r6}
#   delta = {r0, r5, r6} (3), union = {r0, r1, r3, r4, r5, r6} (6) -> DR = 0.5
#   rat 1 (r0, r1, r6, r7): A {r0, r1}, B {r1, r6} -> 2/3; rat 2 (r2..r5): A {r3, r4}, B {r3, r4, r5} -> 1/3
# Inter-RAT counted interferers (reception, interferer transmission):
#   A = {(r0,1), (r2,0), (r3,0), (r5,3), (r7,2)}; B = {(r0,1), (r1,1), (r3,0)} ((0,6) is only in B)
#   both = {(r0,1), (r3,0)} -> union 6, delta 4 -> DR = 2/3
#   rat 1: A {(r0,1), (r7,2)}, B {(r0,1), (r1,1)} -> 2/3; rat 2: A {(r2,0), (r3,0), (r5,3)}, B {(r3,0)} -> 2/3
# Sarle's b of A's rat-1 SINR [12, 10, 0, -2]: mean 5, m2 = 37, m3 = 0, m4 = 1513,
#   G2 = ((n+1) g2 + 6)(n-1)/((n-2)(n-3)) = -7134/1369, b = 1 / (G2 + 27/2) = 2738/22695
# PRR vs distance of A (first attempts, 25 m bins), any attempt decoded per (packet, rx):
#   rat 1: (10,1) d10 yes, (12,0) d12 no -> [0,25): 0.5 (2); (10,2) d30 yes -> [25,50): 1.0 (1);
#          (12,2) d60 no -> [50,75): 0.0 (1)
#   rat 2: (11,4) d40: attempt 0 failed, attempt 1 decoded -> [25,50): 1.0; (11,5) d80 -> [75,100): 1.0
PRR_RATS_A = [(1, 4, 2, 0.5), (2, 2, 2, 1.0)]
PRR_RATS_B = [(1, 4, 3, 0.75), (2, 2, 1, 0.5)]
# prr_links (tx, rx, rat, packets, received): per tx node PRR rat 1 of A: node 0 3/4, node 1 0/2
LINKS_A = [(0, 1, 1, 2, 2), (0, 2, 1, 2, 1), (1, 0, 1, 1, 0), (1, 2, 1, 1, 0), (3, 4, 2, 1, 1), (3, 5, 2, 1, 1)]
LINKS_B = [(0, 1, 1, 1, 0), (0, 2, 1, 1, 1), (1, 0, 1, 1, 1), (1, 2, 1, 1, 1), (3, 4, 2, 1, 1), (3, 5, 2, 1, 0)]


def write_sinr(path, model, keys, dist, sinr, prx, decoded, overlaps, prr_rats, links, los_from_ray=0,
               complete=1, fmt="raysweep-sinr", version="1.0.0", transmissions=TRANSMISSIONS):
    with h5py.File(path, "w") as f:
        a = f.attrs
        a["format"] = fmt
        a["schema_version"] = version
        a["raysweep_version"] = "test"
        a["git_hash"] = "unknown"
        a["config"] = json.dumps({"prr_range_m": 150.0, "sinr_threshold_db": 2.0})
        a["inputs"] = json.dumps({})
        a["provenance"] = json.dumps({"by": "test_sinr_report.py"})
        a["seed"] = np.uint64(7)
        a["channel_model"] = model
        a["los_from_ray"] = np.uint8(los_from_ray)
        a["carrier_hz"] = 5.9e9
        a["sinr_threshold_db"] = 2.0
        a["sensitivity_dbm"] = -90.0
        a["gain_threshold_db"] = -100.0
        a["time_start_s"] = 0.0
        a["time_end_s"] = 1.0
        a["node_count"] = np.uint64(len(NODE_RAT))
        a["transmission_count"] = np.uint64(len(transmissions))
        a["reception_count"] = np.uint64(len(keys))
        a["interferer_count"] = np.uint64(sum(len(o) for o in overlaps))
        if complete is not None:
            a["complete"] = np.uint8(complete)

        n = f.create_group("nodes")
        n.create_dataset("id", data=[f"veh{i}" for i in range(len(NODE_RAT))], dtype=h5py.string_dtype())
        n.create_dataset("kind", data=np.zeros(len(NODE_RAT), np.uint8))
        n.create_dataset("rat", data=np.array(NODE_RAT, np.uint8))

        t = f.create_group("transmissions")
        tx = np.array(transmissions, dtype=np.float64)
        t.create_dataset("node", data=tx[:, 0].astype(np.uint32))
        t.create_dataset("rat", data=tx[:, 1].astype(np.uint8))
        t.create_dataset("message", data=np.zeros(len(tx), np.uint8))
        t.create_dataset("packet", data=tx[:, 2].astype(np.uint64))
        t.create_dataset("attempt", data=tx[:, 3].astype(np.uint8))
        t.create_dataset("size_bytes", data=np.full(len(tx), 300, np.uint32))
        t.create_dataset("start_s", data=tx[:, 4])
        t.create_dataset("duration_s", data=np.full(len(tx), 4e-4))
        t.create_dataset("band_hz", data=np.tile([5.855e9, 5.865e9], (len(tx), 1)))
        t.create_dataset("power_dbm", data=np.full(len(tx), 23.0, np.float32))

        r = f.create_group("receptions")
        trow = np.array([k[0] for k in keys], np.uint32)
        counts = np.array([len(o) for o in overlaps], np.uint16)
        r.create_dataset("transmission", data=trow)
        r.create_dataset("tx", data=tx[trow, 0].astype(np.uint32))
        r.create_dataset("rx", data=np.array([k[1] for k in keys], np.uint32))
        r.create_dataset("rat", data=tx[trow, 1].astype(np.uint8))
        r.create_dataset("packet", data=tx[trow, 2].astype(np.uint64))
        r.create_dataset("attempt", data=tx[trow, 3].astype(np.uint8))
        r.create_dataset("time_s", data=tx[trow, 4])
        r.create_dataset("distance_m", data=np.array(dist, np.float32))
        r.create_dataset("prx_dbm", data=np.array(prx, np.float32))
        r.create_dataset("intra_dbm", data=np.full(len(keys), -np.inf, np.float32))
        r.create_dataset("inter_dbm", data=np.full(len(keys), -np.inf, np.float32))
        r.create_dataset("noise_dbm", data=np.full(len(keys), -95.0, np.float32))
        r.create_dataset("sinr_db", data=np.array(sinr, np.float32))
        r.create_dataset("los_class", data=np.zeros(len(keys), np.uint8))
        r.create_dataset("interferers", data=np.array([sum(c for _, _, c in o) for o in overlaps], np.uint16))
        r.create_dataset("decoded", data=np.array(decoded, np.uint8))
        r.create_dataset("overlap_count", data=counts)
        r.create_dataset("overlap_offset", data=(np.cumsum(counts, dtype=np.uint64) - counts).astype(np.uint64))

        x = f.create_group("interferers")
        flat = [v for o in overlaps for v in o]
        x.create_dataset("transmission", data=np.array([v[0] for v in flat], np.uint32))
        x.create_dataset("gain_db", data=np.full(len(flat), -80.0, np.float32))
        x.create_dataset("power_dbm", data=np.full(len(flat), -100.0, np.float32))
        x.create_dataset("inter_rat", data=np.array([v[1] for v in flat], np.uint8))
        x.create_dataset("counted", data=np.array([v[2] for v in flat], np.uint8))

        k = f.create_group("prr_links")
        k.create_dataset("tx", data=np.array([l[0] for l in links], np.uint32))
        k.create_dataset("rx", data=np.array([l[1] for l in links], np.uint32))
        k.create_dataset("rat", data=np.array([l[2] for l in links], np.uint8))
        k.create_dataset("packets", data=np.array([l[3] for l in links], np.uint64))
        k.create_dataset("received", data=np.array([l[4] for l in links], np.uint64))
        k.create_dataset("prr", data=np.array([l[4] / l[3] for l in links], np.float32))
        k.create_dataset("mean_distance_m", data=np.full(len(links), 50.0, np.float32))

        q = f.create_group("prr_rats")
        q.create_dataset("rat", data=np.array([p[0] for p in prr_rats], np.uint8))
        q.create_dataset("packets", data=np.array([p[1] for p in prr_rats], np.uint64))
        q.create_dataset("received", data=np.array([p[2] for p in prr_rats], np.uint64))
        q.create_dataset("prr", data=np.array([p[3] for p in prr_rats], np.float32))


def file_a(path, **kw):
    write_sinr(path, "ray", KEYS_A, DIST_A, SINR_A, PRX_A, DEC_A, OVL_A, PRR_RATS_A, LINKS_A, **kw)


def file_b(path, **kw):
    write_sinr(path, "tr37885-urban", KEYS_B, DIST_B, SINR_B, PRX_B, DEC_B, OVL_B, PRR_RATS_B, LINKS_B, **kw)


def run(*args):
    p = subprocess.run([sys.executable, SCRIPT, *args], capture_output=True, text=True)
    return p.returncode, p.stdout, p.stderr


def dr(d):
    return d["dr"]


def test_report(tmp):
    a, b = os.path.join(tmp, "a.h5"), os.path.join(tmp, "b.h5")
    c = os.path.join(tmp, "c.h5")
    file_a(a)
    file_b(b)
    # C: B's outcomes over a schedule that differs (t3 starts later), with LoS taken from the ray run.
    moved = TRANSMISSIONS[:3] + [(1, 1, 12, 0, 0.004)]
    file_b(c, los_from_ray=1, transmissions=moved)
    out = os.path.join(tmp, "out", "nested")
    rc, stdout, stderr = run(out, a, b, c)
    check(rc == 0, f"report exit code {rc}: {stderr}")
    if rc != 0:
        return
    with open(os.path.join(out, "report.json")) as fh:
        rep = json.load(fh)
    files = rep["files"]
    check([f["label"] for f in files] == ["ray", "tr37885-urban", "tr37885-urban+los-from-ray"],
          f"labels {[f['label'] for f in files]}")
    check(rep["reference"] == "ray", f"reference {rep['reference']}")
    check(rep["rats"] == ["80211p", "nrv2x"], f"rats {rep['rats']}")
    fa, fb, fc = files
    check(fa["comparison"] is None, "the reference has no comparison")
    check(fa["transmissions"] == 4 and fa["receptions"] == 8 and fb["receptions"] == 9,
          f"counts {fa['transmissions']} {fa['receptions']} {fb['receptions']}")
    check(fa["prr_range_m"] == 150.0, f"prr_range_m {fa['prr_range_m']}")

    # PRR per RAT equals /prr_rats.
    for f, path in ((fa, a), (fb, b)):
        with h5py.File(path, "r") as h:
            for rat, name in ((1, "80211p"), (2, "nrv2x")):
                i = int(np.flatnonzero(h["prr_rats/rat"][...] == rat)[0])
                p = f["rats"][name]["prr"]
                check(p["prr"] == float(h["prr_rats/prr"][i]), f"{f['label']} {name} PRR {p['prr']}")
                check(p["packets"] == int(h["prr_rats/packets"][i]) and p["received"] == int(h["prr_rats/received"][i]),
                      f"{f['label']} {name} PRR counts {p}")
    check(fb["rats"]["80211p"]["prr"]["prr"] == 0.75, "B 80211p PRR 0.75")

    # Decoded fractions, SINR statistics, bimodality.
    ra = fa["rats"]
    check(ra["80211p"]["decoded_fraction"] == 0.5 and ra["nrv2x"]["decoded_fraction"] == 0.5,
          f"A decoded fractions {ra['80211p']['decoded_fraction']} {ra['nrv2x']['decoded_fraction']}")
    check(fb["rats"]["80211p"]["decoded_fraction"] == 3 / 5, f"B 80211p decoded {fb['rats']['80211p']['decoded_fraction']}")
    s1 = ra["80211p"]["sinr"]
    check(s1["n"] == 4 and s1["mean_db"] == 5.0 and s1["median_db"] == 5.0, f"A 80211p SINR stats {s1}")
    check(close(s1["bimodality"], 2738 / 22695), f"A 80211p bimodality {s1['bimodality']} != {2738 / 22695}")
    s2 = ra["nrv2x"]["sinr"]  # r2 below sensitivity and r4 -inf leave SINR 8 and 3
    check(s2["n"] == 2 and s2["mean_db"] == 5.5 and s2["bimodality"] is None, f"A nrv2x SINR stats {s2}")

    # Per-node PRR as transmitter: A rat 1: node 0 3/4, node 1 0/2.
    t1 = ra["80211p"]["tx_node_prr"]
    check(t1["nodes"] == 2 and close(t1["mean"], 0.375) and t1["min"] == 0.0 and t1["max"] == 0.75,
          f"A 80211p tx-node PRR {t1}")
    t2 = ra["nrv2x"]["tx_node_prr"]
    check(t2["nodes"] == 1 and t2["mean"] == 1.0, f"A nrv2x tx-node PRR {t2}")

    # PRR vs distance of the first attempts.
    c1 = ra["80211p"]["prr_distance"]
    check(c1["lower_m"] == [0, 25, 50] and c1["samples"] == [2, 1, 1] and c1["prr"] == [0.5, 1.0, 0.0],
          f"A 80211p PRR-distance {c1}")
    c2 = ra["nrv2x"]["prr_distance"]
    check(c2["lower_m"] == [25, 75] and c2["samples"] == [1, 1] and c2["prr"] == [1.0, 1.0],
          f"A nrv2x PRR-distance {c2}")

    # Disagreement with the reference.
    cb = fb["comparison"]
    d = cb["decodability"]
    check(cb["schedules_identical"] is True, "A and B share the schedule")
    check(d["dr"] == 0.5 and d["symmetric_difference"] == 3 and d["union"] == 6, f"DR decodability {d}")
    check(d["common_keys"] == 8 and d["only_in_reference"] == 0 and d["only_in_file"] == 1, f"key counts {d}")
    check(close(dr(d["per_rat"]["80211p"]), 2 / 3) and close(dr(d["per_rat"]["nrv2x"]), 1 / 3),
          f"DR decodability per RAT {d['per_rat']}")
    i = cb["interferer_detection"]
    check(close(i["dr"], 2 / 3) and i["symmetric_difference"] == 4 and i["union"] == 6 and i["both"] == 2,
          f"DR interferer detection {i}")
    check(close(dr(i["per_rat"]["80211p"]), 2 / 3) and close(dr(i["per_rat"]["nrv2x"]), 2 / 3),
          f"DR interferer detection per RAT {i['per_rat']}")
    cc = fc["comparison"]
    check(cc["schedules_identical"] is False and "differing schedules" in cc.get("note", ""),
          f"C: differing schedules {cc.get('schedules_identical')} {cc.get('note')}")
    check(cc["decodability"]["dr"] == 0.5, f"C DR over keys anyway {cc['decodability']['dr']}")

    # Outputs.
    for name in ("sinr_pdf.png", "prr_distance.png", "report.json", "report.md"):
        p = os.path.join(out, name)
        check(os.path.isfile(p) and os.path.getsize(p) > 0, f"{name} exists and is not empty")
    for name in ("sinr_pdf.png", "prr_distance.png"):
        with open(os.path.join(out, name), "rb") as fh:
            check(fh.read(8) == b"\x89PNG\r\n\x1a\n", f"{name} is a PNG")
    check(sorted(os.listdir(out)) == ["prr_distance.png", "report.json", "report.md", "sinr_pdf.png"],
          f"no temporary files left: {os.listdir(out)}")
    with open(os.path.join(out, "report.md")) as fh:
        md = fh.read()
    check(stdout == md, "stdout is the Markdown report")
    check(md.startswith("| metric | ray | tr37885-urban | tr37885-urban+los-from-ray |"), "Markdown header")
    check("| DR decodability | reference | 0.5000 (3/6) |" in md, "Markdown DR decodability row")
    check("| DR inter-RAT interferer detection | reference | 0.6667 (4/6) |" in md, "Markdown DR interferer row")

    # Options: explicit labels, another reference, a colliding default label.
    rc, _, stderr = run(os.path.join(tmp, "out2"), a, b, "--labels", "RAY,URBAN", "--reference", "1")
    check(rc == 0, f"--labels/--reference exit {rc}: {stderr}")
    if rc == 0:
        with open(os.path.join(tmp, "out2", "report.json")) as fh:
            r2 = json.load(fh)
        check(r2["reference"] == "URBAN" and r2["files"][1]["comparison"] is None, "reference 1")
        check(r2["files"][0]["comparison"]["decodability"]["dr"] == 0.5, "DR is symmetric")
    a2 = os.path.join(tmp, "a_copy.h5")
    shutil.copy(a, a2)
    rc, _, stderr = run(os.path.join(tmp, "out3"), a, a2)
    check(rc == 0, f"same-model run exit {rc}: {stderr}")
    if rc == 0:
        with open(os.path.join(tmp, "out3", "report.json")) as fh:
            r3 = json.load(fh)
        check([f["label"] for f in r3["files"]] == ["ray (a)", "ray (a_copy)"], f"disambiguated labels {r3['files']}")
        c3 = r3["files"][1]["comparison"]
        check(c3["decodability"]["dr"] == 0.0 and c3["interferer_detection"]["dr"] == 0.0, "a file agrees with itself")


def test_errors(tmp):
    a = os.path.join(tmp, "a.h5")
    cases = []
    p = os.path.join(tmp, "incomplete.h5")
    file_a(p, complete=0)
    cases.append((p, "incomplete"))
    p = os.path.join(tmp, "unfinished.h5")
    file_a(p, complete=None)
    cases.append((p, "incomplete"))
    p = os.path.join(tmp, "text.h5")
    with open(p, "w") as fh:
        fh.write("not an HDF5 file\n")
    cases.append((p, "not an HDF5 file"))
    cases.append((os.path.join(tmp, "missing.h5"), "no such file"))
    p = os.path.join(tmp, "channels.h5")
    file_a(p, fmt="raysweep-channels")
    cases.append((p, "not a raysweep-sinr file"))
    p = os.path.join(tmp, "future.h5")
    file_a(p, version="2.0.0")
    cases.append((p, "not supported"))
    for path, why in cases:
        out = os.path.join(tmp, "err_" + os.path.basename(path))
        rc, stdout, stderr = run(out, a, path)
        lines = stderr.strip().splitlines()
        check(rc == 2, f"{os.path.basename(path)}: exit code {rc} (expected 2)")
        check(len(lines) == 1 and path in lines[0] and why in lines[0],
              f"{os.path.basename(path)}: one-line error naming the file ({why}): {stderr!r}")
        check(not os.path.exists(out), f"{os.path.basename(path)}: no output folder on error")


def main():
    tmp = tempfile.mkdtemp(prefix="sinr_report_test_")
    try:
        test_report(tmp)
        test_errors(tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if failures:
        print(f"{len(failures)} check(s) failed")
        return 1
    print("test_sinr_report: all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())

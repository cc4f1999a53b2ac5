#!/usr/bin/python3
"""Checks python/raysweep_dataset.py against a dataset written by tests/generators/test_dataset.cpp.

usage: test_reader.py DATASET.h5 EXPECTED.json SCRATCH_DIR
EXPECTED.json holds the values the C++ test computed from the records it wrote (-inf gains as null).
Exits 0 when every check passes; prints the failures and exits 1 otherwise.
"""
import json
import math
import os
import shutil
import sys
import traceback

import h5py
import numpy as np

import raysweep_dataset as rd

failures = []


def check(cond, what):
    if not cond:
        failures.append(what)
        print("FAIL:", what)


def gains(values):
    return np.array([-np.inf if v is None else v for v in values], dtype=np.float32)


def run(path, e, scratch):
    with rd.open_dataset(path) as ds:
        check(ds.frame_count == e["frames"], f"frame_count {ds.frame_count}")
        check(ds.link_count == e["links"], f"link_count {ds.link_count}")
        check(ds.path_count == e["paths"], f"path_count {ds.path_count}")
        check(ds.complete, "complete")
        check(np.array_equal(ds.times, np.array(e["times"])), f"times {ds.times}")
        nodes = ds.nodes
        check(list(nodes["id"]) == e["node_ids"], f"node ids {nodes['id']}")
        check(list(nodes["kind"]) == e["node_kinds"], f"node kinds {nodes['kind']}")
        check(list(nodes["vclass"]) == e["vclasses"], f"vclasses {nodes['vclass']}")
        check(nodes["dimensions"].shape == (3, 3), f"dimensions shape {nodes['dimensions'].shape}")
        check(np.isclose(nodes["dimensions"][2][2], 3.75), f"dimensions {nodes['dimensions']}")
        attrs = ds.attrs
        check(attrs["config"] == e["config"], f"config {attrs['config']}")
        check(attrs["seed"] == e["seed"], f"seed {attrs['seed']}")
        check(attrs["schema_version"] == "1.5.0", f"schema_version {attrs['schema_version']}")
        check(ds.store == "full" and ds.has_paths, f"store {ds.store}")

        # frame(i)
        for i in range(ds.frame_count):
            f = ds.frame(i)
            check(len(f["node"]) == e["frame_node_counts"][i], f"frame {i} node count {len(f['node'])}")
            check(len(f["tx"]) == e["frame_link_counts"][i], f"frame {i} link count {len(f['tx'])}")
            check(f["position"].shape == (len(f["node"]), 3), f"frame {i} position shape")
            check(np.all(f["frame"] == i), f"frame {i} link frames {f['frame']}")
            check(f["time_s"] == e["times"][i], f"frame {i} time {f['time_s']}")
        check(list(ds.frame(2)["node"]) == [0, 2], f"frame 2 nodes {ds.frame(2)['node']}")
        check(list(ds.frame(-1)["node"]) == [0, 2], "frame(-1) is the last frame")

        # pair() over time, ids in either order, and by index
        p = e["pair"]
        for a, b in ((p["a"], p["b"]), (p["b"], p["a"]), (2, 0)):
            h = ds.pair(a, b)
            check(h["tx"] == 0 and h["rx"] == 2, f"pair {a},{b} nodes {h['tx']},{h['rx']}")
            check(list(h["link"]) == p["link"], f"pair {a},{b} links {h['link']}")
            check(list(h["frame"]) == p["frame"], f"pair frames {h['frame']}")
            check(np.array_equal(h["time_s"], np.array(p["time_s"])), f"pair times {h['time_s']}")
            check(list(h["los_class"]) == p["los_class"], f"pair los {h['los_class']}")
            check(np.array_equal(h["gain_coherent_db"], gains(p["gain_coherent_db"])), f"pair gains {h['gain_coherent_db']}")
            check(list(h["path_count"]) == p["path_count"], f"pair path counts {h['path_count']}")
            check(np.array_equal(h["first_delay_s"], np.array(p["first_delay_s"])), "pair first delays")
        h = ds.pair("veh.a", "veh.b")
        check(list(h["frame"]) == [0, 1], f"pair veh.a-veh.b frames {h['frame']}")
        check(np.isinf(h["gain_coherent_db"][0]) and h["gain_coherent_db"][0] < 0, "out-of-range gain is -inf")
        check(h["flags"][0] & rd.FLAG_OUT_OF_RANGE, "out-of-range flag")

        # paths()
        q = e["paths_of_link"]
        paths = ds.paths(q["link"])
        check(paths["a"].dtype == np.complex64, f"a dtype {paths['a'].dtype}")
        a = np.array(q["a_re"], dtype=np.float32) + 1j * np.array(q["a_im"], dtype=np.float32)
        check(np.array_equal(paths["a"], a.astype(np.complex64)), f"a {paths['a']} vs {a}")
        check(np.array_equal(paths["tau_s"], np.array(q["tau_s"])), f"tau {paths['tau_s']}")
        check(np.array_equal(paths["aod"], np.array(q["aod"], dtype=np.float32)), f"aod {paths['aod']}")
        check(np.array_equal(paths["doppler_hz"], np.array(q["doppler_hz"], dtype=np.float32)), "doppler")
        check(len(paths["interactions"]) == len(q["interactions"]), "interactions per path")
        for got, want in zip(paths["interactions"], q["interactions"]):
            check(len(got) == len(want), f"interaction count {len(got)} vs {len(want)}")
            for g, (t, o, pt) in zip(got, want):
                check(int(g["type"]) == t and int(g["object"]) == o, f"interaction {g} vs {(t, o)}")
                check(np.array_equal(g["point"], np.array(pt, dtype=np.float32)), f"point {g['point']} vs {pt}")
        empty = ds.paths(e["out_of_range_link"])
        check(len(empty["a"]) == 0 and empty["interactions"] == [], "out-of-range link has no paths")

        # cfr()
        c = ds.cfr(e["cfr_link"])
        want = np.array(e["cfr_re"], dtype=np.float32) + 1j * np.array(e["cfr_im"], dtype=np.float32)
        check(c is not None and c.dtype == np.complex64 and np.array_equal(c, want.astype(np.complex64)), f"cfr {c}")
        freqs = ds.cfr_frequencies_hz()
        check(freqs is not None and len(freqs) == len(want), "cfr frequencies")

        # links_table()
        t = ds.links_table()
        check(set(t) == set(rd.LINK_COLUMNS), f"links_table columns {sorted(t)}")
        check(all(len(v) == e["links"] for v in t.values()), "links_table lengths")
        check(list(t["los_class"]) == e["labels"], f"links_table los {t['los_class']}")

    # LinkDataset
    data = rd.LinkDataset(path)
    check(len(data) == e["links"], f"LinkDataset length {len(data)}")
    x, y = data[0]
    x = np.asarray(x)
    check(x.shape == (len(data.feature_names),), f"feature shape {x.shape}")
    check(x.dtype == np.float32, f"feature dtype {x.dtype}")
    labels = [int(np.asarray(data[i][1])) for i in range(len(data))]
    check(labels == e["labels"], f"labels {labels}")
    j = data.feature_names.index("distance_m")
    check(math.isclose(float(x[j]), e["distance_link0"], rel_tol=1e-6), f"distance {x[j]} vs {e['distance_link0']}")
    k = data.feature_names.index("tx_kind")
    check(float(x[k]) == 1.0, "link 0 tx is the RSU")
    check(data.features.shape == (e["links"], len(data.feature_names)), f"features shape {data.features.shape}")
    in_range = rd.LinkDataset(path, include_out_of_range=False)
    check(len(in_range) == e["links"] - 1, f"in-range LinkDataset length {len(in_range)}")
    reg = rd.LinkDataset(path, features=("distance_m",), label="gain_coherent_db")
    check(np.asarray(reg[0][1]).dtype == np.float32, "float label")
    try:
        rd.LinkDataset(path, features=("no_such_feature",))
        check(False, "unknown feature accepted")
    except ValueError:
        pass

    # A file with schema major version 2 is refused with a clear message.
    os.makedirs(scratch, exist_ok=True)
    v2 = os.path.join(scratch, "v2.h5")
    shutil.copyfile(path, v2)
    with h5py.File(v2, "r+") as f:
        f.attrs["schema_version"] = "2.0.0"
    try:
        rd.open_dataset(v2)
        check(False, "schema 2.0.0 accepted")
    except ValueError as err:
        check("2.0.0" in str(err), f"message names the version: {err}")
    # and a minor version bump is accepted
    with h5py.File(v2, "r+") as f:
        f.attrs["schema_version"] = "1.7.0"
    with rd.open_dataset(v2) as ds:
        check(ds.frame_count == e["frames"], "schema 1.7.0 readable")
    # a file that is not a raysweep dataset
    other = os.path.join(scratch, "other.h5")
    with h5py.File(other, "w") as f:
        f.attrs["format"] = "something-else"
    try:
        rd.open_dataset(other)
        check(False, "foreign file accepted")
    except ValueError:
        pass


def main():
    path, expected, scratch = sys.argv[1:4]
    with open(expected) as f:
        e = json.load(f)
    try:
        run(path, e, scratch)
    except Exception:
        traceback.print_exc()
        failures.append("exception")
    return report()


def report():
    """The exit status of a check script: 1 with the failures counted, 0 when there are none."""
    if failures:
        print(f"{len(failures)} check(s) failed")
        return 1
    print("all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())

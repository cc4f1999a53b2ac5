#!/usr/bin/python3
"""Checks python/raysweep_dataset.py on one dataset written at every store level
(tests/generators/test_store_levels.cpp writes them from the same records).

usage: test_reader_levels.py LINKS.h5 CFR.h5 PATHS.h5 FULL.h5 PATHS_TOP2.h5
Exits 0 when every check passes; prints the failures and exits 1 otherwise.
"""
import sys

import numpy as np

import raysweep_dataset as rd
from test_reader import check, report


def same_bits(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.tobytes() == b.tobytes()


def main():
    files = dict(zip(("links", "cfr", "paths", "full", "top2"), sys.argv[1:6]))
    full = rd.open_dataset(files["full"])
    reference = full.links_table()
    check({"k_factor_db", "aod_spread_rad", "strongest_aoa", "paths_beyond_top_k"} <= set(full.link_columns),
          f"1.4.0 columns in {full.link_columns}")
    for level in ("links", "cfr", "paths", "full"):
        with rd.open_dataset(files[level]) as ds:
            check(ds.store == level, f"{level}: store {ds.store}")
            check(ds.path_count == 9, f"{level}: path_count {ds.path_count}")
            table = ds.links_table()
            for c, v in reference.items():
                if c == "path_offset":
                    check((c in table) == (level in ("paths", "full")), f"{level}: path_offset present")
                    continue
                check(same_bits(table[c], v), f"{level}: /links/{c} differs from the full file's")
            cfr = ds.cfr(5)
            if level == "links":
                check(cfr is None and not ds.has_cfr, "links: no CFR")
            else:
                check(same_bits(cfr, full.cfr(5)), f"{level}: CFR differs")
            if level in ("links", "cfr"):
                try:
                    ds.paths(1)
                    check(False, f"{level}: paths() without paths did not raise")
                except ValueError as e:
                    check("store level" in str(e) and '"paths"' in str(e), f"{level}: message {e}")
            else:
                p, q = ds.paths(1), full.paths(1)
                check(same_bits(p["a"], q["a"]) and same_bits(p["tau_s"], q["tau_s"]), f"{level}: paths differ")
                points = np.concatenate([i["point"] for i in p["interactions"]])
                if level == "paths":
                    check(np.all(np.isnan(points)), "paths: interaction points are NaN")
                else:
                    check(same_bits(points, np.concatenate([i["point"] for i in q["interactions"]])), "full: points")
                objects = [list(i["object"]) for i in p["interactions"]]
                check(objects == [list(i["object"]) for i in q["interactions"]], f"{level}: objects {objects}")
    with rd.open_dataset(files["top2"]) as ds:
        check(ds.paths_top_k == 2, f"top2: paths_top_k {ds.paths_top_k}")
        t = ds.links_table()
        check(same_bits(t["path_count"] + t["paths_beyond_top_k"], reference["path_count"]),
              "top2: path_count + paths_beyond_top_k is the full file's path_count")
        p, q = ds.paths(1), full.paths(1)
        check(same_bits(p["tau_s"], q["tau_s"][1:]), f"top2: link 1 keeps its two strongest paths {p['tau_s']}")
    full.close()
    return report()


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/python3
"""Test inputs for python/ml: a features.h5 for a given dataset.h5, and a tiny synthetic run dir.

usage: ml_fixture.py DATASET.h5 OUT_features.h5 [--stride N] [--informative]
  writes a features.h5 (format raysweep-features 1.0.0) aligned to DATASET.h5's links: random
  corridors and vehicles of the right shapes and types. --informative puts buildings on the
  tx-rx line of NLOS links and a vehicle on it of NLOSV links (for checking the wiring only: it
  leaks the label). make_run_dir(DIR) writes DIR/dataset.h5, DIR/features.h5, DIR/sinr/ray.h5.
"""
import argparse
import json
import os

import h5py
import numpy as np

import raysweep_dataset as rd

A, C, W, K = 64, 16, 20.0, 16
MATERIALS = ["none", "concrete", "brick", "glass"]
VEHICLE_CLASSES = ["passenger", "truck", "bus"]


def _vehicles(rng, n, d):
    """(n, K, 6) random vehicles in the corridor, NaN beyond count, sorted by along; count (n,)."""
    count = rng.integers(0, 5, n).astype(np.uint8)
    feats = np.full((n, K, 6), np.nan, np.float32)
    for i in range(n):
        k = int(count[i])
        along = np.sort(rng.uniform(0, max(d[i], 1e-3), k))
        kind = rng.integers(0, len(VEHICLE_CLASSES), k)
        dims = np.array([[5.0, 1.8, 1.5], [7.1, 2.4, 2.4], [12.0, 2.5, 3.4]])[kind]
        feats[i, :k] = np.column_stack([along, rng.uniform(-W, W, k), dims[:, 2], dims[:, 0], dims[:, 1], kind])
    return feats, count


def _corridor(rng, cls, d, informative, grid):
    """Random rasters and vehicles of one block of links (u8 draws: big datasets stay small)."""
    m, (A, C) = len(cls), grid
    height = np.where(rng.random((m, A, C), np.float32) < 0.3, rng.integers(1, 120, (m, A, C), np.uint8), 0)
    height = height.astype(np.uint8)
    material = np.where(height > 0, rng.integers(1, len(MATERIALS), (m, A, C), np.uint8), 0).astype(np.uint8)
    veh, count = _vehicles(rng, m, d)
    if informative:
        height[cls == 2, A // 4:A // 2, C // 2 - 1:C // 2 + 1] = 80
        height[cls != 2, :, C // 2 - 2:C // 2 + 2] = 0
        veh[cls == 1, 0, 0] = 0.5 * d[cls == 1]
        veh[cls == 1, 0, 1] = 0.0
        veh[cls == 1, 0, 2:5] = [3.4, 12.0, 2.5]
        count[cls == 1] = np.maximum(count[cls == 1], 1)
    return height, material, veh, count


def write_features(dataset_path, out_path, stride=1, informative=False, seed=0, block=16384, grid=(A, C)):
    """features.h5 for the links of the frames f with f % stride == 0, written via a temporary name."""
    rng = np.random.default_rng(seed)
    with rd.open_dataset(dataset_path) as ds:
        frame = ds._column("links/frame")
        total = len(frame)
        rows = np.nonzero(frame % stride == 0)[0]
        cls = ds._column("links/los_class_fresnel")[rows]
        t, r = ds.link_node_states()
        pos = ds._column("node_states/position")
        d = np.linalg.norm(pos[t[rows], :2] - pos[r[rows], :2], axis=1)
    m, (A, C) = len(rows), grid  # noqa: N806 (the module's grid constants, overridden)
    tmp = out_path + ".tmp"
    with h5py.File(tmp, "w") as f:
        f.attrs.update({"format": "raysweep-features", "schema_version": "1.0.0", "along_cells": np.uint32(A),
                        "across_cells": np.uint32(C), "half_width_m": W, "max_vehicles": np.uint32(K),
                        "height_scale_m": 0.25, "material_classes": json.dumps(MATERIALS),
                        "vehicle_classes": json.dumps(VEHICLE_CLASSES), "dataset_link_count": np.uint64(total),
                        "config": "{}", "inputs": "[]", "provenance": "{}"})
        f["links/link"] = rows.astype(np.uint64)
        f["links/frame"] = frame[rows].astype(np.uint32)
        # The layout raysweep features writes (schemas/README.md): rasters (M, A x C), a (M, K)
        # array per vehicle field, class 255 in empty slots.
        chunk = min(max(m, 1), 256)
        out = {name: f.create_dataset(name, (m, A * C), np.uint8, compression="gzip", chunks=(chunk, A * C))
               for name in ("corridor/height", "corridor/material")}
        fields = ("along_m", "across_m", "height_m", "length_m", "width_m", "vclass")
        for field in fields:
            out["vehicles/" + field] = f.create_dataset("vehicles/" + field, (m, K),
                                                        np.uint8 if field == "vclass" else np.float32)
        out["vehicles/count"] = f.create_dataset("vehicles/count", (m,), np.uint8)
        for b in range(0, m, block):
            height, material, veh, count = _corridor(rng, cls[b:b + block], d[b:b + block], informative, grid)
            n = len(count)
            out["corridor/height"][b:b + n] = height.reshape(n, A * C)
            out["corridor/material"][b:b + n] = material.reshape(n, A * C)
            for j, field in enumerate(fields):
                v = veh[:, :, j]
                out["vehicles/" + field][b:b + n] = np.where(np.isnan(v), 255, v).astype(np.uint8) \
                    if field == "vclass" else v
            out["vehicles/count"][b:b + n] = count
        f.attrs["complete"] = np.uint8(1)
    os.replace(tmp, out_path)


def _strings(group, name, values):
    group.create_dataset(name, data=np.array(values, dtype=object), dtype=h5py.string_dtype())


def _write_dataset(path, rng, frames=60, nodes=6):
    """A minimal channel dataset: `nodes` vehicles on two crossing roads, every pair every frame,
    with only the columns python/ml reads; LoS class and gain follow distance (plus noise)."""
    times = 10.0 + 0.1 * np.arange(frames)
    start = rng.uniform(0, 150, nodes)
    speed = rng.uniform(5, 15, nodes)
    along_x = np.arange(nodes) % 2 == 0
    pos = np.zeros((frames, nodes, 3))
    s = start[None, :] + speed[None, :] * (times - times[0])[:, None]
    pos[:, :, 0] = np.where(along_x, s, 75.0)
    pos[:, :, 1] = np.where(along_x, 75.0, s)
    pairs = [(a, b) for a in range(nodes) for b in range(a + 1, nodes)]
    links = {k: [] for k in ("frame", "tx", "rx", "flags", "los_class", "los_class_fresnel", "gain_incoherent_db")}
    for f in range(frames):
        for a, b in pairs:
            d = max(np.linalg.norm(pos[f, a] - pos[f, b]), 1.0)
            cls = int(np.clip(np.floor(d / 60 + rng.uniform(0, 1.5)), 0, 2))
            far = d > 190
            links["frame"].append(f), links["tx"].append(a), links["rx"].append(b)
            links["flags"].append(2 if far else 0)
            links["los_class"].append(cls if rng.random() > 0.1 else (cls + 1) % 3)
            links["los_class_fresnel"].append(cls)
            links["gain_incoherent_db"].append(-np.inf if far else -47 - 20 * np.log10(d) - 8 * cls + rng.normal(0, 3))
    types = {"frame": np.uint32, "tx": np.uint32, "rx": np.uint32, "flags": np.uint8, "los_class": np.uint8,
             "los_class_fresnel": np.uint8, "gain_incoherent_db": np.float32}
    with h5py.File(path, "w") as h:
        h.attrs.update({"format": "raysweep-channels", "schema_version": "1.4.0", "carrier_hz": 5.9e9,
                        "complete": np.uint8(1),
                        "config": json.dumps({"radio": {"sensitivity_dbm": -93.0, "tx_power_dbm": 20.0}})})
        for k, t in types.items():
            h[f"links/{k}"] = np.array(links[k], dtype=t)
        h["frames/time_s"] = times
        h["frames/node_offset"] = (np.arange(frames) * nodes).astype(np.uint64)
        h["frames/node_count"] = np.full(frames, nodes, np.uint32)
        h["frames/link_offset"] = (np.arange(frames) * len(pairs)).astype(np.uint64)
        h["frames/link_count"] = np.full(frames, len(pairs), np.uint32)
        h["node_states/node"] = np.tile(np.arange(nodes, dtype=np.uint32), frames)
        h["node_states/position"] = pos.reshape(-1, 3)
        vel = np.zeros((frames, nodes, 3), np.float32)
        vel[:, :, 0], vel[:, :, 1] = np.where(along_x, speed, 0), np.where(along_x, 0, speed)
        h["node_states/velocity"] = vel.reshape(-1, 3)
        h["node_states/heading_deg"] = np.tile(np.where(along_x, 90.0, 0.0), frames).astype(np.float32)
        g = h.create_group("nodes")
        _strings(g, "id", [f"veh{i}" for i in range(nodes)])
        g["kind"] = np.zeros(nodes, np.uint8)
        _strings(g, "vclass", ["passenger"] * (nodes - 1) + ["truck"])
        _strings(g, "vtype", ["car"] * nodes)
        g["dimensions"] = np.array([[5.0, 1.8, 1.5]] * (nodes - 1) + [[7.1, 2.4, 2.4]], np.float32)
    return times, links


def _write_sinr(path, rng, times, links, count=300):
    """A minimal SINR outcome file: 802.11p receptions of random links, decoded by the rule."""
    pick = rng.integers(0, len(links["frame"]), count)
    pick = pick[np.argsort(np.array(links["frame"])[pick], kind="stable")]
    frame = np.array(links["frame"])[pick]
    gain = np.array(links["gain_incoherent_db"])[pick]
    noise = np.full(count, -95.9, np.float32)
    prx = 20.0 + gain
    decoded = ((prx >= -93.0) & (prx - noise >= 10.0)).astype(np.uint8)
    swap = rng.random(count) < 0.5  # receptions go either way along a pair
    tx = np.where(swap, np.array(links["rx"])[pick], np.array(links["tx"])[pick]).astype(np.uint32)
    rx = np.where(swap, np.array(links["tx"])[pick], np.array(links["rx"])[pick]).astype(np.uint32)
    with h5py.File(path, "w") as h:
        h.attrs.update({"format": "raysweep-sinr", "schema_version": "1.0.0", "sinr_threshold_db": 10.0,
                        "sensitivity_dbm": -93.0, "complete": np.uint8(1), "config": json.dumps({})})
        h["transmissions/power_dbm"] = np.full(count, 20.0, np.float32)
        h["transmissions/node"] = tx
        cols = {"transmission": np.arange(count, dtype=np.uint32), "tx": tx, "rx": rx,
                "rat": np.ones(count, np.uint8), "time_s": times[frame] + 0.01, "noise_dbm": noise,
                "intra_dbm": np.full(count, -np.inf, np.float32), "inter_dbm": np.full(count, -np.inf, np.float32),
                "prx_dbm": prx.astype(np.float32), "decoded": decoded}
        for k, v in cols.items():
            h["receptions/" + k] = v


def make_run_dir(directory, seed=0, with_sinr=True, frames=60, nodes=6, grid=(A, C)):
    """DIR/dataset.h5, DIR/features.h5 and (with_sinr) DIR/sinr/ray.h5 of a tiny synthetic city."""
    rng = np.random.default_rng(seed)
    os.makedirs(os.path.join(directory, "sinr"), exist_ok=True)
    times, links = _write_dataset(os.path.join(directory, "dataset.h5"), rng, frames, nodes)
    write_features(os.path.join(directory, "dataset.h5"), os.path.join(directory, "features.h5"), seed=seed,
                   grid=grid)
    if with_sinr:
        _write_sinr(os.path.join(directory, "sinr", "ray.h5"), rng, times, links)
    return directory


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("dataset")
    p.add_argument("out")
    p.add_argument("--stride", type=int, default=1)
    p.add_argument("--informative", action="store_true")
    a = p.parse_args()
    write_features(a.dataset, a.out, a.stride, a.informative)


if __name__ == "__main__":
    main()

#!/usr/bin/python3
"""Independent check for meshkit's model import: world-space bounding box of a
glTF/GLB model in raysweep's z-up frame, computed with numpy only.

Walks the default scene's node hierarchy (matrix or T*R*S, parent*child),
reads each triangle primitive's POSITION accessor, keeps only the vertices its
indices reference (so unused accessor entries do not widen the box) and maps
glTF's y-up axes to raysweep's z-up frame: (x, y, z)_raysweep = (z, x, y)_gltf.

Usage: /usr/bin/python3 gltf_bbox.py MODEL.gltf|MODEL.glb
(Debian's python3 has numpy; a pyenv python3 on PATH may not.)
"""
import json
import os
import struct
import sys

import numpy as np

COMPONENTS = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16,
              5125: np.uint32, 5126: np.float32}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def load(path):
    raw = open(path, "rb").read()
    if raw[:4] == b"glTF":
        json_len, = struct.unpack_from("<I", raw, 12)
        doc = json.loads(raw[20:20 + json_len])
        rest = 20 + json_len
        bin_chunk = None
        if rest + 8 <= len(raw):
            bin_len, = struct.unpack_from("<I", raw, rest)
            bin_chunk = raw[rest + 8:rest + 8 + bin_len]
    else:
        doc = json.loads(raw)
        bin_chunk = None
    buffers = []
    for b in doc["buffers"]:
        if "uri" not in b:
            buffers.append(bin_chunk)
        else:
            with open(os.path.join(os.path.dirname(path), b["uri"]), "rb") as f:
                buffers.append(f.read())
    return doc, buffers


def accessor(doc, buffers, index):
    a = doc["accessors"][index]
    assert "sparse" not in a, "sparse accessors not handled by this script"
    view = doc["bufferViews"][a["bufferView"]]
    dtype = np.dtype(COMPONENTS[a["componentType"]])
    width = WIDTH[a["type"]]
    stride = view.get("byteStride", dtype.itemsize * width)
    start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
    data = buffers[view["buffer"]]
    rows = [np.frombuffer(data, dtype=dtype, count=width, offset=start + i * stride)
            for i in range(a["count"])]
    return np.array(rows, dtype=np.float64).reshape(a["count"], width)


def local_matrix(node):
    if "matrix" in node:
        return np.array(node["matrix"], dtype=np.float64).reshape(4, 4).T  # column-major
    t = node.get("translation", [0, 0, 0])
    x, y, z, w = node.get("rotation", [0, 0, 0, 1])
    s = node.get("scale", [1, 1, 1])
    r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m = np.eye(4)
    m[:3, :3] = r @ np.diag(s)
    m[:3, 3] = t
    return m


def main(path):
    doc, buffers = load(path)
    scene = doc["scenes"][doc.get("scene", 0)]
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    parts = []
    stack = [(n, np.eye(4)) for n in scene["nodes"]]
    while stack:
        index, parent = stack.pop()
        node = doc["nodes"][index]
        world = parent @ local_matrix(node)
        if "mesh" in node:
            mesh = doc["meshes"][node["mesh"]]
            for prim in mesh["primitives"]:
                if prim.get("mode", 4) != 4:
                    continue
                pos = accessor(doc, buffers, prim["attributes"]["POSITION"])
                if "indices" in prim:
                    used = np.unique(accessor(doc, buffers, prim["indices"]).astype(np.int64))
                    pos = pos[used]
                p = (world @ np.c_[pos, np.ones(len(pos))].T).T[:, :3]
                zup = p[:, [2, 0, 1]]
                lo = np.minimum(lo, zup.min(axis=0))
                hi = np.maximum(hi, zup.max(axis=0))
                mat = doc["materials"][prim["material"]].get("name", "") if "material" in prim else ""
                parts.append((node.get("name", ""), mat))
        stack.extend((c, world) for c in node.get("children", []))
    print("parts", len(parts))
    print("min %.6f %.6f %.6f" % tuple(lo))
    print("max %.6f %.6f %.6f" % tuple(hi))
    print("size %.6f %.6f %.6f" % tuple(hi - lo))


if __name__ == "__main__":
    main(sys.argv[1])

#!/usr/bin/python3
"""Preview sheet of a raysweep vehicle library: side and top view of every
entry's LOD 0, triangles coloured by radio material, antenna marked.

usage: vehicles_preview.py LIBRARY_DIR [OUT.png]
Reads manifest.json and the uncompressed GLBs (numpy + matplotlib only).
"""
import json
import math
import os
import struct
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.lines  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

COLORS = {"metal": "#4b5a6a", "glass": "#6fb7d6", "rubber": "#151515", "plastic": "#d9731a",
          "textile": "#b39e7a", "human": "#d9a58c", "wood": "#85592e"}
COMPONENT = {5120: "i1", 5121: "u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def read_glb(path):
    """(material name, triangles Nx3x3 in the file's z-up frame) per primitive."""
    data = open(path, "rb").read()
    _, _, _ = struct.unpack_from("<III", data, 0)
    jlen, _ = struct.unpack_from("<II", data, 12)
    doc = json.loads(data[20:20 + jlen])
    blen = struct.unpack_from("<I", data, 20 + jlen)[0]
    binary = data[28 + jlen:28 + jlen + blen]
    if "KHR_draco_mesh_compression" in doc.get("extensionsUsed", []):
        raise ValueError("Draco-compressed library: preview needs plain GLBs")

    def accessor(i):
        a = doc["accessors"][i]
        view = doc["bufferViews"][a["bufferView"]]
        n = WIDTH[a["type"]]
        dtype = np.dtype(COMPONENT[a["componentType"]])
        start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
        return np.frombuffer(binary, dtype=dtype, count=a["count"] * n, offset=start).reshape(a["count"], n)

    out = []
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            pos = accessor(prim["attributes"]["POSITION"]).astype(float)
            idx = accessor(prim["indices"]).reshape(-1, 3)
            name = doc["materials"][prim["material"]]["name"] if "material" in prim else ""
            out.append((name.replace("itu_", ""), pos[idx]))
    return out


def draw(ax, prims, view, antenna):
    polys, colors, depth = [], [], []
    for material, tris in prims:
        if view == "side":  # looking from -y towards +y: x right, z up; near faces drawn last
            proj, d = tris[:, :, [0, 2]], -tris[:, :, 1].mean(axis=1)
        else:  # top: x right, y up, higher faces last
            proj, d = tris[:, :, [0, 1]], tris[:, :, 2].mean(axis=1)
        polys.extend(proj)
        colors.extend([COLORS.get(material, "#ff00ff")] * len(proj))
        depth.extend(d)
    order = np.argsort(depth)
    ax.add_collection(PolyCollection([polys[i] for i in order], facecolors=[colors[i] for i in order],
                                     edgecolors="#00000030", linewidths=0.2))
    a = antenna[[0, 2]] if view == "side" else antenna[[0, 1]]
    ax.plot(a[0], a[1], marker="v", color="red", markersize=6)
    ax.autoscale_view()
    ax.set_aspect("equal")
    ax.tick_params(labelsize=6)


def main():
    if len(sys.argv) < 2:
        print(__doc__)
        return 2
    lib = sys.argv[1]
    out = sys.argv[2] if len(sys.argv) > 2 else os.path.join(lib, "preview.png")
    manifest = json.load(open(os.path.join(lib, "manifest.json"), encoding="utf-8"))
    entries = manifest["vehicles"]
    cols = 4
    rows = math.ceil(len(entries) / cols)
    fig, axes = plt.subplots(rows * 2, cols, figsize=(4 * cols, 2.6 * rows * 2), dpi=90, squeeze=False)
    used = set()
    for i, v in enumerate(entries):
        prims = read_glb(os.path.join(lib, v["lods"][0]["file"]))
        used.update(m for m, _ in prims)
        r, c = 2 * (i // cols), i % cols
        antenna = np.array(v["antenna"], dtype=float)
        draw(axes[r][c], prims, "side", antenna)
        draw(axes[r + 1][c], prims, "top", antenna)
        d = v["dims"]
        axes[r][c].set_title(f"{v['name']} ({d['length']:.2f} x {d['width']:.2f} x {d['height']:.2f} m)", fontsize=8)
    for i in range(len(entries), rows * cols):
        axes[2 * (i // cols)][i % cols].axis("off")
        axes[2 * (i // cols) + 1][i % cols].axis("off")
    handles = [Patch(color=COLORS.get(m, "#ff00ff"), label=m) for m in sorted(used)]
    handles.append(matplotlib.lines.Line2D([], [], color="red", marker="v", linestyle="", label="antenna"))
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=9)
    fig.suptitle("raysweep vehicle library: side (x-z) and top (x-y) views, front at x = 0", fontsize=11)
    fig.tight_layout(rect=(0, 0.03, 1, 0.97))
    fig.savefig(out)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())

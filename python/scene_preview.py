#!/usr/bin/python3
"""Top-down preview of a raysweep scene folder: roofs coloured by radio material,
shaded by height, with the network lanes when a manifest names a network.

usage: scene_preview.py SCENE_DIR [OUT.png]
Reads SCENE_DIR/mitsuba/scene.xml and its PLY meshes (the same geometry as
scene.glb) so it needs only numpy and matplotlib (run with /usr/bin/python3).
"""
import gzip
import json
import os
import re
import sys
import xml.etree.ElementTree as ET

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import matplotlib.lines  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

COLORS = {
    "concrete": "#9e9e9e", "brick": "#b5533c", "glass": "#6fb7d6", "wood": "#a0784a",
    "metal": "#4b5a6a", "plasterboard": "#e0d6c2", "medium_dry_ground": "#d9e6c9",
    "very_dry_ground": "#efe3c2", "wet_ground": "#a9c9a0",
}


def read_ply(path):
    """Binary little-endian or ascii PLY with float x,y,z and uchar/int face lists."""
    with open(path, "rb") as f:
        header = []
        while True:
            line = f.readline().decode("ascii", "replace").strip()
            header.append(line)
            if line == "end_header":
                break
        body = f.read()
    fmt = next(h.split()[1] for h in header if h.startswith("format"))
    elements, current = [], None
    for h in header:
        parts = h.split()
        if parts[:1] == ["element"]:
            current = [parts[1], int(parts[2]), []]
            elements.append(current)
        elif parts[:1] == ["property"] and current is not None:
            current[2].append(parts[1:])
    sizes = {"float": 4, "float32": 4, "double": 8, "float64": 8, "uchar": 1, "uint8": 1, "char": 1,
             "int": 4, "int32": 4, "uint": 4, "uint32": 4, "short": 2, "ushort": 2}
    np_types = {"float": "<f4", "float32": "<f4", "double": "<f8", "float64": "<f8", "uchar": "u1",
                "uint8": "u1", "char": "i1", "int": "<i4", "int32": "<i4", "uint": "<u4", "uint32": "<u4",
                "short": "<i2", "ushort": "<u2"}
    if fmt == "ascii":
        tokens = body.split()
        pos, verts, faces = 0, None, []
        for name, count, props in elements:
            if name == "vertex":
                n = len(props)
                arr = np.array(tokens[pos:pos + n * count], dtype=float).reshape(count, n)
                pos += n * count
                names = [p[-1] for p in props]
                verts = arr[:, [names.index("x"), names.index("y"), names.index("z")]]
            elif name == "face":
                for _ in range(count):
                    k = int(tokens[pos])
                    faces.append([int(t) for t in tokens[pos + 1:pos + 1 + k]])
                    pos += 1 + k
        return verts, faces
    pos, verts, faces = 0, None, []
    for name, count, props in elements:
        if name == "vertex":
            dtype = np.dtype([(p[-1], np_types[p[0]]) for p in props])
            arr = np.frombuffer(body, dtype=dtype, count=count, offset=pos)
            pos += dtype.itemsize * count
            verts = np.stack([arr["x"], arr["y"], arr["z"]], axis=1).astype(float)
        elif name == "face":
            list_type, index_type = props[0][1], props[0][2]
            lt, it = np_types[list_type], np_types[index_type]
            ls, isz = sizes[list_type], sizes[index_type]
            for _ in range(count):
                k = int(np.frombuffer(body, dtype=lt, count=1, offset=pos)[0])
                pos += ls
                faces.append(np.frombuffer(body, dtype=it, count=k, offset=pos).tolist())
                pos += isz * k
    return verts, faces


def network_lanes(scene_dir):
    """Lane centre lines of the network the scene was built against, if any."""
    try:
        manifest = json.load(open(os.path.join(scene_dir, "manifest.json"), encoding="utf-8"))
        net = next(i["path"] for i in manifest["provenance"]["inputs"] if i["role"] == "net")
        opener = gzip.open if open(net, "rb").read(2) == b"\x1f\x8b" else open
        lanes = []
        with opener(net, "rb") as f:
            for _, el in ET.iterparse(f):
                if el.tag == "edge":
                    if el.get("function") != "internal":
                        for lane in el.findall("lane"):
                            pts = [tuple(map(float, p.split(",")[:2])) for p in lane.get("shape", "").split()]
                            if len(pts) > 1:
                                lanes.append(pts)
                    el.clear()
        return lanes
    except (OSError, KeyError, StopIteration, ValueError, ET.ParseError):
        return []


def main():
    if len(sys.argv) < 2:
        print(__doc__)
        return 2
    scene_dir = sys.argv[1]
    out = sys.argv[2] if len(sys.argv) > 2 else os.path.join(scene_dir, "preview.png")
    xml_path = os.path.join(scene_dir, "mitsuba", "scene.xml")
    xml = open(xml_path, encoding="utf-8").read()
    shapes = re.findall(r'<string name="filename" value="([^"]+)"/>\s*'
                        r'(?:<boolean[^>]*/>\s*)?<ref id="mat-itu_([a-z_]+)"', xml)
    fig, ax = plt.subplots(figsize=(9, 9), dpi=110)
    used = set()
    zmax = 1.0
    layers = []
    for filename, material in shapes:
        verts, faces = read_ply(os.path.join(scene_dir, "mitsuba", filename))
        tris = np.array([f[:3] for f in faces if len(f) >= 3], dtype=int)
        if len(tris) == 0:
            continue
        p = verts[tris]
        normal_z = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])[:, 2]
        up = normal_z > 0  # roofs and ground: what a view from above sees
        layers.append((material, p[up], p[up][:, :, 2].max(axis=1)))
        zmax = max(zmax, float(verts[:, 2].max()))
        used.add(material)
    for material, polys, heights in sorted(layers, key=lambda l: l[2].min() if len(l[2]) else 0):
        order = np.argsort(heights)
        base = np.array(matplotlib.colors.to_rgb(COLORS.get(material, "#ff00ff")))
        shade = 0.55 + 0.45 * (heights[order] / zmax)[:, None]
        if material.endswith("ground"):
            shade = np.ones_like(shade)
        ax.add_collection(PolyCollection(polys[order][:, :, :2], facecolors=np.clip(base * shade, 0, 1),
                                         edgecolors="face", linewidths=0.3))
    lanes = network_lanes(scene_dir)
    for lane in lanes:
        xy = np.array(lane)
        ax.plot(xy[:, 0], xy[:, 1], color="#303030", linewidth=0.6, alpha=0.8)
    ax.autoscale_view()
    ax.set_aspect("equal")
    ax.set_xlabel("x (m, network coordinates)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{os.path.basename(os.path.normpath(scene_dir))}: roofs by radio material "
                 f"(darker = lower, max {zmax:.0f} m)")
    handles = [Patch(color=COLORS.get(m, "#ff00ff"), label=m) for m in sorted(used)]
    if lanes:
        handles.append(matplotlib.lines.Line2D([], [], color="#303030", label="SUMO lanes"))
    ax.legend(handles=handles, loc="upper right")
    fig.tight_layout()
    fig.savefig(out)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())

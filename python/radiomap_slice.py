#!/usr/bin/python3
"""Horizontal slice of a raysweep radio map (OpenVDB) at antenna height.

usage: radiomap_slice.py MAP.vdb SCENE_DIR OUT.png [--texture] [--grid NAME]
Default picture: the slice of rss_dbm (received power of the best server, dBm)
over the scene outline (roofs by material, lanes), transmitters marked, with a
colour bar in dB. --texture writes only the coloured slice (RGBA, one pixel
per voxel, transparent where no voxel is active) and OUT.png.json with its
world extent and colour scale: what python/render_blender.py lays on the scene.
Reads the file with Debian's python3-openvdb (module pyopenvdb).
"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pyopenvdb as vdb  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scene_preview  # noqa: E402

CMAP = "viridis"


def load(path, grid_name):
    # pyopenvdb reads float grids only (the int grids los_class.* and
    # best_server need the C++ API), so the grid is read by name.
    meta = vdb.readMetadata(path)
    try:
        g = vdb.read(path, grid_name)
    except (KeyError, LookupError, ValueError, TypeError) as e:
        raise SystemExit(f"{path}: cannot read float grid {grid_name}: {e}")
    ijk, values = [], []
    for item in g.citerOnValues():
        if item.count != 1:  # tiles never occur in raysweep's files
            continue
        ijk.append(item.min)
        values.append(item.value)
    return g, np.array(ijk, dtype=int).reshape(-1, 3), np.array(values, dtype=float), meta


def slice_at(g, ijk, values, meta):
    """The layer nearest the first transmitter's height."""
    tx = json.loads(meta["tx"])
    z_tx = tx[0]["position_m"][2] if tx else 1.5
    ks = np.unique(ijk[:, 2])
    zs = np.array([g.transform.indexToWorld((0, 0, int(k)))[2] for k in ks])
    k = int(ks[np.argmin(np.abs(zs - z_tx))])
    sel = ijk[:, 2] == k
    return ijk[sel], values[sel], float(zs[np.argmin(np.abs(zs - z_tx))]), tx


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    texture = "--texture" in sys.argv
    grid_name = "rss_dbm"
    if "--grid" in sys.argv:
        grid_name = sys.argv[sys.argv.index("--grid") + 1]
        args.remove(grid_name)
    if len(args) != 3:
        print(__doc__)
        return 2
    path, scene_dir, out = args
    g, ijk, values, meta = load(path, grid_name)
    if len(values) == 0:
        raise SystemExit(f"{path}: grid {grid_name} has no active voxel")
    layer, vals, z, tx = slice_at(g, ijk, values, meta)
    v = float(meta["voxel_m"])
    floor = float(meta.get("sensitivity_dbm", -93)) if grid_name == "rss_dbm" else float(np.percentile(vals, 2))
    vmax = float(vals.max())
    vmin = min(floor, vmax - 1)
    i0, j0 = layer[:, 0].min(), layer[:, 1].min()
    w, h = layer[:, 0].max() - i0 + 1, layer[:, 1].max() - j0 + 1
    img = np.full((h, w), np.nan)
    img[layer[:, 1] - j0, layer[:, 0] - i0] = vals
    extent = [(i0 - 0.5) * v, (i0 + w - 0.5) * v, (j0 - 0.5) * v, (j0 + h - 0.5) * v]
    if texture:
        rgba = matplotlib.colormaps[CMAP]((np.clip(img, vmin, vmax) - vmin) / (vmax - vmin))
        rgba[np.isnan(img)] = (0, 0, 0, 0)
        plt.imsave(out, rgba[::-1], format="png")
        with open(out + ".json", "w", encoding="utf-8") as f:
            json.dump({"extent": extent, "z": z, "vmin": vmin, "vmax": vmax, "grid": grid_name, "cmap": CMAP,
                       "tx": tx}, f)
        return 0
    fig, ax = plt.subplots(figsize=(9, 7.5), dpi=110)
    try:  # the scene outline: roofs in grey, lanes
        import re
        xml = open(os.path.join(scene_dir, "mitsuba", "scene.xml"), encoding="utf-8").read()
        for filename, material in re.findall(r'<string name="filename" value="([^"]+)"/>\s*'
                                             r'(?:<boolean[^>]*/>\s*)?<ref id="mat-itu_([a-z_]+)"', xml):
            if material.endswith("ground"):
                continue
            verts, faces = scene_preview.read_ply(os.path.join(scene_dir, "mitsuba", filename))
            tris = np.array([f[:3] for f in faces if len(f) >= 3], dtype=int)
            if len(tris):
                ax.add_collection(PolyCollection(verts[tris][:, :, :2], facecolors="#c8c8c8", edgecolors="#c8c8c8",
                                                 linewidths=0.2, zorder=1))
        for lane in scene_preview.network_lanes(scene_dir):
            xy = np.array(lane)
            ax.plot(xy[:, 0], xy[:, 1], color="#606060", linewidth=0.4, alpha=0.6, zorder=2)
    except OSError:
        pass
    im = ax.imshow(img, origin="lower", extent=extent, cmap=CMAP, vmin=vmin, vmax=vmax, zorder=3,
                   interpolation="nearest")
    for t in tx:
        ax.plot(t["position_m"][0], t["position_m"][1], marker="^", color="red", markersize=9, zorder=4)
        ax.annotate(t["id"], (t["position_m"][0], t["position_m"][1]), xytext=(5, 5), textcoords="offset points",
                    color="red", zorder=4)
    ax.autoscale_view()
    ax.set_aspect("equal")
    ax.set_xlabel("x (m, network coordinates)")
    ax.set_ylabel("y (m)")
    label = "received power of the best server (dBm)" if grid_name == "rss_dbm" else grid_name + " (dB)"
    fig.colorbar(im, ax=ax, shrink=0.8, label=label)
    scene_name = os.path.basename(os.path.normpath(scene_dir))
    if scene_name.startswith(".") or "tmp" in scene_name:
        scene_name = "scene"
    ax.set_title(f"radio map: {grid_name} at z = {z:.1f} m ({len(vals)} voxels of {v:g} m), "
                 f"{float(meta['carrier_hz']) / 1e9:g} GHz")
    fig.tight_layout()
    fig.savefig(out, format="png")
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())

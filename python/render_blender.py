"""Render a raysweep scene with Blender (headless, Cycles on CPU).

Run by `raysweep render` as
  blender -b --factory-startup --python render_blender.py -- --scene scene.glb --out OUT.png
      [--vehicles vehicles.glb] [--paths TRACE.json] [--slice SLICE.png --slice-meta SLICE.png.json]
      [--camera top|oblique|X,Y,Z:TX,TY,TZ] [--size W,H] [--samples N] [--max-pairs N]
Materials get one flat colour per radio material (itu_<name>, as in
python/scene_preview.py), paths are thin tubes coloured by their last
interaction, antennas are spheres, the radio map is a textured plane at its
slice height; a legend is drawn into the picture's corner.
"""
import argparse
import json
import math
import sys

import numpy

numpy.bool = bool  # Blender 3.4's glTF importer still uses np.bool (removed in numpy 1.24)
import bpy  # noqa: E402
import mathutils  # noqa: E402

MATERIAL_COLORS = {
    "concrete": "#9e9e9e", "brick": "#b5533c", "glass": "#6fb7d6", "wood": "#a0784a",
    "metal": "#4b5a6a", "plasterboard": "#e0d6c2", "medium_dry_ground": "#d9e6c9",
    "very_dry_ground": "#efe3c2", "wet_ground": "#a9c9a0", "rubber": "#202020",
    "plastic": "#d0d0d0", "textile": "#7a5c8e", "human": "#e0b090",
}
PATH_COLORS = {"los": "#ffd400", "specular": "#e6194b", "refraction": "#3cb44b",
               "diffraction": "#4363d8", "diffuse": "#f58231"}


def rgb(hexcolor):
    h = hexcolor.lstrip("#")
    # Blender wants linear values: convert from sRGB.
    return tuple(((int(h[i:i + 2], 16) / 255.0) ** 2.2) for i in (0, 2, 4))


def flat_material(name, color, emission=0.0, alpha=1.0):
    m = bpy.data.materials.get(name) or bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes.get("Principled BSDF")
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.8
    if emission > 0:
        bsdf.inputs["Emission"].default_value = (*color, 1.0)
        bsdf.inputs["Emission Strength"].default_value = emission
    return m


def recolour(objects):
    """One colour per radio material: glTF materials are named itu_<material>."""
    used = set()
    for ob in objects:
        if ob.type != "MESH":
            continue
        for slot in ob.material_slots:
            name = slot.material.name if slot.material else ""
            key = name.split(".")[0]
            key = key[4:] if key.startswith("itu_") else key
            color = MATERIAL_COLORS.get(key, "#ff00ff")
            slot.material = flat_material("rs_" + key, rgb(color))
            used.add(key)
    return used


def import_glb(path):
    before = set(bpy.data.objects)
    bpy.ops.import_scene.gltf(filepath=path)
    return [o for o in bpy.data.objects if o not in before]


def tube(points, color_name, radius):
    curve = bpy.data.curves.new("path", type="CURVE")
    curve.dimensions = "3D"
    curve.bevel_depth = radius
    curve.bevel_resolution = 2
    spline = curve.splines.new("POLY")
    spline.points.add(len(points) - 1)
    for p, q in zip(spline.points, points):
        p.co = (q[0], q[1], q[2], 1.0)
    ob = bpy.data.objects.new("path", curve)
    ob.data.materials.append(flat_material("path_" + color_name, rgb(PATH_COLORS[color_name]), emission=2.0))
    bpy.context.collection.objects.link(ob)
    return ob


def sphere(center, radius, color):
    bpy.ops.mesh.primitive_uv_sphere_add(radius=radius, location=center, segments=16, ring_count=8)
    ob = bpy.context.active_object
    ob.data.materials.append(flat_material("antenna", rgb(color), emission=3.0))
    return ob


def draw_paths(path, max_pairs, radius):
    trace = json.load(open(path, encoding="utf-8"))
    nodes = {n["id"]: n["position"] for n in trace["nodes"]}
    pairs = [p for p in trace["pairs"] if p.get("paths")]
    pairs.sort(key=lambda p: -(p.get("path_gain_incoherent_db") or -1e9))
    kinds = set()
    for p in pairs[:max_pairs]:
        strongest = sorted(p["paths"], key=lambda q: -(q["a_re"] ** 2 + q["a_im"] ** 2))[:6]
        for q in strongest:
            pts = [nodes[p["tx"]]] + [i["point"] for i in q["interactions"]] + [nodes[p["rx"]]]
            kind = q["interactions"][-1]["type"] if q["interactions"] else "los"
            tube(pts, kind, radius)
            kinds.add(kind)
    for pos in nodes.values():
        sphere(pos, radius * 6, "#ff2020")
    return kinds


def slice_plane(tex, meta_path):
    meta = json.load(open(meta_path, encoding="utf-8"))
    x0, x1, y0, y1 = meta["extent"]
    bpy.ops.mesh.primitive_plane_add(size=1, location=((x0 + x1) / 2, (y0 + y1) / 2, meta["z"]))
    ob = bpy.context.active_object
    ob.scale = (x1 - x0, y1 - y0, 1)
    m = bpy.data.materials.new("radiomap")
    m.use_nodes = True
    nt = m.node_tree
    bsdf = nt.nodes.get("Principled BSDF")
    img = nt.nodes.new("ShaderNodeTexImage")
    img.image = bpy.data.images.load(tex)
    img.interpolation = "Closest"
    nt.links.new(img.outputs["Color"], bsdf.inputs["Base Color"])
    nt.links.new(img.outputs["Color"], bsdf.inputs["Emission"])
    bsdf.inputs["Emission Strength"].default_value = 0.6
    nt.links.new(img.outputs["Alpha"], bsdf.inputs["Alpha"])
    m.blend_method = "BLEND"
    ob.data.materials.append(m)
    for t in meta.get("tx", []):
        sphere(t["position_m"], 1.2, "#ff2020")
    return meta


def bounds(objects):
    lo = [math.inf] * 3
    hi = [-math.inf] * 3
    for ob in objects:
        if ob.type != "MESH":
            continue
        for c in ob.bound_box:
            w = ob.matrix_world @ mathutils.Vector(c)
            for k in range(3):
                lo[k] = min(lo[k], w[k])
                hi[k] = max(hi[k], w[k])
    return lo, hi


def camera(spec, lo, hi, aspect):
    cx, cy = (lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2
    span = max(hi[0] - lo[0], hi[1] - lo[1], 1.0)
    cam_data = bpy.data.cameras.new("camera")
    cam = bpy.data.objects.new("camera", cam_data)
    bpy.context.collection.objects.link(cam)
    if spec == "top":
        cam_data.type = "ORTHO"
        cam_data.ortho_scale = max(hi[0] - lo[0], (hi[1] - lo[1]) * aspect) * 1.05
        eye, target = (cx, cy, hi[2] + span), (cx, cy, 0)
    elif spec == "oblique":
        eye, target = (cx - 0.55 * span, cy - 0.75 * span, 0.6 * span), (cx, cy, 0)
        cam_data.lens = 30
    else:
        a, b = spec.split(":")
        eye, target = tuple(map(float, a.split(","))), tuple(map(float, b.split(",")))
        cam_data.lens = 30
    cam.location = eye
    d = mathutils.Vector(target) - mathutils.Vector(eye)
    cam.rotation_euler = d.to_track_quat("-Z", "Y").to_euler()
    cam_data.clip_end = 10 * span + 1000
    bpy.context.scene.camera = cam
    return cam


def legend(entries, cam, aspect):
    """Names in their colours, as text objects fixed to the camera (top left)."""
    data = cam.data
    half_w = data.ortho_scale / 2 if data.type == "ORTHO" else 0.5 * data.sensor_width / data.lens
    depth = 1.0 if data.type != "ORTHO" else 1.0
    half_h = half_w / aspect
    size = half_h * 0.055
    for n, (name, color) in enumerate(entries):
        txt = bpy.data.curves.new("legend", type="FONT")
        txt.body = name
        txt.size = size
        ob = bpy.data.objects.new("legend", txt)
        ob.data.materials.append(flat_material("legend_" + name, rgb(color), emission=4.0))
        bpy.context.collection.objects.link(ob)
        ob.parent = cam
        ob.location = (-half_w * 0.97, half_h * 0.93 - (n + 1) * size * 1.25, -depth)
    data.clip_start = min(data.clip_start, 0.5)


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--vehicles")
    ap.add_argument("--paths")
    ap.add_argument("--slice")
    ap.add_argument("--slice-meta")
    ap.add_argument("--camera", default="oblique")
    ap.add_argument("--size", default="1280,720")
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--max-pairs", type=int, default=4)
    a = ap.parse_args(argv)

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene_objects = import_glb(a.scene)
    used = recolour(scene_objects)
    # Frame the buildings, not the ground plane's margin.
    framed = [o for o in scene_objects if not o.name.startswith("ground")] or scene_objects
    lo, hi = bounds(framed)
    if a.vehicles:
        used |= recolour(import_glb(a.vehicles))
    kinds = set()
    span = max(hi[0] - lo[0], hi[1] - lo[1], 1.0)
    if a.paths:
        kinds = draw_paths(a.paths, a.max_pairs, radius=max(0.05, span / 1500))
    if a.slice:
        slice_plane(a.slice, a.slice_meta)

    sc = bpy.context.scene
    w, h = map(int, a.size.split(","))
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.samples = a.samples
    sc.cycles.use_denoising = False
    sc.cycles.max_bounces = 2
    sc.render.resolution_x, sc.render.resolution_y = w, h
    sc.render.resolution_percentage = 100
    sc.render.image_settings.file_format = "PNG"
    sc.render.filepath = a.out
    sc.view_settings.view_transform = "Standard"
    world = bpy.data.worlds.new("sky")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.8, 0.85, 0.9, 1)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.5
    sc.world = world
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", type="SUN"))
    sun.data.energy = 2.0
    sun.rotation_euler = (math.radians(35), math.radians(10), math.radians(30))
    bpy.context.collection.objects.link(sun)
    cam = camera(a.camera, lo, hi, w / h)
    entries = [(m, MATERIAL_COLORS.get(m, "#ff00ff")) for m in sorted(used)]
    entries += [("path: " + k, PATH_COLORS[k]) for k in sorted(kinds)]
    if a.slice:
        entries.append(("radio map: viridis, dark = weak", "#21918c"))
    legend(entries, cam, w / h)
    bpy.ops.render.render(write_still=True)
    print("legend:", ", ".join(name for name, _ in entries))


main()

#!/usr/bin/python3
"""Canonical cases: raysweep and Sionna RT against closed forms, one mechanism
at a time, where the two tools' models can be told apart from their searches.

    /usr/bin/python3 bench/peers/sionna/canonical.py [--build build] [--out DIR]

Each case is a scene of one object written here (Mitsuba XML + PLY),
imported by `raysweep scene --from-mitsuba`, traced by `raysweep trace` and
exported by it (`--mitsuba`, raysweep's own material parameters) for Sionna
RT 2.2, which runs in the peer's virtual environment (compare's venv, see
README.md); skipped cleanly without it. Closed forms (computed here, in
numpy/scipy, from the formulas, not from either tool):

  ground    two-ray over a medium-dry-ground half space, V polarisation (TM
            in the plane of incidence), P.2040 interface reflection; the
            coherent sum |a_LoS + a_ground|^2 too (independent of either tool's
            sign convention). 10, 50 and 200 m.
  wall      a 0.3 m concrete slab (one surface, P.2040 single-layer slab
            formulas): the reflection at 63 degrees (TE: the E field is
            vertical, the plane of incidence horizontal) and the transmission
            at normal incidence.
  wedge     the vertical edge of a perfectly conducting 90-degree corner
            (exterior angle 270 degrees, n = 1.5), receiver in the shadow
            region: UTD (Kouyoumjian-Pathak) soft coefficient, the E field
            parallel to the edge.
  wedge_h   the same corner turned so that its edge is horizontal: the
            vertical E field is perpendicular to the edge, UTD's hard
            coefficient.

Writes DIR/canonical.json and DIR/canonical.md: per case and path, |a| in dB
of the closed form, raysweep and Sionna, and the differences.
"""
import argparse
import glob
import json
import math
import os
import shutil
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(HERE)))
C0 = 299792458.0
EPS0 = 8.8541878128e-12
VENV = os.environ.get("RAYSWEEP_PEER_VENV", os.path.expanduser("~/.cache/raysweep/sionna-rt-2.2.0"))

# ----------------------------------------------------------------- closed forms


def eta(mat, f):
    """Complex relative permittivity, exp(+jwt): eps_r - j sigma / (w eps0)."""
    return mat["relative_permittivity"] - 1j * mat["conductivity"] / (2 * math.pi * f * EPS0)


def interface(e, cos_t):
    """P.2040 half-space reflection (TE, TM)."""
    sin2 = 1 - cos_t ** 2
    root = np.sqrt(e - sin2)
    r_te = (cos_t - root) / (cos_t + root)
    r_tm = (e * cos_t - root) / (e * cos_t + root)
    return r_te, r_tm


def slab(e, cos_t, d, lam):
    """P.2040 single-layer slab: (R_TE, R_TM), (T_TE, T_TM)."""
    sin2 = 1 - cos_t ** 2
    q = 2 * math.pi * d / lam * np.sqrt(e - sin2)
    q0 = 2 * math.pi * d / lam * cos_t
    out_r, out_t = [], []
    for r1 in interface(e, cos_t):
        den = 1 - r1 ** 2 * np.exp(-2j * q)
        out_r.append(r1 * (1 - np.exp(-2j * q)) / den)
        out_t.append((1 - r1 ** 2) * np.exp(-1j * (q - q0)) / den)
    return out_r, out_t


def utd_transition(x):
    """F(X) = 2j sqrt(X) e^{jX} int_{sqrt X}^inf e^{-j t^2} dt."""
    from scipy.special import fresnel
    s = math.sqrt(x)
    # int_u^inf e^{-j t^2} dt = sqrt(pi/2) [ (1/2 - C(v)) - j (1/2 - S(v)) ], v = u sqrt(2/pi)
    sv, cv = fresnel(s * math.sqrt(2 / math.pi))
    tail = math.sqrt(math.pi / 2) * ((0.5 - cv) - 1j * (0.5 - sv))
    return 2j * s * np.exp(1j * x) * tail


def utd_pec_soft(n, phi, phi_i, length, k, hard=False):
    """Kouyoumjian-Pathak, perfectly conducting wedge, normal incidence
    (beta0 = 90 deg): soft (E parallel to the edge) D1 + D2 - (D3 + D4), hard
    (E perpendicular to it) D1 + D2 + (D3 + D4)."""
    def a_pm(beta, sign):
        nn = round((beta + sign * math.pi) / (2 * math.pi * n))
        return 2 * math.cos((2 * math.pi * n * nn - beta) / 2) ** 2

    def term(beta, sign):
        cot = 1 / math.tan((math.pi + sign * beta) / (2 * n))
        return cot * utd_transition(k * length * a_pm(beta, sign))

    d1 = term(phi - phi_i, +1)
    d2 = term(phi - phi_i, -1)
    d3 = term(phi + phi_i, +1)
    d4 = term(phi + phi_i, -1)
    pre = -np.exp(-1j * math.pi / 4) / (2 * n * math.sqrt(2 * math.pi * k))
    return pre * (d1 + d2 + (1 if hard else -1) * (d3 + d4))


def er_wall_power(mat, f, step=0.1):
    """First-order diffuse path gain of the rough wall x = 0 (y in [-50, 50],
    z in [0, 20]) between (5, -10, 1.5) and (5, 10, 1.5), effective roughness
    (Degli-Esposti 2007) as an energy balance: of the power a smooth surface
    would reflect, S^2 is scattered with a directive lobe ((1 + cos psi_R) /
    2)^alpha_R normalised over the hemisphere. dG = lambda^2 S^2 |R|^2 f
    cos(theta_i) dA / (16 pi^2 r_i^2 r_s^2); the vertical E field splits
    between TE and TM by the tilt of each element's plane of incidence."""
    lam = C0 / f
    e = eta(mat, f)
    sc, alpha = mat["scattering_coefficient"], int(mat["alpha_r"])
    ys = np.arange(-50 + step / 2, 50, step)
    zs = np.arange(step / 2, 20, step)
    y, z = np.meshgrid(ys, zs)
    tx, rx = np.array([5.0, -10.0, 1.5]), np.array([5.0, 10.0, 1.5])
    p = np.stack([np.zeros_like(y), y, z], axis=-1)
    vi, vs = p - tx, rx - p
    ri, rs = np.linalg.norm(vi, axis=-1), np.linalg.norm(vs, axis=-1)
    ki, ks = vi / ri[..., None], vs / rs[..., None]
    n = np.array([1.0, 0, 0])
    cos_i = -(ki @ n)
    spec = ki + 2 * cos_i[..., None] * n
    cos_psi = np.sum(spec * ks, axis=-1)
    # lobe normalisation over the hemisphere x > 0, per incidence angle
    th = np.linspace(0, math.pi / 2, 181)[:-1] + math.pi / 360
    ph = np.linspace(0, 2 * math.pi, 361)[:-1] + math.pi / 360
    tt, pp = np.meshgrid(th, ph)
    dirs = np.stack([np.cos(tt), np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp)], axis=-1)
    d_omega = np.sin(tt) * (math.pi / 360) * (math.pi / 180)  # 0.5 deg in theta, 1 deg in phi

    def norm_at(cos_t):
        s_dir = np.array([cos_t, math.sqrt(max(0.0, 1 - cos_t ** 2)), 0.0])
        return np.sum(((1 + dirs @ s_dir) / 2) ** alpha * d_omega)
    table_c = np.linspace(0, 1, 201)
    table_f = np.array([norm_at(c) for c in table_c])
    lobe = ((1 + cos_psi) / 2) ** alpha / np.interp(cos_i, table_c, table_f)
    r_te, r_tm = interface(e, cos_i) if mat["thickness_m"] == 0 else slab(e, cos_i, mat["thickness_m"], lam)[0]
    # share of the vertical field perpendicular to the plane of incidence (TE)
    te_dir = np.cross(ki, n)
    te_norm = np.linalg.norm(te_dir, axis=-1)
    te_share = np.where(te_norm > 0, (te_dir[..., 2] / np.maximum(te_norm, 1e-12)) ** 2, 1.0)
    r2 = te_share * np.abs(r_te) ** 2 + (1 - te_share) * np.abs(r_tm) ** 2
    dg = lam ** 2 * sc ** 2 * r2 * lobe * cos_i / (16 * math.pi ** 2 * ri ** 2 * rs ** 2) * step * step
    return float(np.sum(dg))


def wedge_self_check(f=5.9e9):
    """The UTD closed form's own checks: across the shadow boundary (phi =
    phi' + pi) the diffracted field jumps by exactly the incident field, so
    the total field is continuous (returned: the mismatch over the incident
    field, dB); on the shadowed face (phi = n pi) the soft field vanishes
    (E tangential to a perfect conductor; returned: dB against free space)."""
    lam = C0 / f
    k = 2 * math.pi / lam
    s_i, s_d = 10 * math.sqrt(2), 20.0
    length = s_i * s_d / (s_i + s_d)
    phi_i = math.radians(45)

    def field(phi):  # the diffracted field over exp(-jk(s + s')), unit source
        return utd_pec_soft(1.5, phi, phi_i, length, k) * math.sqrt(s_i / (s_d * (s_i + s_d))) / s_i
    incident = 1 / (s_i + s_d)
    sb = phi_i + math.pi
    jump = field(sb + 1e-7) - (field(sb - 1e-7) + incident)
    return {"shadow boundary": db(jump / incident), "shadowed face": db(field(1.5 * math.pi - 1e-9) / incident)}


def db(a):
    return 20 * math.log10(abs(a)) if abs(a) > 0 else float("-inf")

# ----------------------------------------------------------------- scenes


def write_ply(path, verts, tris):
    with open(path, "w") as f:
        f.write(f"ply\nformat ascii 1.0\nelement vertex {len(verts)}\nproperty float x\nproperty float y\n"
                f"property float z\nelement face {len(tris)}\nproperty list uchar int vertex_indices\nend_header\n")
        for v in verts:
            f.write(" ".join(f"{c:.6f}" for c in v) + "\n")
        for t in tris:
            f.write("3 " + " ".join(str(i) for i in t) + "\n")


def write_scene(folder, shapes):
    """shapes: [(name, material, verts, tris)] -> folder/scene.xml."""
    os.makedirs(os.path.join(folder, "meshes"), exist_ok=True)
    mats = sorted({m for _, m, _, _ in shapes})
    xml = ['<scene version="2.1.0">']
    for m in mats:
        xml.append(f'  <bsdf type="diffuse" id="mat-itu_{m}"><rgb name="reflectance" value="0.5 0.5 0.5"/></bsdf>')
    for name, m, verts, tris in shapes:
        write_ply(os.path.join(folder, "meshes", name + ".ply"), verts, tris)
        xml.append(f'  <shape type="ply" id="mesh-{name}"><string name="filename" value="meshes/{name}.ply"/>'
                   f'<boolean name="face_normals" value="true"/><ref id="mat-itu_{m}" name="bsdf"/></shape>')
    xml.append("</scene>")
    with open(os.path.join(folder, "scene.xml"), "w") as f:
        f.write("\n".join(xml) + "\n")


def quad(p0, u, v):
    verts = [p0, [p0[i] + u[i] for i in range(3)], [p0[i] + u[i] + v[i] for i in range(3)], [p0[i] + v[i] for i in range(3)]]
    return verts, [[0, 1, 2], [0, 2, 3]]


def box(lo, hi):
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    verts = [[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0], [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]]
    tris = [[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4], [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6],
            [3, 0, 4], [3, 4, 7]]
    return verts, tris


WEDGE_ANGLES = (228, 235, 245, 255, 265)  # receivers' phi (deg from face 0), 20 m from the edge; shadow beyond 225


def wedge_rx(ang):
    std = math.pi - math.radians(ang)
    return 20 * math.cos(std), 20 * math.sin(std)


def cases():
    """name -> (shapes, nodes [(id, x, y, z)], raysweep --set list, Sionna solver flags)."""
    out = {}
    nodes = []
    for d in (10, 50, 200):
        nodes += [(f"a{d}", -d / 2, 1000 * (d // 10), 1.5), (f"b{d}", d / 2, 1000 * (d // 10), 1.5)]
    # one ground per distance, far apart, so every pair sees its own plane only
    shapes = []
    for k, d in enumerate((10, 50, 200)):
        v, t = quad([-200, 1000 * (d // 10) - 200, 0], [400, 0, 0], [0, 400, 0])
        shapes.append((f"ground{k}", "medium_dry_ground", v, t))
    out["ground"] = (shapes, nodes, ["tracer.max_depth=1", "tracer.diffraction=false", "tracer.diffuse=false",
                                     "tracer.refraction=false", "tracer.vehicle_diffraction=false"],
                     {"max_depth": 1, "refraction": False, "diffraction": False})
    # long enough for both pairs: the reflection at y = 0, the crossing at y = 200
    wall = quad([0, -50, 0], [0, 300, 0], [0, 0, 20])
    out["wall"] = ([("wall", "concrete", *wall)],
                   [("r1", 5, -10, 1.5), ("r2", 5, 10, 1.5), ("t1", 5, 200, 1.5), ("t2", -5, 200, 1.5)],
                   ["tracer.max_depth=1", "tracer.diffraction=false", "tracer.diffuse=false",
                    "tracer.vehicle_diffraction=false"],
                   {"max_depth": 1, "refraction": True, "diffraction": False})
    corner = box([-40, -40, 0], [0, 0, 20])
    wedge_nodes = [("tx", -10, 10, 1.5)] + [(f"rx{ang}", *wedge_rx(ang), 1.5) for ang in WEDGE_ANGLES]
    out["wedge"] = ([("corner", "metal", *corner)], wedge_nodes,
                    ["tracer.max_depth=1", "tracer.diffuse=false", "tracer.diffraction_reflection=false",
                     "tracer.vehicle_diffraction=false", "tracer.refraction=false"],
                    {"max_depth": 1, "refraction": False, "diffraction": True})
    # The same corner turned so that its edge is horizontal (along x, at
    # height 30 m): the vertical E field is perpendicular to the edge, UTD's
    # hard case. (x, y) of the vertical case -> (y, z - 30).
    corner_h = box([0, -40, -10], [20, 0, 30])
    out["wedge_h"] = ([("corner", "metal", *corner_h)],
                      [(i, 1.5, y, x + 30) for i, x, y, _ in wedge_nodes],
                      out["wedge"][2], out["wedge"][3])
    # A rough concrete wall: S = 0.4, directive lobe alpha_R = 4, no cross-
    # polarisation; the first-order diffuse power of tiles, rays and Sionna.
    rough = quad([0, -50, 0], [0, 100, 0], [0, 0, 20])
    out["rough"] = ([("wall", "concrete", *rough)], [("d1", 5, -10, 1.5), ("d2", 5, 10, 1.5)],
                    ["tracer.max_depth=1", "tracer.diffraction=false", "tracer.refraction=false",
                     "tracer.vehicle_diffraction=false", "tracer.diffuse=true", "tracer.path_threshold_db=0",
                     "materials.concrete.xpd=0"],
                    {"max_depth": 1, "refraction": False, "diffraction": False, "diffuse": True})
    return out

# ----------------------------------------------------------------- closed-form paths


def closed_forms(name, peer):
    f = peer["radio"]["frequency_hz"]
    lam = C0 / f
    k = 2 * math.pi / lam
    mats = peer["materials"]
    rows = []
    if name == "ground":
        e = eta(mats["medium_dry_ground"], f)
        for d in (10, 50, 200):
            h = 1.5
            d_los, d_ref = d, math.hypot(d, 2 * h)
            cos_t = 2 * h / d_ref
            _, r_tm = interface(e, cos_t)
            a_los = lam / (4 * math.pi * d_los) * np.exp(-1j * k * d_los)
            a_ref = r_tm * lam / (4 * math.pi * d_ref) * np.exp(-1j * k * d_ref)
            pair = (f"a{d}", f"b{d}")
            rows += [(pair, "los", a_los), (pair, "specular", a_ref), (pair, "sum", a_los + a_ref)]
    elif name == "wall":
        m = mats["concrete"]
        e, d_slab = eta(m, f), m["thickness_m"]
        length = 2 * math.hypot(5, 10)
        cos_t = 5 / math.hypot(5, 10)
        (r_te, _), _ = slab(e, cos_t, d_slab, lam)
        rows.append((("r1", "r2"), "specular", r_te * lam / (4 * math.pi * length) * np.exp(-1j * k * length)))
        rows.append((("r1", "r2"), "los", lam / (4 * math.pi * 20) * np.exp(-1j * k * 20)))
        _, (t_te, _) = slab(e, 1.0, d_slab, lam)
        rows.append((("t1", "t2"), "refraction", t_te * lam / (4 * math.pi * 10) * np.exp(-1j * k * 10)))
    elif name == "rough":
        rows.append((("d1", "d2"), "diffuse", math.sqrt(er_wall_power(mats["concrete"], f))))
    elif name in ("wedge", "wedge_h"):
        tx, edge = np.array([-10, 10, 1.5]), np.array([0, 0, 1.5])

        def phi_of(p):  # from face 0 (along -x, the face y = 0) through the exterior
            return (math.pi - math.atan2(p[1], p[0])) % (2 * math.pi)
        for ang in WEDGE_ANGLES:
            rx = np.array([*wedge_rx(ang), 1.5])
            s_i, s_d = np.linalg.norm(tx - edge), np.linalg.norm(rx - edge)
            length = s_i * s_d / (s_i + s_d)
            dcoef = utd_pec_soft(1.5, phi_of(rx), phi_of(tx), length, k, hard=name == "wedge_h")
            a = lam / (4 * math.pi) / s_i * dcoef * math.sqrt(s_i / (s_d * (s_i + s_d))) * np.exp(-1j * k * (s_i + s_d))
            rows.append(((f"rx{ang}", "tx"), "diffraction", a))
    return rows

# ----------------------------------------------------------------- the two tools


def classify(types):
    types = [t for t in types if t]
    if not types:
        return "los"
    for name in ("diffuse", "diffraction", "refraction", "specular"):
        if name in types:
            return name
    return "other"


def raysweep_paths(doc):
    out = {}
    for p in doc["pairs"]:
        key = tuple(sorted((p["tx"], p["rx"])))
        for path in p["paths"]:
            kind = classify([i["type"] for i in path["interactions"]])
            out.setdefault((key, kind), []).append(complex(path["a_re"], path["a_im"]))
    return out


SIONNA_TYPES = {1: "specular", 2: "diffuse", 4: "refraction", 8: "diffraction"}


def sionna_side(spec_file):
    """Runs in the venv: Sionna RT on the exported scene, every node both ends."""
    import mitsuba as mi
    mi.set_variant("llvm_ad_mono_polarized")
    import sionna.rt as rt
    spec = json.load(open(spec_file))
    peer = json.load(open(os.path.join(spec["peer"], "peer.json")))
    scene = rt.load_scene(os.path.join(spec["peer"], "scene.xml"), merge_shapes=False)
    scene.frequency = peer["radio"]["frequency_hz"]
    for arr in ("tx_array", "rx_array"):
        setattr(scene, arr, rt.PlanarArray(num_rows=1, num_cols=1, pattern="iso", polarization="V"))
    nodes = peer["nodes"]
    for n in nodes:
        scene.add(rt.Transmitter(name="tx-" + n["id"], position=mi.Point3f(*n["position"])))
        scene.add(rt.Receiver(name="rx-" + n["id"], position=mi.Point3f(*n["position"])))
    flags = spec["flags"]
    for name, mat in scene.radio_materials.items():
        m = peer["materials"].get(name.replace("raysweep_", ""), {})
        if m.get("lobe") == "directive":
            mat.scattering_pattern = rt.DirectivePattern(alpha_r=int(m["alpha_r"]))
    paths = rt.PathSolver()(scene, max_depth=flags["max_depth"], los=True, specular_reflection=True,
                            diffuse_reflection=flags.get("diffuse", False), refraction=flags["refraction"],
                            diffraction=flags["diffraction"], edge_diffraction=False,
                            samples_per_src=10 ** 6, max_num_paths_per_src=10 ** 5, synthetic_array=True, seed=1)
    # [rx, rx_ant, tx, tx_ant, path] (one antenna each) -> [rx, tx, path]
    are, aim = (np.array(x)[:, 0, :, 0, :] for x in paths.a)
    tau = np.array(paths.tau)
    tau = tau[:, 0, :, 0, :] if tau.ndim == 5 else tau
    valid = np.array(paths.valid)
    valid = valid[:, 0, :, 0, :] if valid.ndim == 5 else valid
    types = np.array(paths.interactions)
    types = types[:, :, 0, :, 0, :] if types.ndim == 6 else types
    out = []
    n = len(nodes)
    for r in range(n):
        for t in range(n):
            if r == t:
                continue
            for q in range(are.shape[-1]):
                if not valid[r, t, q]:
                    continue
                seq = [SIONNA_TYPES.get(int(types[d, r, t, q]), "") for d in range(types.shape[0])]
                out.append({"tx": nodes[t]["id"], "rx": nodes[r]["id"], "types": seq,
                            "a_re": float(are[r, t, q]), "a_im": float(aim[r, t, q]), "tau_s": float(tau[r, t, q])})
    json.dump(out, open(spec["out"], "w"))


def sionna_paths(peer_dir, flags, work, frequency):
    py = os.path.join(VENV, "bin", "python")
    spec = os.path.join(work, "sionna_spec.json")
    out = os.path.join(work, "sionna_paths.json")
    json.dump({"peer": peer_dir, "flags": flags, "out": out}, open(spec, "w"))
    env = dict(os.environ)
    # drjit needs libLLVM >= 17: the one compare put into the venv (README.md)
    found = sorted(glob.glob(os.path.join(VENV, "llvm", "libLLVM*.so*")))
    if found:
        env.setdefault("DRJIT_LIBLLVM_PATH", found[-1])
    subprocess.run([py, os.path.abspath(__file__), "--sionna-side", spec], check=True, env=env)
    got = {}
    for p in json.load(open(out)):
        key = tuple(sorted((p["tx"], p["rx"])))
        if p["tx"] > p["rx"]:  # each unordered pair once (reciprocal)
            continue
        # Sionna's a leaves the carrier's phase exp(-j 2 pi f tau) to the channel
        # functions (cir, cfr); raysweep's a includes it. Coherent sums need it.
        a = complex(p["a_re"], p["a_im"]) * np.exp(-2j * math.pi * frequency * p["tau_s"])
        got.setdefault((key, classify(p["types"])), []).append(a)
    return got


def pick(found, pair, kind):
    if kind == "diffuse":  # the power of all diffuse paths, as one amplitude
        vals = found.get((pair, kind), [])
        return math.sqrt(sum(abs(v) ** 2 for v in vals)) if vals else None
    if kind == "sum":
        vals = found.get((pair, "los"), []) + found.get((pair, "specular"), [])
        return sum(vals) if vals else None
    vals = found.get((pair, kind), [])
    return max(vals, key=abs) if vals else None


def main():
    if len(sys.argv) == 3 and sys.argv[1] == "--sionna-side":
        sionna_side(sys.argv[2])
        return
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--out", default="/tmp/raysweep-canonical")
    a = ap.parse_args()
    raysweep = os.path.join(a.build, "raysweep")
    have_peer = os.path.exists(os.path.join(VENV, "bin", "python"))
    if not have_peer:
        print(f"canonical: no peer environment at {VENV} (run compare once to install it); Sionna columns empty")
    os.makedirs(a.out, exist_ok=True)
    table = []
    for name, (shapes, nodes, sets, flags) in cases().items():
        work = os.path.join(a.out, name)
        shutil.rmtree(work, ignore_errors=True)
        write_scene(os.path.join(work, "mitsuba"), shapes)
        subprocess.run([raysweep, "-q", "scene", "--from-mitsuba", os.path.join(work, "mitsuba", "scene.xml"),
                        "--no-preview", "--out", os.path.join(work, "scene")], check=True)
        with open(os.path.join(work, "nodes.csv"), "w") as f:
            f.write("id,x,y,z\n" + "".join(f"{i},{x},{y},{z}\n" for i, x, y, z in nodes))
        args = [raysweep, "-q", "trace", "--scene", os.path.join(work, "scene"), "--nodes",
                os.path.join(work, "nodes.csv"), "--out", os.path.join(work, "trace.json"), "--mitsuba",
                os.path.join(work, "peer")]
        for s in sets:
            args += ["--set", s]
        subprocess.run(args, check=True)
        peer = json.load(open(os.path.join(work, "peer", "peer.json")))
        ours = raysweep_paths(json.load(open(os.path.join(work, "trace.json"))))
        theirs = (sionna_paths(os.path.join(work, "peer"), flags, work, peer["radio"]["frequency_hz"])
                  if have_peer else {})
        for pair, kind, a_cf in closed_forms(name, peer):
            key = tuple(sorted(pair))
            r, s = pick(ours, key, kind), pick(theirs, key, kind)
            row = {"case": name, "pair": "-".join(key), "path": kind, "closed_db": db(a_cf),
                   "raysweep_db": db(r) if r is not None else None, "sionna_db": db(s) if s is not None else None}
            table.append(row)
    with open(os.path.join(a.out, "canonical.json"), "w") as f:
        json.dump(table, f, indent=1)
    lines = ["| case | pair | path | closed form dB | raysweep dB | Sionna RT dB | raysweep - closed | Sionna - closed |",
             "|---|---|---|---|---|---|---|---|"]
    for r in table:
        def fmt(v):
            return "-" if v is None else f"{v:.2f}"

        def diff(v):
            return "-" if v is None else f"{v - r['closed_db']:+.2f}"
        lines.append(f"| {r['case']} | {r['pair']} | {r['path']} | {r['closed_db']:.2f} | {fmt(r['raysweep_db'])} | "
                     f"{fmt(r['sionna_db'])} | {diff(r['raysweep_db'])} | {diff(r['sionna_db'])} |")
    check = wedge_self_check()
    lines.append(f"\nThe UTD closed form's own checks: across the shadow boundary the diffracted field jumps by the "
                 f"incident field to {check['shadow boundary']:.0f} dB (the total field is continuous); on the "
                 f"shadowed face it is {check['shadowed face']:.0f} dB below free space (no tangential E on a "
                 "perfect conductor).")
    with open(os.path.join(a.out, "canonical.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()

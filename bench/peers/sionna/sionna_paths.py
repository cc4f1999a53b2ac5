"""Sionna RT's side of `compare`: run inside the peer's virtual environment.

    python sionna_paths.py --peer DIR --mechanisms a|b|c --out DIR [--samples N | --converge]

Reads DIR/scene.xml and DIR/peer.json (written by `raysweep trace --mitsuba
DIR`), sets Sionna up as peer.json says (materials, carrier, antennas, one
transmitter and one receiver per node), runs Sionna's PathSolver on the CPU
(Mitsuba variant llvm_ad_mono_polarized) and writes, for every unordered pair
i < j traced as tx = i, rx = j:

    OUT/sionna.json   settings, timings, nodes, pairs (LoS class), convergence history
    OUT/sionna.npz    the paths, flat: pair, a_re, a_im, tau_s, types [n, depth]
                      (InteractionType codes), objects [n, depth] (index into
                      sionna.json's objects, -1 none)

The paths are Sionna's, unfiltered; `compare` applies peer_rules (raysweep's
path classes, threshold and range) to them. --converge applies the same rules
to decide when to stop doubling samples_per_src (peer_rules.converged: the
same pairs have paths, the p95 over pairs of |change| in incoherent gain is
below 0.1 dB and the largest change below 1 dB).
"""
import argparse
import json
import os
import resource
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import peer_rules as rules  # noqa: E402

T_START = time.perf_counter()
import numpy as np  # noqa: E402
import mitsuba as mi  # noqa: E402

mi.set_variant("llvm_ad_mono_polarized")
import drjit as dr  # noqa: E402
import sionna.rt as rt  # noqa: E402

IMPORT_S = time.perf_counter() - T_START
PATTERN = {"isotropic": "iso", "dipole": "dipole", "halfwave": "hw_dipole"}
# Sionna preallocates max_num_paths_per_src x sources x depth records, and drops
# candidates beyond the per-source cap silently: start small, and redo a solve
# with 4x the cap whenever the candidates stored reach it (solve()).
FIRST_PATHS_PER_SRC = 200_000
# Sionna also drops specular chains whose hash collides with another's in a
# table of max(max_num_paths_per_src, 1e6) counters per source
# (SBCandidateGenerator). On the ring road at 1e6 samples a source stores
# about 29,000 candidates and lost 3.7 % of its valid paths with the 1e6 table
# (184 of 191), none from 3.2e6 on (191 at 3.2e6 and 12.8e6): the cap is
# raised until it is at least this many times the candidates per source.
HASH_HEADROOM = 100


def mechanism_flags(mech, tracer):
    """Sionna's switches for a mechanism set: (a) LoS + reflection + slabs,
    (b) + edge diffraction, (c) + diffuse; each as far as raysweep's own
    switches allow (a switch off there is off here)."""
    return {"los": bool(tracer.get("los", True)),
            "specular_reflection": bool(tracer.get("specular", True)),
            "refraction": bool(tracer.get("refraction", True)),
            "diffraction": mech in "bc" and bool(tracer.get("diffraction", True)),
            # Free borders (a screen's edge): raysweep's closed meshes have none
            # but the ground's, which it leaves out; Sionna's edge_diffraction
            # would diffract there.
            "edge_diffraction": False,
            # raysweep's UTD field is evaluated in the lit region too.
            "diffraction_lit_region": True,
            "diffuse_reflection": mech == "c" and bool(tracer.get("diffuse", True))}


def solver_depth(tracer):
    """Sionna's max_depth counts every interaction, a slab crossing included;
    raysweep's counts reflections, with slabs capped apart. max_depth +
    max_transmissions covers every raysweep path; peer_rules.in_model removes
    the longer mixtures Sionna then also finds."""
    slabs = int(tracer.get("max_transmissions", 2)) if tracer.get("refraction", True) else 0
    return int(tracer.get("max_depth", 3)) + slabs


def scattering_pattern(m):
    """raysweep's lobe as Sionna's pattern (Sionna wants integer exponents)."""
    lobe = m.get("lobe", "lambertian")
    if lobe == "directive":
        return rt.DirectivePattern(alpha_r=max(1, int(round(m["alpha_r"]))))
    if lobe == "backscatter":
        return rt.BackscatteringPattern(alpha_r=max(1, int(round(m["alpha_r"]))),
                                        alpha_i=max(1, int(round(m["alpha_i"]))), lambda_=float(m["lambda_r"]))
    return rt.LambertianPattern()


def configure_materials(scene, peer, diffuse):
    """Every radio material set explicitly from peer.json (not from the XML's
    floats alone): slab thickness as exported (raysweep's half spaces get 1 m of
    lossy ground, which reflects as the half space does); S = 0 unless diffuse
    scattering is compared, because Sionna scales every reflection by
    sqrt(1 - S^2) whether or not diffuse paths are traced, raysweep only when
    its diffuse mechanism is on."""
    applied = {}
    for name, rm in scene.radio_materials.items():
        key = name[len("raysweep_"):] if name.startswith("raysweep_") else name
        if key not in peer["materials"]:
            sys.exit(f"sionna_paths: material {name} is not in peer.json")
        m = peer["materials"][key]
        rm.relative_permittivity = float(m["relative_permittivity"])
        rm.conductivity = float(m["conductivity"])
        rm.thickness = float(m.get("exported_thickness_m") or m.get("thickness_m") or 1.0)
        rm.scattering_coefficient = float(m["scattering_coefficient"]) if diffuse else 0.0
        rm.xpd_coefficient = float(m["xpd_coefficient"])
        rm.scattering_pattern = scattering_pattern(m)
        applied[key] = {"relative_permittivity": rm.relative_permittivity[0], "conductivity": rm.conductivity[0],
                        "thickness_m": rm.thickness[0], "scattering_coefficient": rm.scattering_coefficient[0],
                        "xpd_coefficient": rm.xpd_coefficient[0], "pattern": type(rm.scattering_pattern).__name__,
                        "alpha_r": getattr(rm.scattering_pattern, "alpha_r", None)}
    return applied


def load(peer_dir, peer, diffuse):
    """The scene with carrier, antennas and one tx and one rx per node."""
    scene = rt.load_scene(os.path.join(peer_dir, "scene.xml"), merge_shapes=False)
    radio = peer["radio"]
    scene.frequency = float(radio["frequency_hz"])
    scene.bandwidth = float(radio["bandwidth_hz"])
    pattern = PATTERN[radio.get("antenna", "isotropic")]
    pol = radio.get("polarization", "V")
    scene.tx_array = rt.PlanarArray(num_rows=1, num_cols=1, pattern=pattern, polarization=pol)
    scene.rx_array = rt.PlanarArray(num_rows=1, num_cols=1, pattern=pattern, polarization=pol)
    materials = configure_materials(scene, peer, diffuse)
    for k, n in enumerate(peer["nodes"]):
        scene.add(rt.Receiver(name=f"rx{k:05d}", position=mi.Point3f(*map(float, n["position"]))))
    return scene, materials


def objects_of(scene):
    """Object id -> (name, material, is a vehicle's)."""
    out = {}
    for name, obj in scene.objects.items():
        mat = obj.radio_material.name
        mat = mat[len("raysweep_"):] if mat.startswith("raysweep_") else mat
        out[int(obj.object_id)] = (name, mat, name.startswith("veh"))
    return out


def squeeze(x, lead):
    """Drop the antenna axes of Sionna's [.., rx, rx_ant, tx, tx_ant, paths]."""
    x = np.asarray(x)
    if x.ndim == lead + 5:
        return x.reshape(x.shape[:lead] + (x.shape[lead], x.shape[lead + 2], x.shape[lead + 4]))
    return x


def set_transmitters(scene, peer, batch):
    for name in list(scene.transmitters):
        scene.remove(name)
    for k in batch:
        scene.add(rt.Transmitter(name=f"tx{k:05d}", position=mi.Point3f(*map(float, peer["nodes"][k]["position"]))))


class CountingGenerator:
    """Wraps Sionna's candidate generator to read how many candidates it
    stored: below max_num_paths_per_src in total, no source can have hit the
    per-source cap (where Sionna drops candidates silently)."""

    def __init__(self, inner):
        self.inner, self.stored = inner, 0

    def __call__(self, *args, **kw):
        buf = self.inner(*args, **kw)
        dr.eval(buf.paths_counter)
        self.stored = int(buf.paths_counter.numpy()[0])
        return buf


# Records Sionna preallocates per solver call (max_num_paths_per_src x
# sources), about 200 bytes each at depth 5: batches of sources keep them
# below this many (5 GB).
MAX_RECORDS = 25_000_000


def solve(scene, peer, flags, depth, samples, seed, batch_rays, deterministic, cap=FIRST_PATHS_PER_SRC):
    """Sionna's paths of every pair i < j (tx = i, rx = j), the transmitters in
    batches (at most batch_rays rays and MAX_RECORDS preallocated records per
    call); a call whose candidates reach max_num_paths_per_src is redone with 4x
    the cap (below it in total, no source can have hit it: Sionna drops
    candidates beyond it silently), and with 4x the cap whenever that is below
    HASH_HEADROOM x the candidates per source (hash collisions). Diffuse paths
    are folded per batch."""
    n = len(peer["nodes"])
    out = {"pair": [], "a_re": [], "a_im": [], "tau": [], "types": [], "objects": []}
    k, raw = 0, 0
    t0 = time.perf_counter()
    while k < n - 1:
        batch = list(range(k, min(n - 1, k + max(1, min(batch_rays // samples, MAX_RECORDS // cap)))))
        set_transmitters(scene, peer, batch)
        p, stored = solve_once(scene, flags, depth, samples, seed, deterministic, cap)
        if stored >= cap:
            print(f"sionna_paths: {stored} candidates reached max_num_paths_per_src = {cap}: again with {4 * cap}",
                  file=sys.stderr, flush=True)
            cap *= 4
            continue
        if cap < HASH_HEADROOM * stored / len(batch):
            print(f"sionna_paths: {stored} candidates of {len(batch)} sources in a hash table of {cap} per source: "
                  f"again with {4 * cap}", file=sys.stderr, flush=True)
            cap *= 4
            continue
        part = collect(p, batch, n, depth)
        del p
        raw += len(part["pair"])
        if flags["diffuse_reflection"]:
            part = fold_diffuse(part, float(peer["radio"]["bandwidth_hz"]))
        for key, v in part.items():
            out[key].append(v)
        k += len(batch)
    solve_s = time.perf_counter() - t0
    return {key: np.concatenate(v) for key, v in out.items()}, solve_s, cap, raw


def solve_once(scene, flags, depth, samples, seed, deterministic, cap):
    solver = rt.PathSolver(deterministic=deterministic)
    counter = CountingGenerator(solver._candidate_generator)
    solver._candidate_generator = counter
    p = solver(scene, max_depth=depth, samples_per_src=samples, max_num_paths_per_src=cap,
               synthetic_array=True, seed=seed, **flags)
    return p, counter.stored


def collect(p, batch, n, depth):
    """The valid paths of the batch's pairs (tx = i in batch, rx = j > i), flat."""
    a_re, a_im = (squeeze(t.numpy(), 0) for t in p.a)
    tau = squeeze(p.tau.numpy(), 0)
    valid = squeeze(p.valid.numpy(), 0).astype(bool)
    types = squeeze(p.interactions.numpy(), 1)
    objs = squeeze(p.objects.numpy(), 1)
    out = {"pair": [np.zeros(0, np.int32)], "a_re": [np.zeros(0)], "a_im": [np.zeros(0)], "tau": [np.zeros(0)],
           "types": [np.zeros((0, depth), np.uint8)], "objects": [np.zeros((0, depth), np.uint32)]}
    for ti, i in enumerate(batch):
        for j in range(i + 1, n):
            v = valid[j, ti]
            if not v.any():
                continue
            out["pair"].append(np.full(int(v.sum()), pair_index(i, j, n), dtype=np.int32))
            out["a_re"].append(a_re[j, ti][v].astype(np.float64))
            out["a_im"].append(a_im[j, ti][v].astype(np.float64))
            out["tau"].append(tau[j, ti][v].astype(np.float64))
            out["types"].append(pad(types[:, j, ti][:, v].T.astype(np.uint8), depth))
            out["objects"].append(pad(objs[:, j, ti][:, v].T.astype(np.uint32), depth))
    return {k: np.concatenate(v) for k, v in out.items()}


def pad(x, depth):
    """Sionna's interaction arrays are as deep as the longest path found."""
    return np.pad(x, ((0, 0), (0, depth - x.shape[1]))) if x.shape[1] < depth else x


def fold_diffuse(part, bandwidth):
    """Sionna returns one diffuse path per ray sample that sees the receiver;
    raysweep sums its diffuse samples per scattering object and delay bin of
    1 / bandwidth into one record. Sionna's are summed the same way (and per
    interaction sequence, so that peer_rules can still classify them): the
    power, the power-weighted delay, the strongest member's objects. Without
    it the path threshold would drop single samples whose sum matters."""
    d = (part["types"] == rules.DIFFUSE).any(axis=1)
    if not d.any():
        return part
    keep = {k: v[~d] for k, v in part.items()}
    q = {k: v[d] for k, v in part.items()}
    first = np.argmax(q["types"] == rules.DIFFUSE, axis=1)
    obj = q["objects"][np.arange(len(first)), first].astype(np.int64)
    key = np.column_stack([q["pair"].astype(np.int64), obj, np.floor(q["tau"] * bandwidth).astype(np.int64),
                           q["types"].astype(np.int64)])
    _, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.ravel()
    p = q["a_re"] ** 2 + q["a_im"] ** 2
    power = np.bincount(inv, weights=p)
    tau = np.bincount(inv, weights=p * q["tau"]) / np.maximum(power, 1e-300)
    order = np.lexsort((p, inv))
    rep = order[np.r_[inv[order][1:] != inv[order][:-1], True]]
    rec = {"pair": q["pair"][rep], "a_re": np.sqrt(power), "a_im": np.zeros(len(rep)), "tau": tau,
           "types": q["types"][rep], "objects": q["objects"][rep]}
    return {k: np.concatenate([keep[k], rec[k]]) for k in keep}


def pair_index(i, j, n):
    """Index of the unordered pair i < j in the order (0,1), (0,2), .., (1,2), .."""
    return i * n - i * (i + 1) // 2 + (j - i - 1)


def object_table(flat, objects):
    """Sionna's object ids -> indices into a list of names, and vehicle flags."""
    ids = sorted(objects)
    index = {oid: k for k, oid in enumerate(ids)}
    raw = flat["objects"]
    idx = np.full(raw.shape, -1, dtype=np.int32)
    veh = np.zeros(raw.shape, dtype=bool)
    for oid, k in index.items():
        hit = raw == oid
        idx[hit] = k
        veh[hit] = objects[oid][2]
    idx[flat["types"] == 0] = -1
    return idx, veh, [{"name": objects[o][0], "material": objects[o][1], "vehicle": objects[o][2]} for o in ids]


def pair_gains(flat, veh, peer, n):
    """Incoherent gain per pair (dB) after peer_rules: what --converge watches."""
    tracer = peer["tracer"]
    p = flat["a_re"] ** 2 + flat["a_im"] ** 2
    keep = rules.in_model(flat["types"], veh, tracer)
    keep &= ~rules.duplicates(flat["pair"], flat["tau"], flat["types"], flat["objects"])
    pair, p = flat["pair"][keep], p[keep]
    keep = rules.keep_above_threshold(pair, p, float(tracer.get("path_threshold_db", 60)))
    g = rules.gain_db(rules.pair_power(pair[keep], p[keep], n * (n - 1) // 2))
    pos = np.array([nd["position"] for nd in peer["nodes"]], dtype=float)
    ii, jj = np.triu_indices(n, 1)
    far = np.linalg.norm(pos[ii] - pos[jj], axis=1) > rules.max_range_m(peer["radio"], tracer)
    g[far] = -np.inf
    return g


def los_classes(scene, peer, objects):
    """Geometric LoS class of each pair on Sionna's scene, as raysweep defines
    it: nothing crossed = LOS, only vehicles = NLOSV, anything static = NLOS.
    Every crossing of the segment is walked (up to 64)."""
    pos = np.array([nd["position"] for nd in peer["nodes"]], dtype=float)
    n = len(pos)
    ii, jj = np.triu_indices(n, 1)
    static = np.zeros(len(ii), dtype=bool)
    vehicle = np.zeros(len(ii), dtype=bool)
    org, tgt = pos[ii].copy(), pos[jj]
    alive = np.ones(len(ii), dtype=bool)
    veh_ids = {oid for oid, o in objects.items() if o[2]}
    for _ in range(64):
        if not alive.any():
            break
        d = tgt - org
        length = np.linalg.norm(d, axis=1)
        ray = mi.Ray3f(mi.Point3f(*org.T.astype(np.float32)), mi.Vector3f(*(d / length[:, None]).T.astype(np.float32)))
        ray.maxt = mi.Float(np.maximum(length - 1e-3, 0).astype(np.float32))
        si = scene.mi_scene.ray_intersect(ray, active=mi.Bool(alive))
        hit = si.is_valid().numpy() & alive
        ids = dr.reinterpret_array(mi.UInt32, si.shape).numpy()
        is_veh = np.array([int(x) in veh_ids for x in ids])
        vehicle |= hit & is_veh
        static |= hit & ~is_veh
        p = np.stack([si.p.x.numpy(), si.p.y.numpy(), si.p.z.numpy()], axis=1).astype(float)
        org = np.where(hit[:, None], p + (d / length[:, None]) * 1e-3, org)
        alive = hit
    return np.where(static, "NLOS", np.where(vehicle, "NLOSV", "LOS"))


def solve_union(scene, peer, flags, depth, samples, a):
    """a.runs solves with seeds a.seed, a.seed + 1, ...: the union of their
    valid paths. Each path Sionna returns is exact (image method and
    backtracking), but its candidates are sampled: on the ring road a second
    solve added 597 of 10,782 paths. A path of a later run that an earlier
    run already has (pair, interactions, objects, delay to 1 ps) is left out."""
    flat, solve_s, cap, raw = solve(scene, peer, flags, depth, samples, a.seed, a.batch_rays, a.deterministic)
    for r in range(1, a.runs):
        more, s, cap, n_raw = solve(scene, peer, flags, depth, samples, a.seed + r, a.batch_rays, a.deterministic, cap)
        seen = set(zip(*path_keys(flat)))
        new = np.array([k not in seen for k in zip(*path_keys(more))], dtype=bool)
        print(f"sionna_paths: run {r + 1} of {a.runs}: {int(new.sum())} of {len(new)} paths new", file=sys.stderr,
              flush=True)
        flat = {key: np.concatenate([flat[key], more[key][new]]) for key in flat}
        solve_s, raw = solve_s + s, raw + n_raw
    return flat, solve_s, cap, raw


def path_keys(flat):
    rows = lambda x: [r.tobytes() for r in np.ascontiguousarray(x)]
    return (flat["pair"].tolist(), rows(flat["types"]), rows(flat["objects"]),
            np.round(flat["tau"] * 1e12).astype(np.int64).tolist())


def run(scene, peer, a, flags, depth, history):
    """One solve at a.samples; with --converge, double until peer_rules.converged."""
    n = len(peer["nodes"])
    samples = a.samples
    prev = None
    while True:
        flat, solve_s, cap, raw = solve_union(scene, peer, flags, depth, samples, a)
        _, veh, _ = object_table(flat, objects_of(scene))
        g = pair_gains(flat, veh, peer, n)
        step = {"samples_per_src": samples, "solve_s": solve_s, "paths": int(len(flat["pair"])), "paths_raw": raw,
                "max_num_paths_per_src": cap, "pairs_with_paths": int(np.isfinite(g).sum()),
                "max_rss_gib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20}
        if prev is not None:
            ok, p95, worst, same = rules.converged(prev, g, a.tol_db, a.max_change_db)
            step.update(p95_change_db=p95, max_change_db=worst, same_pairs=same, converged=ok)
        history.append(step)
        print(f"sionna_paths: {json.dumps(step)}", file=sys.stderr, flush=True)
        if not a.converge or step.get("converged"):
            return flat, solve_s, samples, bool(step.get("converged", False))
        if samples * 2 > a.max_samples or solve_s * 2.2 > a.max_solve_s:
            return flat, solve_s, samples, False
        prev, samples = g, samples * 2


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--peer", required=True)
    ap.add_argument("--mechanisms", choices=["a", "b", "c"], required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--samples", type=int, default=1_000_000, help="samples_per_src (the start with --converge)")
    ap.add_argument("--converge", action="store_true")
    ap.add_argument("--tol-db", type=float, default=0.1, help="--converge: p95 |change| over pairs (dB)")
    ap.add_argument("--max-change-db", type=float, default=1.0, help="--converge: largest |change| (dB)")
    ap.add_argument("--max-samples", type=int, default=64_000_000)
    ap.add_argument("--max-solve-s", type=float, default=1800.0, help="--converge: no step expected to take longer")
    ap.add_argument("--batch-rays", type=int, default=20_000_000, help="rays per solver call (memory)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--runs", type=int, default=1, help="solves with seeds seed.. seed+runs-1, their paths' union")
    ap.add_argument("--deterministic", action="store_true",
                    help="PathSolver(deterministic=True): reproducible, but 7x the memory (7.4 vs 1.0 GiB, demo 20 nodes, 1e5 samples)")
    a = ap.parse_args()
    with open(os.path.join(a.peer, "peer.json")) as f:
        peer = json.load(f)
    tracer = peer["tracer"]
    flags = mechanism_flags(a.mechanisms, tracer)
    depth = solver_depth(tracer)
    t0 = time.perf_counter()
    scene, materials = load(a.peer, peer, flags["diffuse_reflection"])
    load_s = time.perf_counter() - t0
    history = []
    flat, solve_s, samples, conv = run(scene, peer, a, flags, depth, history)
    objects = objects_of(scene)
    idx, veh, table = object_table(flat, objects)
    t1 = time.perf_counter()
    los = los_classes(scene, peer, objects)
    os.makedirs(a.out, exist_ok=True)
    np.savez_compressed(os.path.join(a.out, "sionna.npz"), pair=flat["pair"], a_re=flat["a_re"], a_im=flat["a_im"],
                        tau_s=flat["tau"], types=flat["types"], objects=idx, on_vehicle=veh)
    doc = {"sionna_rt": rt.__version__ if hasattr(rt, "__version__") else "", "mitsuba": mi.__version__,
           "drjit": dr.__version__, "variant": mi.variant(), "llvm": os.environ.get("DRJIT_LIBLLVM_PATH", ""),
           "settings": {"max_depth": depth, "samples_per_src": samples, "seed": a.seed, "runs": a.runs,
                        "deterministic": a.deterministic, "synthetic_array": True,
                        "max_num_paths_per_src": history[-1]["max_num_paths_per_src"], "batch_rays": a.batch_rays,
                        "frequency_hz": scene.frequency[0], "tx_array": PATTERN[peer["radio"].get("antenna", "isotropic")],
                        "polarization": peer["radio"].get("polarization", "V"), **flags},
           "materials": materials, "converge": {"enabled": a.converge, "converged": conv, "tol_db": a.tol_db,
                                                "max_change_db": a.max_change_db,
                                                "history": history},
           "timing": {"import_s": IMPORT_S, "load_s": load_s, "solve_s": solve_s, "los_class_s": time.perf_counter() - t1},
           "nodes": [nd["id"] for nd in peer["nodes"]], "los_class": los.tolist(), "objects": table}
    with open(os.path.join(a.out, "sionna.json"), "w") as f:
        json.dump(doc, f, indent=1)


if __name__ == "__main__":
    main()

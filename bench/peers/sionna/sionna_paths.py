"""Sionna RT's side of `compare`: run inside the peer's virtual environment.

    python sionna_paths.py --peer DIR --mechanisms a|b|c --out DIR [--samples N] [--runs K | --converge]

Reads DIR/scene.xml and DIR/peer.json (written by `raysweep trace --mitsuba
DIR`), sets Sionna up as peer.json says (materials, carrier, antennas) and runs
Sionna's PathSolver on the CPU (Mitsuba variant llvm_ad_mono_polarized), for
every unordered pair i < j traced as tx = i, rx = j:

- one transmitter per call, with only its receivers j > i: Sionna tests every
  candidate against every receiver and preallocates its buffers per source, so
  memory stays that of one source and no pair is solved twice;
- in runs: the first on Sionna's own Fibonacci lattice (which depends only on
  N: every source, seed and run would otherwise shoot the same rays), each
  later one on that lattice turned by a uniform random rotation, with its own
  seed and its own hash table size (Sionna's hash ignores the seed, so the
  same table loses the same chains every run);
- the runs combined: the union of their non-diffuse paths (each path is exact;
  only its discovery is sampled), the mean of their diffuse records (each
  run's diffuse weights are unbiased);
- --converge: runs until one more run changes no pair at or above the
  sensitivity floor by more than --tol-db (non-diffuse gain; no pair appears
  there) and, with diffuse on, every such pair's standard error from the
  runs' spread is within --diffuse-se-db; else --max-runs / --max-hours.

    OUT/sionna.json   settings, timings, peak memory, nodes, pairs (LoS class), the runs' history
    OUT/sionna.npz    the paths, flat: pair, a_re, a_im, tau_s, types [n, depth]
                      (InteractionType codes), objects [n, depth] (index into
                      sionna.json's objects, -1 none)

The paths are Sionna's, unfiltered; `compare` applies peer_rules (raysweep's
path classes, threshold and range) to them; the convergence figures apply
the same rules.
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
import sionna.rt.path_solvers.sb_candidate_generator as sbg  # noqa: E402
import sionna.rt.path_solvers.sb_deterministic as sbd  # noqa: E402

IMPORT_S = time.perf_counter() - T_START
PATTERN = {"isotropic": "iso", "dipole": "dipole", "halfwave": "hw_dipole"}
# Sionna preallocates max_num_paths_per_src x sources x depth records, and drops
# candidates beyond the per-source cap silently: start small, and redo a call
# with 4x the cap whenever the candidates stored reach it (Tables.fits).
FIRST_PATHS_PER_SRC = 200_000
# Sionna also drops specular chains whose hash collides with another's in a
# table of max(max_num_paths_per_src, MIN_SPEC_COUNT_SIZE) counters per source
# (SBCandidateGenerator; the class attribute is read at call time, so the
# table is sized here apart from the buffer). On the ring road at 1e6 samples
# a source stores about 29,000 candidates and lost 3.7 % of its valid paths
# with a table of 1e6 (184 of 191), none from 3.2e6 on: the table is kept at
# least this many times the specular candidates of a source (LoS and diffuse
# records never touch it).
HASH_HEADROOM = 100
MIN_TABLE = 1_000_003


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
    """The scene with carrier and antennas (set_link adds the nodes)."""
    scene = rt.load_scene(os.path.join(peer_dir, "scene.xml"), merge_shapes=False)
    radio = peer["radio"]
    scene.frequency = float(radio["frequency_hz"])
    scene.bandwidth = float(radio["bandwidth_hz"])
    pattern = PATTERN[radio.get("antenna", "isotropic")]
    pol = radio.get("polarization", "V")
    scene.tx_array = rt.PlanarArray(num_rows=1, num_cols=1, pattern=pattern, polarization=pol)
    scene.rx_array = rt.PlanarArray(num_rows=1, num_cols=1, pattern=pattern, polarization=pol)
    materials = configure_materials(scene, peer, diffuse)
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


def receivers_of(i, n, both_directions):
    """Source i's receivers: j > i (each unordered pair once, and no work for
    the pairs (j, i) that another call solves: Sionna tests every candidate
    against every receiver), or every j != i when the reverse direction is
    needed too (the diffuse-then-reflection class, collect())."""
    return [j for j in range(n) if j != i] if both_directions else list(range(i + 1, n))


def set_link(scene, peer, i, receivers):
    """Node i as the only transmitter, these nodes as the receivers."""
    for name in list(scene.transmitters) + list(scene.receivers):
        scene.remove(name)
    nodes = peer["nodes"]
    scene.add(rt.Transmitter(name=f"tx{i:05d}", position=mi.Point3f(*map(float, nodes[i]["position"]))))
    for j in receivers:
        scene.add(rt.Receiver(name=f"rx{j:05d}", position=mi.Point3f(*map(float, nodes[j]["position"]))))


class CountingGenerator:
    """Wraps Sionna's candidate generator to read what it stored: all
    candidates (below max_num_paths_per_src no source can have hit the cap,
    where Sionna drops candidates silently) and the specular chains among them
    (the only ones that go through the hash table; LoS and diffuse records
    are stored as valid paths without it)."""

    def __init__(self, inner):
        self.inner, self.stored, self.specular = inner, 0, 0

    def __call__(self, *args, **kw):
        buf = self.inner(*args, **kw)
        dr.eval(buf.paths_counter, buf.valid)
        self.stored = int(buf.paths_counter.numpy()[0])
        self.specular = self.stored - int(np.count_nonzero(buf.valid.numpy()[:self.stored]))
        return buf


def random_rotation(rng):
    """A uniformly random rotation (Shoemake's quaternion): Sionna's Fibonacci
    lattice turned by it keeps its equal-area cells, so 4 pi / N still holds."""
    u1, u2, u3 = rng.random(3)
    a, b = np.sqrt(1 - u1), np.sqrt(u1)
    w, x, y, z = a * np.sin(2 * np.pi * u2), a * np.cos(2 * np.pi * u2), b * np.sin(2 * np.pi * u3), b * np.cos(2 * np.pi * u3)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


class Lattice:
    """The turn applied to the rays Sionna spawns (None: its own lattice).
    The matrix enters the kernels as opaque values: turning the lattice does
    not recompile them."""
    rotation = None


def _turned(spawn):
    def spawn_turned(lattice, samples_per_src, src_positions):
        ray = spawn(lattice, samples_per_src, src_positions)
        if Lattice.rotation is None:
            return ray
        r = [dr.opaque(mi.Float, float(v)) for v in np.ravel(Lattice.rotation)]
        d = ray.d
        ray.d = mi.Vector3f(r[0] * d.x + r[1] * d.y + r[2] * d.z, r[3] * d.x + r[4] * d.y + r[5] * d.z,
                            r[6] * d.x + r[7] * d.y + r[8] * d.z)
        return ray
    return spawn_turned


# Both candidate generators take the function by name at import: turn it there.
for _mod in (sbg, sbd):
    _mod.spawn_ray_from_sources = _turned(_mod.spawn_ray_from_sources)


class Tables:
    """max_num_paths_per_src and the specular hash table's size, kept across
    calls: they only grow (each new value is a new kernel to compile)."""

    def __init__(self):
        self.cap, self.table = FIRST_PATHS_PER_SRC, MIN_TABLE

    def fits(self, stored, specular):
        """False (and larger values) when a call has to be redone."""
        if stored >= self.cap:
            print(f"sionna_paths: {stored} candidates reached max_num_paths_per_src = {self.cap}: again with "
                  f"{4 * self.cap}", file=sys.stderr, flush=True)
            self.cap *= 4
            return False
        if self.table < HASH_HEADROOM * specular:
            want = odd(HASH_HEADROOM * specular * 2)
            print(f"sionna_paths: {specular} specular candidates in a hash table of {self.table}: again with {want}",
                  file=sys.stderr, flush=True)
            self.table = want
            return False
        return True


def odd(x):
    return int(x) | 1


def solve_run(scene, peer, flags, depth, samples, seed, tables, deterministic, bandwidth, both_directions):
    """One run: every source alone against its receivers j > i, on the
    current lattice, with this run's seed and hash table size. Returns the
    run's paths (diffuse folded per pair, object, delay bin and sequence), its
    solve time, raw path count and the largest candidate count of a source."""
    n = len(peer["nodes"])
    parts, raw, most = [], 0, 0
    t0 = time.perf_counter()
    for i in range(n if both_directions else n - 1):
        receivers = receivers_of(i, n, both_directions)
        set_link(scene, peer, i, receivers)
        while True:
            sbg.SBCandidateGenerator.MIN_SPEC_COUNT_SIZE = tables.table
            p, stored, specular = solve_once(scene, flags, depth, samples, seed, deterministic, tables.cap)
            if tables.fits(stored, specular):
                break
            del p
            dr.flush_malloc_cache()
        most = max(most, stored)
        part = collect(p, i, receivers, n, depth)
        del p
        dr.flush_malloc_cache()
        raw += len(part["pair"])
        if flags["diffuse_reflection"]:
            part = fold_diffuse(part, bandwidth)
        parts.append(part)
    flat = {key: np.concatenate([q[key] for q in parts]) for key in parts[0]}
    return flat, time.perf_counter() - t0, raw, most


def solve_once(scene, flags, depth, samples, seed, deterministic, cap):
    solver = rt.PathSolver(deterministic=deterministic)
    counter = CountingGenerator(solver._candidate_generator)
    solver._candidate_generator = counter
    p = solver(scene, max_depth=depth, samples_per_src=samples, max_num_paths_per_src=cap,
               synthetic_array=True, seed=seed, **flags)
    return p, counter.stored, counter.specular


def reverse_chains(types, objects):
    """Each path's interactions in reverse order (the padding stays at the end)."""
    t, o = np.zeros_like(types), objects.copy()
    for k, m in enumerate(np.count_nonzero(types, axis=1)):
        t[k, :m] = types[k, :m][::-1]
        o[k, :m] = objects[k, :m][::-1]
    return t, o


def collect(p, i, receivers, n, depth):
    """The valid paths of source i, flat, as pairs i < j run from i to j.
    Receivers j > i: every path, except, when the receivers j < i are solved
    too, the diffuse-then-reflection class (peer_rules.diffuse_then_reflection:
    biased in Sionna's sampling). Receivers j < i: only that class of the pair
    (j, i), taken from this solve's paths that end in their one scattering
    after reflections or slabs, reversed (reciprocity; Sionna samples those
    without bias: the scattering is the chain's last interaction, evaluated
    per sample)."""
    a_re, a_im = (squeeze(t.numpy(), 0) for t in p.a)
    tau = squeeze(p.tau.numpy(), 0)
    valid = squeeze(p.valid.numpy(), 0).astype(bool)
    types = squeeze(p.interactions.numpy(), 1)
    objs = squeeze(p.objects.numpy(), 1)
    out = {"pair": [np.zeros(0, np.int32)], "a_re": [np.zeros(0)], "a_im": [np.zeros(0)], "tau": [np.zeros(0)],
           "types": [np.zeros((0, depth), np.uint8)], "objects": [np.zeros((0, depth), np.uint32)]}
    both = any(j < i for j in receivers)
    for r, j in enumerate(receivers):
        v = valid[r, 0]
        t = pad(types[:, r, 0].T.astype(np.uint8), depth)
        o = pad(objs[:, r, 0].T.astype(np.uint32), depth)
        if j < i:
            # This solve's chains that end in their one scattering, after
            # reflections or slabs: reversed, the pair (j, i)'s class.
            last = np.count_nonzero(t, axis=1) - 1
            v = v & (last >= 1) & (t[np.arange(len(t)), np.maximum(last, 0)] == rules.DIFFUSE)
            v &= (t == rules.DIFFUSE).sum(axis=1) == 1
            t, o = reverse_chains(t, o)
        elif both:
            v = v & ~rules.diffuse_then_reflection(t)
        if not v.any():
            continue
        out["pair"].append(np.full(int(v.sum()), pair_index(min(i, j), max(i, j), n), dtype=np.int32))
        out["a_re"].append(a_re[r, 0][v].astype(np.float64))
        out["a_im"].append(a_im[r, 0][v].astype(np.float64))
        out["tau"].append(tau[r, 0][v].astype(np.float64))
        out["types"].append(t[v])
        out["objects"].append(o[v])
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


def path_keys(flat):
    rows = lambda x: [r.tobytes() for r in np.ascontiguousarray(x)]  # noqa: E731
    return (flat["pair"].tolist(), rows(flat["types"]), rows(flat["objects"]),
            np.round(flat["tau"] * 1e12).astype(np.int64).tolist())


def split_diffuse(flat):
    d = (flat["types"] == rules.DIFFUSE).any(axis=1)
    return {k: v[~d] for k, v in flat.items()}, {k: v[d] for k, v in flat.items()}


class Accumulated:
    """The runs so far: the union of their non-diffuse paths (each is exact,
    only its discovery is sampled: a path of a later run that an earlier one
    has, by pair, interactions, objects and delay to 1 ps, is left out) and
    their diffuse records, whose mean over runs is the estimate (Sionna's
    diffuse weights are 4 pi / N over the event probabilities: unbiased per
    run). Each run's diffuse records stay apart for the standard error."""

    def __init__(self, n, bandwidth):
        self.n, self.bandwidth = n, bandwidth
        self.specular, self.seen, self.diffuse_runs = None, set(), []

    def add(self, flat):
        spec, dif = split_diffuse(flat)
        keys = list(zip(*path_keys(spec)))
        new = np.array([k not in self.seen for k in keys], dtype=bool)
        self.seen.update(keys)
        if self.specular is None:
            self.specular = {k: v[new] for k, v in spec.items()}
        else:
            self.specular = {k: np.concatenate([self.specular[k], spec[k][new]]) for k in spec}
        self.diffuse_runs.append(dif)
        return int(new.sum()), len(new)

    def diffuse_mean(self):
        """The runs' diffuse records folded together, power divided by the runs."""
        cat = {k: np.concatenate([d[k] for d in self.diffuse_runs]) for k in self.specular}
        if len(cat["pair"]) == 0:
            return cat
        mean = fold_diffuse(cat, self.bandwidth)
        mean["a_re"] = mean["a_re"] / np.sqrt(len(self.diffuse_runs))
        return mean

    def flat(self):
        dif = self.diffuse_mean()
        return {k: np.concatenate([self.specular[k], dif[k]]) for k in self.specular}


def pair_power_rules(flat, veh, peer, n):
    """Power per pair of the paths peer_rules keeps, before the threshold."""
    p = flat["a_re"] ** 2 + flat["a_im"] ** 2
    keep = rules.in_model(flat["types"], veh, peer["tracer"])
    return rules.pair_power(flat["pair"][keep], p[keep], n * (n - 1) // 2)


def convergence(acc, prev_spec_db, scene, peer):
    """The run's convergence figures over the pairs at or above the floor:
    the largest change of the non-diffuse gain that this run made, and the
    standard error of each pair's power from the diffuse runs' spread."""
    n = acc.n
    objects = objects_of(scene)
    flat = acc.flat()
    _, veh, _ = object_table(flat, objects)
    g = pair_gains(flat, veh, peer, n)
    _, sveh, _ = object_table(acc.specular, objects)
    g_spec = pair_gains(acc.specular, sveh, peer, n)
    floor = float(peer["radio"]["sensitivity_dbm"] - peer["radio"]["tx_power_dbm"])
    use = np.isfinite(g) & (g >= floor)
    out = {"pairs_with_paths": int(np.isfinite(g).sum()), "pairs_above_floor": int(use.sum())}
    if prev_spec_db is not None:
        worst, p95, appeared = rules.run_change(prev_spec_db, g_spec, g, floor)
        out.update(max_change_db=worst, p95_change_db=p95, pairs_appeared=appeared)
    runs = len(acc.diffuse_runs)
    if runs >= 2 and any(len(d["pair"]) for d in acc.diffuse_runs):
        per_run = []
        for d in acc.diffuse_runs:
            _, dveh, _ = object_table(d, objects)
            per_run.append(pair_power_rules(d, dveh, peer, n))
        se_db = rules.standard_error_db(np.array(per_run), g)[use]
        out.update(diffuse_se_max_db=float(se_db.max()) if len(se_db) else 0.0,
                   diffuse_se_p95_db=float(np.percentile(se_db, 95)) if len(se_db) else 0.0)
    return out, g_spec


def converged(step, a, diffuse):
    if "max_change_db" not in step:
        return False
    ok = step["max_change_db"] <= a.tol_db and step["pairs_appeared"] == 0
    if diffuse:
        ok &= step.get("diffuse_se_max_db", np.inf) <= a.diffuse_se_db
    return bool(ok)


def run(scene, peer, a, flags, depth, history):
    """Runs on turned lattices (run 0 on Sionna's own), each with its own seed
    and hash table size, until one more run changes no pair at or above the
    floor by more than a.tol_db (and, with diffuse, every such pair's standard
    error is within a.diffuse_se_db), or a.max_runs / a.max_hours is reached."""
    n = len(peer["nodes"])
    bandwidth = float(peer["radio"]["bandwidth_hz"])
    acc, tables, rng = Accumulated(n, bandwidth), Tables(), np.random.default_rng(a.seed)
    both = flags["diffuse_reflection"] and not a.one_direction
    prev, total_s, conv = None, 0.0, False
    for r in range(a.max_runs if a.converge else a.runs):
        Lattice.rotation = None if r == 0 else random_rotation(rng)
        if r > 0:  # another table size: other chains collide
            tables.table = odd(tables.table * 1.07)
        flat, solve_s, raw, most = solve_run(scene, peer, flags, depth, a.samples, a.seed + r, tables,
                                             a.deterministic, bandwidth, both)
        new, total = acc.add(flat)
        total_s += solve_s
        step = {"run": r + 1, "samples_per_src": a.samples, "solve_s": solve_s, "paths_raw": raw,
                "non_diffuse_paths": total, "new_non_diffuse_paths": new,
                "diffuse_records": int(len(flat["pair"]) - total),
                "max_candidates_per_src": most, "max_num_paths_per_src": tables.cap, "hash_table": tables.table,
                "max_rss_gib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20}
        fig, g_spec = convergence(acc, prev, scene, peer)
        step.update(fig)
        conv = converged(step, a, flags["diffuse_reflection"])
        step["converged"] = conv
        history.append(step)
        print(f"sionna_paths: {json.dumps(step)}", file=sys.stderr, flush=True)
        prev = g_spec
        if a.converge and (conv or total_s / (r + 1) * (r + 2) > a.max_hours * 3600):
            break
    return acc.flat(), total_s, a.samples, conv


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--peer", required=True)
    ap.add_argument("--mechanisms", choices=["a", "b", "c"], required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--samples", type=int, default=1_000_000, help="samples_per_src of each run")
    ap.add_argument("--runs", type=int, default=2, help="runs without --converge")
    ap.add_argument("--converge", action="store_true", help="runs until converged (or --max-runs, --max-hours)")
    ap.add_argument("--tol-db", type=float, default=0.1,
                    help="--converge: the largest change one more run may make to a pair at or above the floor (dB)")
    ap.add_argument("--diffuse-se-db", type=float, default=0.2,
                    help="--converge, diffuse on: the largest standard error of such a pair's power (dB)")
    ap.add_argument("--max-runs", type=int, default=24)
    ap.add_argument("--max-hours", type=float, default=2.0, help="--converge: stop before a run would end later")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--one-direction", action="store_true",
                    help="diffuse on: leave the diffuse-then-reflection class to Sionna's own (biased) sampling "
                         "instead of the reverse direction's solve")
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
           "settings": {"max_depth": depth, "samples_per_src": samples, "seed": a.seed, "runs": len(history),
                        "lattices": "run 1 Sionna's Fibonacci lattice, then turned by uniform random rotations",
                        "sources_per_call": 1,
                        "diffuse_then_reflection": ("one-direction (Sionna's own, biased)" if a.one_direction else
                                                    "the reverse direction's reflection-then-diffuse paths"),
                        "deterministic": a.deterministic, "synthetic_array": True,
                        "max_num_paths_per_src": history[-1]["max_num_paths_per_src"],
                        "hash_table": history[-1]["hash_table"],
                        "frequency_hz": scene.frequency[0], "tx_array": PATTERN[peer["radio"].get("antenna", "isotropic")],
                        "polarization": peer["radio"].get("polarization", "V"), **flags},
           "materials": materials, "converge": {"enabled": a.converge, "converged": conv, "tol_db": a.tol_db,
                                                "diffuse_se_db": a.diffuse_se_db, "history": history},
           "max_rss_gib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20,
           "timing": {"import_s": IMPORT_S, "load_s": load_s, "solve_s": solve_s, "los_class_s": time.perf_counter() - t1},
           "nodes": [nd["id"] for nd in peer["nodes"]], "los_class": los.tolist(), "objects": table}
    with open(os.path.join(a.out, "sionna.json"), "w") as f:
        json.dump(doc, f, indent=1)


if __name__ == "__main__":
    main()

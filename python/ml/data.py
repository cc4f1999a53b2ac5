"""One city's run directory as arrays: links (scalar inputs, labels), context, 802.11p receptions.

Everything a model sees is an input of the simulation (node states, vehicle types, the scene
around the link); blocker_count and the gains' other columns come from tracing and would leak the
labels, so they are not read as features.
"""
import json
import os

import h5py
import numpy as np

import raysweep_dataset as rd

from . import baselines, context

RAT_80211P = 1  # schemas/README.md, SINR file, code table `rat`
MAX_STALE_S = 1.0  # a reception uses a featured snapshot at most this much older
# Vehicle library classes (meshkit/vehicle_classes.cpp) by body, so codes agree across cities.
BODY = {"": 0, "passenger": 1, "taxi": 1, "evehicle": 1, "private": 1, "delivery": 2, "emergency": 2,
        "truck": 3, "trailer": 4, "bus": 5, "coach": 5, "motorcycle": 6, "moped": 6, "bicycle": 6}
OTHER_BODY = 7
SCALAR_FEATURES = ("distance_m", "distance_2d_m", "dz_m", "tx_speed", "rx_speed", "tx_kind", "rx_kind",
                   "tx_body", "rx_body", "tx_length_m", "tx_width_m", "tx_height_m", "rx_length_m",
                   "rx_width_m", "rx_height_m", "heading_cos", "tx_align", "rx_align")


def free_space_gain_db(d, fc_hz):
    """-(free-space path loss) at distance d (>= 1 m): the learned models predict the gain relative to
    it, so they extrapolate to distances outside their training cities like a path loss does."""
    return -20.0 * np.log10(4 * np.pi * np.maximum(d, 1.0) * fc_hz / 299792458.0)


class InputError(Exception):
    """A missing or malformed input; the message names the file."""


class City:
    """Arrays of one city. `rows`: the links used (a deterministic sample of at most max_links of the
    featured links, plus the links of the 802.11p receptions), every per-link array aligned to it."""

    def __init__(self, name, run_dir):
        self.name, self.run_dir = name, run_dir
        self.scenario = baselines.scenario_of(name)
        self.notes = []
        self.ctx = None
        self.rec = None


def _require(path, what):
    if not os.path.isfile(path):
        raise InputError(f"{path}: missing ({what})")


def _open_dataset(path):
    _require(path, "channel dataset of `raysweep run`")
    try:
        ds = rd.open_dataset(path)
    except (OSError, ValueError) as e:
        raise InputError(f"{path}: {e}") from None
    need = ["links/" + c for c in ("frame", "tx", "rx", "flags", "los_class", "los_class_fresnel",
                                   "gain_incoherent_db")] + ["node_states/position", "nodes/id", "frames/time_s"]
    missing = [n for n in need if n not in ds.file]
    if missing or "carrier_hz" not in ds.file.attrs or "config" not in ds.file.attrs:
        ds.close()
        raise InputError(f"{path}: malformed channel dataset, missing {missing or 'root attributes'}")
    return ds


def _sample(candidates, max_links, seed):
    """At most max_links of the candidate rows, uniformly and reproducibly, ascending."""
    if max_links is None or len(candidates) <= max_links:
        return candidates
    rng = np.random.default_rng(seed)
    return np.sort(rng.choice(candidates, size=max_links, replace=False))


def _node_geometry(ds, rows):
    """Per-link tx/rx states (positions, velocities, headings) and node attributes for `rows`."""
    t_rows, r_rows = ds.link_node_states()
    pos, vel = ds._column("node_states/position"), ds._column("node_states/velocity")
    heading = ds._column("node_states/heading_deg").astype(np.float64)
    nodes = ds.nodes
    body = np.array([BODY.get(v, OTHER_BODY) for v in nodes["vclass"]], np.float32)
    out = {}
    for end, states in (("tx", t_rows[rows]), ("rx", r_rows[rows])):
        node = ds._column("links/" + end)[rows].astype(np.int64)
        out[end] = {"pos": pos[states], "vel": vel[states], "heading": np.radians(heading[states]),
                    "kind": nodes["kind"][node].astype(np.float32), "body": body[node],
                    "dims": nodes["dimensions"][node].astype(np.float64)}
    return out


def _centre(end):
    """Vehicle centre (2-D): the front-bumper position moved back half a length along the heading
    (clockwise from north: the direction is (sin h, cos h)); RSUs have length 0."""
    back = end["dims"][:, 0] / 2
    return end["pos"][:, :2] - back[:, None] * np.stack([np.sin(end["heading"]), np.cos(end["heading"])], 1)


def scalar_features(g):
    """(n, len(SCALAR_FEATURES)) from _node_geometry's output; no absolute position (cities differ)."""
    t, r = g["tx"], g["rx"]
    delta = r["pos"] - t["pos"]
    bearing = np.arctan2(delta[:, 0], delta[:, 1])  # clockwise from north, like the headings
    vehicle = lambda e: e["kind"] == 0  # RSUs have no heading: alignment 0
    align = lambda e: np.where(vehicle(e), np.abs(np.cos(e["heading"] - bearing)), 0.0)
    cols = {"distance_m": np.linalg.norm(delta, axis=1), "distance_2d_m": np.linalg.norm(delta[:, :2], axis=1),
            "dz_m": np.abs(delta[:, 2]), "tx_speed": np.linalg.norm(t["vel"], axis=1),
            "rx_speed": np.linalg.norm(r["vel"], axis=1), "tx_kind": t["kind"], "rx_kind": r["kind"],
            "tx_body": t["body"], "rx_body": r["body"],
            "heading_cos": np.where(vehicle(t) & vehicle(r), np.cos(t["heading"] - r["heading"]), 0.0),
            "tx_align": align(t), "rx_align": align(r)}
    for end, e in (("tx", t), ("rx", r)):
        for i, q in enumerate(("length", "width", "height")):
            cols[f"{end}_{q}_m"] = e["dims"][:, i]
    return np.stack([np.asarray(cols[n], np.float32) for n in SCALAR_FEATURES], axis=1)


def _read_receptions(path, ds, frames):
    """802.11p receptions mapped to their link rows: the pair's link in the last of `frames` (sorted
    frame indices: those with context features) at or before the reception's start. With every
    frame that is the frame the SINR generator used; with a frame stride, a snapshot up to a stride
    older (MAX_STALE_S at most)."""
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        raise InputError(f"{path}: cannot open as HDF5 ({e})") from None
    with f:
        if rd._text(f.attrs.get("format", "")) != "raysweep-sinr" or "receptions/rat" not in f:
            raise InputError(f"{path}: not a raysweep SINR outcome file")
        try:
            r = {k: f["receptions/" + k][...] for k in ("transmission", "tx", "rx", "rat", "time_s", "noise_dbm",
                                                         "intra_dbm", "inter_dbm", "decoded")}
            power = f["transmissions/power_dbm"][...]
            thr, sens = float(f.attrs["sinr_threshold_db"]), float(f.attrs["sensitivity_dbm"])
            cfg = json.loads(rd._text(f.attrs["config"])) if "config" in f.attrs else {}
        except KeyError as e:
            raise InputError(f"{path}: malformed SINR outcome file ({e})") from None
    keep = r["rat"] == RAT_80211P
    r = {k: v[keep] for k, v in r.items()}
    ft = ds.times[frames]
    pick = np.maximum(np.searchsorted(ft, r["time_s"], side="right") - 1, 0)
    frame = frames[pick] if len(frames) else np.zeros(len(pick), np.int64)
    fresh = np.abs(r["time_s"] - ds.times[frame]) <= MAX_STALE_S if len(frames) else np.zeros(len(pick), bool)
    n = max(ds.node_count, 1)
    key = lambda fr, a, b: (fr.astype(np.int64) * n + a.astype(np.int64)) * n + b.astype(np.int64)
    link_key = key(ds._column("links/frame"), ds._column("links/tx"), ds._column("links/rx"))  # sorted
    want = key(frame, np.minimum(r["tx"], r["rx"]), np.maximum(r["tx"], r["rx"]))
    pos = np.minimum(np.searchsorted(link_key, want), len(link_key) - 1)
    found = link_key[pos] == want if len(link_key) else np.zeros(len(want), bool)
    noise_mw = sum(10 ** (r[k].astype(np.float64) / 10) for k in ("noise_dbm", "intra_dbm", "inter_dbm"))
    rec = {"link": np.where(found & fresh, pos, -1), "frame": frame, "decoded": r["decoded"].astype(np.float64),
           "tx_power_dbm": power[r["transmission"]].astype(np.float64),
           "required_dbm": np.maximum(sens, 10 * np.log10(noise_mw) + thr)}
    heights = (float(cfg.get("antenna_height_m", baselines.ANTENNA_HEIGHT_M)),
               float(cfg.get("blocker_height_m", baselines.BLOCKER_HEIGHT_M)))
    return rec, heights


def _load_context(path, ds, city):
    """Opens features.h5 when present: the featured links (or every link) and the reader."""
    if not os.path.exists(path):
        city.notes.append(f"{path} absent: no context features (gbdt on scalar inputs, no cnn)")
        return None, np.arange(ds.link_count, dtype=np.int64)
    try:
        ff = context.FeatureFile(path, ds.link_count)
    except ValueError as e:
        raise InputError(str(e)) from None
    return ff, ff.links


def _attach_receptions(city, ds, universe, sinr_path):
    if not os.path.exists(sinr_path):
        city.notes.append(f"{sinr_path} absent: task (c) skipped for {city.name}")
        return np.empty(0, np.int64)
    frames = np.unique(ds._column("links/frame")[universe]).astype(np.int64)
    rec, city.heights = _read_receptions(sinr_path, ds, frames)
    featured = np.isin(rec["link"], universe)
    dropped = int(np.sum(~featured))
    if len(frames) < len(ds.times):
        city.notes.append(f"features.h5 covers {len(frames)} of {len(ds.times)} frames: receptions use the pair's "
                          f"link in the last covered frame at or before them")
    if dropped:
        city.notes.append(f"{dropped} of {len(featured)} 802.11p receptions have no link (pair not stored in that "
                          f"frame): left out of task (c)")
    city.rec = {k: v[featured] for k, v in rec.items()}
    return city.rec["link"]


def load_city(name, run_dir, max_links=200000, seed=1):
    """Reads RUN_DIR/dataset.h5, RUN_DIR/features.h5 (optional) and RUN_DIR/sinr/ray.h5 (optional)."""
    city = City(name, run_dir)
    city.heights = (baselines.ANTENNA_HEIGHT_M, baselines.BLOCKER_HEIGHT_M)
    ds = _open_dataset(os.path.join(run_dir, "dataset.h5"))
    ff = None
    try:
        radio = json.loads(rd._text(ds.file.attrs["config"])).get("radio", {})
        city.floor_db = float(radio["sensitivity_dbm"]) - float(radio["tx_power_dbm"])
        city.fc_hz = float(ds.file.attrs["carrier_hz"])
        city.times = ds.times.astype(np.float64)
        city.link_total = ds.link_count
        ff, universe = _load_context(os.path.join(run_dir, "features.h5"), ds, city)
        sample = _sample(universe, max_links, seed)
        if len(sample) < len(universe):
            city.notes.append(f"subsampled {len(sample)} of {len(universe)} links (--max-links)")
        rec_links = _attach_receptions(city, ds, universe, os.path.join(run_dir, "sinr", "ray.h5"))
        rows = np.union1d(sample, rec_links).astype(np.int64)
        _fill_links(city, ds, rows, np.isin(rows, sample))
        if city.rec is not None:
            city.rec["row"] = np.searchsorted(rows, city.rec["link"])
        if ff is not None:
            _fill_context(city, ff, np.searchsorted(ff.links, rows))
    except KeyError as e:
        raise InputError(f"{ds.path}: malformed ({e})") from None
    except OSError as e:  # h5py: a damaged dataset or chunk in one of the run dir's files
        raise InputError(f"{run_dir}: unreadable input file ({e})") from None
    finally:
        ds.close()
        if ff is not None:
            ff.close()
    return city


def _fill_links(city, ds, rows, in_sample):
    flags = ds._column("links/flags")[rows]
    gain = ds._column("links/gain_incoherent_db")[rows].astype(np.float64)
    g = _node_geometry(ds, rows)
    city.rows, city.in_sample = rows, in_sample
    city.frame = ds._column("links/frame")[rows].astype(np.int64)
    city.cls = ds._column("links/los_class_fresnel")[rows].astype(np.int64)
    city.los_geo = ds._column("links/los_class")[rows].astype(np.int64)
    city.in_range = (flags & rd.FLAG_OUT_OF_RANGE) == 0
    city.gain = np.where(city.in_range, np.maximum(gain, city.floor_db), np.nan)  # -inf (no path) -> floor
    city.X = scalar_features(g)
    city.d3 = city.X[:, SCALAR_FEATURES.index("distance_m")].astype(np.float64)
    city.d2 = city.X[:, SCALAR_FEATURES.index("distance_2d_m")].astype(np.float64)
    city.prior = free_space_gain_db(city.d3, city.fc_hz)
    city.d_centre = np.linalg.norm(_centre(g["rx"]) - _centre(g["tx"]), axis=1)


def _fill_context(city, ff, positions):
    ctx = ff.read(positions)
    city.ctx = ctx
    city.grid = {"A": ff.A, "C": ff.C, "W": ff.W, "K": ff.K, "height_scale": ff.height_scale}
    city.materials = ff.materials
    city.agg = context.aggregates(ctx, ff.height_scale, ff.W)


def unify_materials(cities):
    """Material codes of every city remapped to one vocabulary ("none" first), so a raster means the
    same in every city; returns the vocabulary."""
    names = sorted({m for c in cities if c.ctx is not None for m in c.materials[1:]})
    vocab = ["none"] + names
    for c in cities:
        if c.ctx is None:
            continue
        lut = np.array([0] + [vocab.index(m) for m in c.materials[1:]], np.uint8)
        c.ctx["material"] = lut[np.minimum(c.ctx["material"], len(lut) - 1)]
        c.materials = vocab
    return vocab

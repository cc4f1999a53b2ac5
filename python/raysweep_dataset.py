"""Reader of raysweep channel datasets (HDF5, layout in schemas/README.md).

    from raysweep_dataset import open_dataset, LinkDataset

    with open_dataset("channels.h5") as ds:
        print(ds.frame_count, ds.link_count, ds.times[:5])
        f0 = ds.frame(0)                  # node states and links of frame 0
        hist = ds.pair("veh12", "rsu0")   # one pair over time (ids or node indices, any order)
        p = ds.paths(hist["link"][0])     # paths of one link (store levels paths and full)
        table = ds.links_table()          # every /links column, for bulk work

    data = LinkDataset("channels.h5")     # (features, label) per link; a torch Dataset when torch is installed

    with open_dataset("channels.h5") as ds:  # splits that do not leak: time windows 1 s apart
        splits = time_splits(ds.times, (0.7, 0.15, 0.15), gap_s=1.0)
    train = LinkDataset("channels.h5", frames=splits["train"])
    for train_cities, test_city in city_rotations(["demo", "ring", "badhersfeld"]): ...

Files store one of four cumulative levels (`ds.store`): links (every /links column, the per-link
summaries included), cfr (+ frequency responses), paths (+ paths without interaction points), full (+
interaction points). Link columns and CFR are the same at every level.

Needs numpy and h5py only (run with /usr/bin/python3 on Debian); torch is optional.
"""
import json

import h5py
import numpy as np

FORMAT = "raysweep-channels"
SUPPORTED_MAJOR = 1

LOS_CLASSES = {0: "LOS", 1: "NLOSV", 2: "NLOS"}
INTERACTION_TYPES = {1: "specular", 2: "refraction", 3: "diffuse", 4: "diffraction"}
NODE_KINDS = {0: "vehicle", 1: "rsu"}
FLAG_CACHED = 1
FLAG_OUT_OF_RANGE = 2
FLAG_ENCLOSED = 4  # an end's antenna inside a building (since schema 1.5.0)

LINK_COLUMNS = ("frame", "tx", "rx", "los_class", "flags", "blocker_count", "gain_coherent_db",
                "gain_incoherent_db", "first_delay_s", "rms_delay_spread_s", "path_count", "path_offset",
                "paths_below_threshold",  # since schema 1.1.0
                "los_class_fresnel", "fresnel_clearance",  # since schema 1.2.0
                "vehicle_loss_db",  # since schema 1.3.0
                "paths_beyond_top_k", "diffuse_gain_db", "k_factor_db", "rms_doppler_spread_hz",
                "aod_spread_rad", "aoa_spread_rad", "strongest_excess_delay_s", "strongest_aod",
                "strongest_aoa")  # since schema 1.4.0 (the last four of them (L, 2): zenith/theta, azimuth/phi)
STORE_LEVELS = ("links", "cfr", "paths", "full")


def _text(value):
    """h5py gives str for variable-length string attributes and bytes for string datasets."""
    if isinstance(value, bytes):
        return value.decode("utf-8")
    return str(value)


def _major(version):
    try:
        return int(str(version).split(".")[0])
    except ValueError:
        return None


class ChannelDataset:
    """An open dataset file. Use open_dataset(); close() or use as a context manager."""

    def __init__(self, path):
        self.path = str(path)
        self._file = h5py.File(self.path, "r")
        try:
            self._check()
        except Exception:
            self._file.close()
            raise
        self._columns = {}

    def _check(self):
        attrs = self._file.attrs
        fmt = _text(attrs["format"]) if "format" in attrs else None
        if fmt != FORMAT:
            raise ValueError(f"{self.path}: not a raysweep channel dataset (format attribute {fmt!r}, "
                             f"expected {FORMAT!r})")
        version = _text(attrs["schema_version"]) if "schema_version" in attrs else None
        major = _major(version) if version is not None else None
        if major != SUPPORTED_MAJOR:
            raise ValueError(f"{self.path}: schema version {version!r} is not supported: this reader reads "
                             f"major version {SUPPORTED_MAJOR} (update raysweep_dataset.py)")

    # -- lifetime --------------------------------------------------------------------------
    def close(self):
        self._file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    @property
    def file(self):
        """The underlying h5py.File."""
        return self._file

    # -- header ----------------------------------------------------------------------------
    @property
    def attrs(self):
        """Root attributes as a dict; config, inputs and provenance parsed from their JSON text."""
        out = {}
        for key, value in self._file.attrs.items():
            if isinstance(value, (str, bytes)):
                value = _text(value)
                if key in ("config", "inputs", "provenance"):
                    value = json.loads(value)
            elif isinstance(value, np.generic):
                value = value.item()
            out[key] = value
        return out

    @property
    def schema_version(self):
        return _text(self._file.attrs["schema_version"])

    @property
    def complete(self):
        return int(self._file.attrs.get("complete", 0)) == 1

    @property
    def frame_count(self):
        return int(self._file["frames/time_s"].shape[0])

    @property
    def link_count(self):
        return int(self._file["links/tx"].shape[0])

    @property
    def store(self):
        """Store level: links, cfr, paths or full (files written before schema 1.4.0 are full)."""
        return _text(self._file.attrs.get("store", "full"))

    @property
    def paths_top_k(self):
        """0, or the number of strongest paths each link keeps (levels paths and full)."""
        return int(self._file.attrs.get("paths_top_k", 0))

    @property
    def path_count(self):
        """Sum of the links' path counts: the rows of /paths where stored, else the paths the gains sum."""
        if "path_count" in self._file.attrs:
            return int(self._file.attrs["path_count"])
        return int(self._file["paths/tau_s"].shape[0]) if "paths" in self._file else 0

    @property
    def has_paths(self):
        return "paths" in self._file

    @property
    def node_count(self):
        return int(self._file["nodes/id"].shape[0]) if "nodes/id" in self._file else 0

    @property
    def has_cfr(self):
        return "cfr" in self._file

    @property
    def times(self):
        """Frame times (F,), seconds."""
        return self._column("frames/time_s")

    @property
    def nodes(self):
        """Node table as a structured array: id, kind (0 vehicle, 1 rsu), vclass, vtype, dimensions (l, w, h)."""
        if "nodes" not in self._columns:
            g = self._file["nodes"]
            n = g["id"].shape[0]
            out = np.empty(n, dtype=[("id", object), ("kind", np.uint8), ("vclass", object), ("vtype", object),
                                     ("dimensions", np.float32, (3,))])
            out["id"] = [_text(v) for v in g["id"][...]]
            out["kind"] = g["kind"][...]
            out["vclass"] = [_text(v) for v in g["vclass"][...]]
            out["vtype"] = [_text(v) for v in g["vtype"][...]]
            out["dimensions"] = g["dimensions"][...].reshape(n, 3)
            self._columns["nodes"] = out
        return self._columns["nodes"]

    @property
    def objects(self):
        """Object names (O,) as a list of str."""
        return [_text(v) for v in self._file["objects/name"][...]]

    def node_index(self, node):
        """Node index of a node id (str) or index (int)."""
        if isinstance(node, (int, np.integer)):
            if not 0 <= int(node) < self.node_count:
                raise IndexError(f"node index {node} out of range (N = {self.node_count})")
            return int(node)
        ids = self.nodes["id"]
        hits = np.nonzero(ids == str(node))[0]
        if hits.size == 0:
            raise KeyError(f"{self.path}: no node with id {node!r}")
        return int(hits[0])

    # -- columns ---------------------------------------------------------------------------
    def _column(self, name):
        """A whole dataset, read once and cached."""
        if name not in self._columns:
            self._columns[name] = self._file[name][...]
        return self._columns[name]

    def links_table(self):
        """Every /links column as a dict of numpy arrays (L,) for bulk/ML use."""
        return {c: self._column("links/" + c) for c in self.link_columns}

    @property
    def link_columns(self):
        """The /links columns this file has (older files lack the columns added since: see LINK_COLUMNS)."""
        return tuple(c for c in LINK_COLUMNS if "links/" + c in self._file)

    # -- frames ----------------------------------------------------------------------------
    def frame(self, i):
        """Node states and links of frame i: dict with time_s, node, position (n, 3), velocity (n, 3),
        heading_deg, link_index (rows of /links) and every /links column."""
        if not -self.frame_count <= i < self.frame_count:
            raise IndexError(f"frame {i} out of range (F = {self.frame_count})")
        i = i % self.frame_count
        f = self._file
        s0 = int(f["frames/node_offset"][i])
        s1 = s0 + int(f["frames/node_count"][i])
        l0 = int(f["frames/link_offset"][i])
        l1 = l0 + int(f["frames/link_count"][i])
        out = {
            "time_s": float(f["frames/time_s"][i]),
            "node": f["node_states/node"][s0:s1],
            "position": f["node_states/position"][s0:s1],
            "velocity": f["node_states/velocity"][s0:s1],
            "heading_deg": f["node_states/heading_deg"][s0:s1],
            "link_index": np.arange(l0, l1, dtype=np.int64),
        }
        for c in self.link_columns:
            out[c] = f["links/" + c][l0:l1]
        return out

    def pair(self, a, b):
        """One node pair over time (ids or indices, either order): dict of per-frame arrays
        link (row of /links), frame, time_s, los_class, flags, blocker_count, gain_coherent_db,
        gain_incoherent_db, first_delay_s, rms_delay_spread_s, path_count; plus tx, rx."""
        ia, ib = self.node_index(a), self.node_index(b)
        if ia == ib:
            raise ValueError("a pair needs two different nodes")
        tx, rx = min(ia, ib), max(ia, ib)
        rows = np.nonzero((self._column("links/tx") == tx) & (self._column("links/rx") == rx))[0]
        frame = self._column("links/frame")[rows]
        out = {"tx": tx, "rx": rx, "link": rows, "frame": frame, "time_s": self.times[frame]}
        for c in ("los_class", "flags", "blocker_count", "gain_coherent_db", "gain_incoherent_db", "first_delay_s",
                  "rms_delay_spread_s", "path_count"):
            out[c] = self._column("links/" + c)[rows]
        return out

    def paths(self, link_index):
        """Paths of one link (row of /links), sorted by delay: dict with a (complex64), tau_s, aod (n, 2),
        aoa (n, 2) (theta, phi in rad), doppler_hz, interaction_count and interactions: a list with, per
        path, a structured array of (type, object, point). Points are NaN at store level paths; levels
        links and cfr hold no paths (ValueError naming the level to sweep with)."""
        f = self._file
        if not 0 <= link_index < self.link_count:
            raise IndexError(f"link {link_index} out of range (L = {self.link_count})")
        if not self.has_paths:
            raise ValueError(f"{self.path}: store level {self.store!r} holds no paths (its link columns, summaries "
                             f"and CFR do): sweep with [sweep] store = \"paths\" or \"full\"")
        p0 = int(f["links/path_offset"][link_index])
        p1 = p0 + int(f["links/path_count"][link_index])
        out = {
            "a": f["paths/a"][p0:p1].astype(np.complex64),
            "tau_s": f["paths/tau_s"][p0:p1],
            "aod": f["paths/aod"][p0:p1],
            "aoa": f["paths/aoa"][p0:p1],
            "doppler_hz": f["paths/doppler_hz"][p0:p1],
            "interaction_count": f["paths/interaction_count"][p0:p1],
        }
        offsets = f["paths/interaction_offset"][p0:p1]
        counts = out["interaction_count"].astype(np.int64)
        dtype = np.dtype([("type", np.uint8), ("object", np.uint32), ("point", np.float32, (3,))])
        interactions = []
        if p1 > p0:
            i0 = int(offsets[0])
            i1 = int(offsets[-1] + counts[-1])
            types = f["interactions/type"][i0:i1]
            objects = f["interactions/object"][i0:i1]
            # Level paths stores no points: NaN.
            points = (f["interactions/point"][i0:i1] if "interactions/point" in f
                      else np.full((i1 - i0, 3), np.nan, dtype=np.float32))
            for off, cnt in zip(offsets, counts):
                s = int(off) - i0
                rec = np.empty(int(cnt), dtype=dtype)
                rec["type"] = types[s:s + cnt]
                rec["object"] = objects[s:s + cnt]
                rec["point"] = points[s:s + cnt]
                interactions.append(rec)
        out["interactions"] = interactions
        return out

    def cfr(self, link_index):
        """Frequency response of one link (K,) complex64, or None when the file stores none."""
        if not self.has_cfr:
            return None
        return self._file["cfr/h"][link_index].astype(np.complex64)

    def cfr_frequencies_hz(self):
        """Absolute subcarrier frequencies (K,), or None: carrier + (k - K // 2) * spacing."""
        if not self.has_cfr:
            return None
        g = self._file["cfr"]
        k = int(g.attrs["subcarriers"])
        return float(g.attrs["carrier_hz"]) + (np.arange(k) - k // 2) * float(g.attrs["subcarrier_spacing_hz"])

    def links_of_frames(self, frames):
        """Rows of /links (int64, ascending) of the given frame indices."""
        frames = np.unique(np.asarray(frames, dtype=np.int64))
        if frames.size and (frames[0] < 0 or frames[-1] >= self.frame_count):
            raise IndexError(f"frames out of range (F = {self.frame_count})")
        off = self._column("frames/link_offset").astype(np.int64)[frames]
        cnt = self._column("frames/link_count").astype(np.int64)[frames]
        if not frames.size:
            return np.empty(0, dtype=np.int64)
        return np.concatenate([np.arange(o, o + c, dtype=np.int64) for o, c in zip(off, cnt)])

    # -- geometry --------------------------------------------------------------------------
    def link_node_states(self):
        """For every link, the rows of /node_states holding its tx and rx state in the link's frame:
        two int64 arrays (L,). Raises ValueError when a link names a node absent from its frame."""
        if "link_state_rows" not in self._columns:
            n = max(self.node_count, 1)
            offsets = self._column("frames/node_offset").astype(np.int64)
            counts = self._column("frames/node_count").astype(np.int64)
            state_frame = np.repeat(np.arange(len(offsets), dtype=np.int64), counts)
            key = state_frame * n + self._column("node_states/node").astype(np.int64)  # sorted: frames, then nodes
            frame = self._column("links/frame").astype(np.int64)
            rows = []
            for end in ("tx", "rx"):
                want = frame * n + self._column("links/" + end).astype(np.int64)
                r = np.searchsorted(key, want)
                r = np.minimum(r, max(len(key) - 1, 0))
                if len(want) and (len(key) == 0 or np.any(key[r] != want)):
                    raise ValueError(f"{self.path}: a link names a node absent from its frame's node states")
                rows.append(r)
            self._columns["link_state_rows"] = tuple(rows)
        return self._columns["link_state_rows"]

    def link_distances(self):
        """3-D tx-rx distance (L,) in metres of every link."""
        t, r = self.link_node_states()
        pos = self._column("node_states/position")
        return np.linalg.norm(pos[t] - pos[r], axis=1)


def open_dataset(path):
    """Opens a dataset; raises ValueError when the file is not a raysweep dataset or has an unsupported
    major schema version."""
    return ChannelDataset(path)


# --- Splits -----------------------------------------------------------------------------------

def time_splits(times, fractions=(0.7, 0.15, 0.15), gap_s=1.0, names=("train", "val", "test")):
    """Frames split into contiguous time windows, in time order, at least gap_s seconds apart.

    The links of one frame are correlated and frames 0.1 s apart are nearly the same channel, so a
    split over shuffled links or frames measures memory, not generalisation. Window i takes the
    share fractions[i] of the sweep's time left after the gaps; frames inside a gap belong to no
    split, so the last frame of a window and the first of the next are at least gap_s apart, and no
    frame is in two splits. `times`: the frame times (ChannelDataset.times). Returns
    {name: frame indices (int64, ascending)}; ValueError when the sweep is too short for the gaps.
    """
    t = np.asarray(times, dtype=np.float64)
    if len(fractions) != len(names) or not fractions or min(fractions) <= 0:
        raise ValueError("time_splits: one positive fraction per name")
    if gap_s < 0:
        raise ValueError("time_splits: gap_s must not be negative")
    if t.size == 0:
        return {n: np.empty(0, dtype=np.int64) for n in names}
    t0, t1 = float(t.min()), float(t.max())
    usable = (t1 - t0) - gap_s * (len(names) - 1)
    if usable <= 0:
        raise ValueError(f"time_splits: {t1 - t0:.3f} s of frames cannot hold {len(names)} windows "
                         f"{gap_s} s apart")
    share = np.asarray(fractions, dtype=np.float64) / float(np.sum(fractions))
    out, start = {}, t0
    for i, name in enumerate(names):
        last = i == len(names) - 1
        end = t1 if last else start + share[i] * usable
        inside = (t >= start) & ((t <= end) if last else (t < end))
        out[name] = np.nonzero(inside)[0].astype(np.int64)
        start = end + gap_s
    return out


def city_rotations(cities):
    """Leave-one-city-out: for each city, (the other cities, that city), for training on the others
    and testing on the one held out."""
    cities = list(cities)
    return [([c for c in cities if c != held], held) for held in cities]


# --- PyTorch-style link dataset -----------------------------------------------------------------

try:  # torch is optional
    import torch as _torch
    from torch.utils.data import Dataset as _DatasetBase
except ImportError:  # pragma: no cover - depends on the machine
    _torch = None
    _DatasetBase = object


class LinkDataset(_DatasetBase):
    """Links as (features, label) samples.

    Features (float32, in the order of `feature_names`; pick a subset with `features=`):
      tx_x, tx_y, tx_z, rx_x, rx_y, rx_z   node positions (m, scene frame)
      distance_m                           3-D tx-rx distance
      tx_speed, rx_speed                   |velocity| (m/s)
      tx_heading_deg, rx_heading_deg       heading (deg, clockwise from north)
      tx_kind, rx_kind                     0 vehicle, 1 rsu
      tx_vclass, rx_vclass                 vehicle class code: index into `vclass_names` (RSUs: the "" entry)
      tx_length_m, tx_width_m, tx_height_m, rx_length_m, rx_width_m, rx_height_m   vehicle dimensions
      blocker_count                        objects blocking the direct ray (derived from tracing: leaks the label)
    label: any /links column (default los_class, 0 LOS / 1 NLOSV / 2 NLOS), int64 for integer columns,
    float32 otherwise. include_out_of_range=False drops links flagged out of range. frames: only the
    links of these frame indices (a split of time_splits), else every link.

    With torch installed this is a torch.utils.data.Dataset returning tensors; otherwise numpy arrays.
    """

    ALL_FEATURES = ("tx_x", "tx_y", "tx_z", "rx_x", "rx_y", "rx_z", "distance_m", "tx_speed", "rx_speed",
                    "tx_heading_deg", "rx_heading_deg", "tx_kind", "rx_kind", "tx_vclass", "rx_vclass",
                    "tx_length_m", "tx_width_m", "tx_height_m", "rx_length_m", "rx_width_m", "rx_height_m",
                    "blocker_count")
    DEFAULT_FEATURES = ("tx_x", "tx_y", "tx_z", "rx_x", "rx_y", "rx_z", "distance_m", "tx_speed", "rx_speed",
                        "tx_kind", "rx_kind", "tx_vclass", "rx_vclass")

    def __init__(self, path, features=DEFAULT_FEATURES, label="los_class", include_out_of_range=True,
                 frames=None):
        unknown = [f for f in features if f not in self.ALL_FEATURES]
        if unknown:
            raise ValueError(f"unknown features {unknown}; available: {list(self.ALL_FEATURES)}")
        if label not in LINK_COLUMNS:
            raise ValueError(f"unknown label {label!r}; available: {list(LINK_COLUMNS)}")
        self.feature_names = tuple(features)
        self.label_name = label
        with open_dataset(path) as ds:
            nodes = ds.nodes
            self.vclass_names = sorted(set(nodes["vclass"].tolist()) | {""})
            vclass_code = np.array([self.vclass_names.index(v) for v in nodes["vclass"]], dtype=np.float32)
            t_rows, r_rows = ds.link_node_states()
            pos = ds._column("node_states/position")
            vel = ds._column("node_states/velocity")
            heading = ds._column("node_states/heading_deg")
            tx = ds._column("links/tx").astype(np.int64)
            rx = ds._column("links/rx").astype(np.int64)
            cols = {}
            for end, rows, node in (("tx", t_rows, tx), ("rx", r_rows, rx)):
                p = pos[rows]
                cols[end + "_x"], cols[end + "_y"], cols[end + "_z"] = p[:, 0], p[:, 1], p[:, 2]
                cols[end + "_speed"] = np.linalg.norm(vel[rows], axis=1)
                cols[end + "_heading_deg"] = heading[rows]
                cols[end + "_kind"] = nodes["kind"][node]
                cols[end + "_vclass"] = vclass_code[node]
                dims = nodes["dimensions"][node]
                cols[end + "_length_m"], cols[end + "_width_m"], cols[end + "_height_m"] = \
                    dims[:, 0], dims[:, 1], dims[:, 2]
            cols["distance_m"] = np.linalg.norm(pos[t_rows] - pos[r_rows], axis=1)
            cols["blocker_count"] = ds._column("links/blocker_count")
            labels = ds._column("links/" + label)
            keep = np.ones(len(tx), dtype=bool)
            if not include_out_of_range:
                keep = (ds._column("links/flags") & FLAG_OUT_OF_RANGE) == 0
            if frames is not None:
                chosen = np.zeros(len(tx), dtype=bool)
                chosen[ds.links_of_frames(frames)] = True
                keep &= chosen
        self.link_index = np.nonzero(keep)[0]
        n = len(self.link_index)
        self.features = np.empty((n, len(self.feature_names)), dtype=np.float32)
        for j, name in enumerate(self.feature_names):
            self.features[:, j] = np.asarray(cols[name])[keep]
        labels = labels[keep]
        self.labels = labels.astype(np.int64) if np.issubdtype(labels.dtype, np.integer) else labels.astype(np.float32)

    def __len__(self):
        return len(self.labels)

    def __getitem__(self, i):
        x, y = self.features[i], self.labels[i]
        if _torch is not None:
            return _torch.from_numpy(np.array(x)), _torch.as_tensor(y)
        return x, y

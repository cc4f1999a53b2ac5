"""Context features of features.h5 (format raysweep-features): reading, aggregates, rasters.

Per link the file holds a corridor raster in the link's own frame (A cells along tx->rx, C cells
across, half width W) with building heights and materials, and up to K other vehicles in the
corridor (along, across, height, length, width, class code). Layout: schemas/README.md (written by
`raysweep features`, generators/sweep/context_features.hpp); see python/ml/README.md.
"""
import json

import h5py
import numpy as np

FORMAT = "raysweep-features"
SUPPORTED_MAJOR = 1
VEHICLE_FIELDS = ("along_m", "across_m", "height_m", "length_m", "width_m", "class")
FILE_VEHICLE_FIELDS = ("along_m", "across_m", "height_m", "length_m", "width_m", "vclass")  # /vehicles/<field>
EMPTY_SLOT = 255  # /vehicles/vclass of an empty slot
AGGREGATES = ("bldg_center_frac", "bldg_center_max_m", "bldg_frac", "bldg_mean_m", "veh_count",
              "veh_max_height_m", "veh_min_abs_across_m", "veh_near_count", "veh_near_max_height_m")
NEAR_LINE_M = 1.5  # a vehicle centre this close to the tx-rx line is a likely blocker


def _text(v):
    return v.decode("utf-8") if isinstance(v, bytes) else str(v)


class FeatureFile:
    """An open features.h5, checked against the channel dataset it belongs to."""

    def __init__(self, path, dataset_link_count):
        self.path = str(path)
        try:
            self.file = h5py.File(self.path, "r")
        except OSError as e:
            raise ValueError(f"{self.path}: cannot open as HDF5 ({e})") from None
        try:
            self._check(dataset_link_count)
        except (KeyError, ValueError, TypeError) as e:
            self.file.close()
            raise ValueError(f"{self.path}: {e}") from None

    def _check(self, dataset_link_count):
        a = self.file.attrs
        if _text(a.get("format", "")) != FORMAT:
            raise ValueError(f"not a {FORMAT} file (format {_text(a.get('format', ''))!r})")
        version = _text(a.get("schema_version", ""))
        if version.split(".")[0] != str(SUPPORTED_MAJOR):
            raise ValueError(f"schema version {version!r} not supported (major {SUPPORTED_MAJOR})")
        if int(a.get("complete", 0)) != 1:
            raise ValueError("incomplete (attribute complete != 1): its writer stopped early")
        if int(a["dataset_link_count"]) != dataset_link_count:
            raise ValueError(f"dataset_link_count {int(a['dataset_link_count'])} != the dataset's "
                             f"{dataset_link_count} links: features of another dataset")
        self.A, self.C = int(a["along_cells"]), int(a["across_cells"])
        self.W, self.K = float(a["half_width_m"]), int(a["max_vehicles"])
        self.height_scale = float(a["height_scale_m"])
        self.materials = [str(m) for m in json.loads(_text(a["material_classes"]))]
        self.vehicle_classes = [str(m) for m in json.loads(_text(a["vehicle_classes"]))]
        self.links = self.file["links/link"][...].astype(np.int64)
        m = len(self.links)
        if np.any(np.diff(self.links) <= 0) or (m and (self.links[0] < 0 or self.links[-1] >= dataset_link_count)):
            raise ValueError("/links/link not strictly ascending rows of the dataset")
        # The file's layout (schemas/README.md): rasters (M, A x C) along-major, one (M, K) array a
        # vehicle field.
        shapes = {"corridor/height": (m, self.A * self.C), "corridor/material": (m, self.A * self.C),
                  "vehicles/count": (m,)}
        shapes.update({"vehicles/" + f: (m, self.K) for f in FILE_VEHICLE_FIELDS})
        for name, shape in shapes.items():
            if self.file[name].shape != shape:
                raise ValueError(f"/{name} has shape {self.file[name].shape}, expected {shape}")

    def close(self):
        self.file.close()

    def read(self, positions, block=8192):
        """height, material (u8, (n, A, C)), vehicles (f32 (n, K, 6): VEHICLE_FIELDS, NaN in empty
        slots), count (n,) of the given ascending row positions; read block by block because h5py's
        point selection is slow."""
        positions = np.asarray(positions, np.int64)
        n = len(positions)
        out = {"height": np.zeros((n, self.A * self.C), np.uint8),
               "material": np.zeros((n, self.A * self.C), np.uint8),
               "vehicles": np.full((n, self.K, 6), np.nan, np.float32),
               "count": np.zeros(n, np.uint8)}
        for b0 in np.unique(positions // block) * block:
            sel = (positions >= b0) & (positions < b0 + block)
            local = positions[sel] - b0
            for key, name in (("height", "corridor/height"), ("material", "corridor/material"),
                              ("count", "vehicles/count")):
                ds = self.file[name]
                out[key][sel] = ds[b0:min(b0 + block, ds.shape[0])][local]
            for j, field in enumerate(FILE_VEHICLE_FIELDS):
                ds = self.file["vehicles/" + field]
                v = ds[b0:min(b0 + block, ds.shape[0])][local].astype(np.float32)
                if field == "vclass":
                    v[v == EMPTY_SLOT] = np.nan
                out["vehicles"][sel, :, j] = v
        out["height"] = out["height"].reshape(n, self.A, self.C)
        out["material"] = out["material"].reshape(n, self.A, self.C)
        return out


def aggregates(ctx, height_scale, half_width):
    """(n, len(AGGREGATES)) scalar summaries of the context for the tree model."""
    h = ctx["height"].astype(np.float32) * height_scale
    n, _, c = h.shape
    centres = -half_width + (np.arange(c) + 0.5) * 2 * half_width / c
    strip = np.abs(centres) <= max(2 * half_width / c, 2.0)  # at least the two middle columns
    hc = h[:, :, strip]
    veh = ctx["vehicles"]
    count = ctx["count"].astype(np.float32)
    vh = np.nan_to_num(veh[:, :, 2], nan=0.0)  # rows beyond count are NaN
    across = np.where(np.isnan(veh[:, :, 1]), np.inf, np.abs(veh[:, :, 1]))
    near = across < NEAR_LINE_M
    none = np.zeros(n, np.float32)
    cols = [(hc > 0).mean(axis=(1, 2)), hc.max(axis=(1, 2)), (h > 0).mean(axis=(1, 2)), h.mean(axis=(1, 2)),
            count, vh.max(axis=1) if vh.shape[1] else none,
            np.minimum(across.min(axis=1), half_width + 1) if vh.shape[1] else none + half_width + 1,
            near.sum(axis=1), np.where(near, vh, 0).max(axis=1) if vh.shape[1] else none]
    return np.stack([np.asarray(x, np.float32) for x in cols], axis=1)


def vehicle_raster(vehicles, d_along, shape, half_width):
    """(n, A, C) tallest vehicle height per cell: each vehicle a box of its length along and its width
    across the link (vehicles on the link's own road are aligned with it, the ones that matter)."""
    n = len(vehicles)
    a_cells, c_cells = shape
    step_a = np.maximum(np.asarray(d_along, np.float32), 1e-3) / a_cells
    centre_a = (np.arange(a_cells) + 0.5)[None, :] * step_a[:, None]  # (n, A)
    step_c = 2 * half_width / c_cells
    centre_c = -half_width + (np.arange(c_cells) + 0.5) * step_c  # (C,)
    out = np.zeros((n, a_cells, c_cells), np.float32)
    for k in range(vehicles.shape[1]):
        v = vehicles[:, k]
        ok = ~np.isnan(v[:, 0])
        if not ok.any():
            continue
        in_a = np.abs(centre_a - v[:, :1]) <= (v[:, 3:4] / 2 + step_a[:, None] / 2)
        in_c = np.abs(centre_c[None, :] - v[:, 1:2]) <= (v[:, 4:5] / 2 + step_c / 2)
        box = in_a[:, :, None] & in_c[:, None, :] & ok[:, None, None]
        out = np.maximum(out, np.where(box, np.nan_to_num(v[:, 2])[:, None, None], 0))
    return out

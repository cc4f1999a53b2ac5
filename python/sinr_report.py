#!/usr/bin/python3
"""Report on raysweep SINR outcome files (format raysweep-sinr, schema major 1).

usage: sinr_report.py OUTDIR FILE.h5 [FILE.h5 ...] [--labels L1,L2,...]
                      [--reference INDEX] [--distance-bin METRES]

Writes into OUTDIR (created when missing; every output is written to a temporary
name in OUTDIR and renamed when complete):
  sinr_pdf.png      per RAT: density of sinr_db (1 dB bins) over the receptions with a
                    finite SINR and prx_dbm >= sensitivity_dbm, one step curve per file,
                    the SINR threshold as a vertical line
  prr_distance.png  per RAT: PRR against tx-rx distance of the first attempt, one line
                    per file (bins with at least MIN_BIN_SAMPLES samples)
  report.json       every number of the report (NaN as null)
  report.md         the same as a Markdown table (metrics x files), also printed to stdout

Per file: PRR per RAT (/prr_rats), decoded fraction, SINR mean/median and Sarle's
bimodality coefficient per RAT, per-node PRR as transmitter (/prr_links), and for every
file but the reference the disagreement ratio DR = |R delta M| / |R union M| with the
reference for (a) decodability ((transmission, rx) keys with decoded = 1) and (b)
inter-RAT interferer detection ((transmission, rx, interferer transmission) with
inter_rat = 1 and counted = 1), both over the receptions present in both files.

Exit status 2 with a one-line error naming the file when an input is missing, not
HDF5, not a raysweep-sinr file, incomplete, or of an unsupported schema major version.
Needs numpy, h5py and matplotlib (run with /usr/bin/python3 on Debian).
"""
import argparse
import hashlib
import json
import math
import os
import sys
import tempfile

import h5py
import numpy as np

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

FORMAT = "raysweep-sinr"
SUPPORTED_MAJOR = 1
RAT_NAMES = {0: "none", 1: "80211p", 2: "nrv2x"}
MIN_BIN_SAMPLES = 20          # PRR-distance bins with fewer samples are not plotted
BIMODAL_THRESHOLD = 5.0 / 9.0  # Sarle's b of a uniform distribution; above suggests bimodality
INTERFERER_BLOCK = 1 << 22    # /interferers rows read per block

TRANSMISSION_COLUMNS = ("node", "rat", "message", "packet", "attempt", "size_bytes", "start_s",
                        "duration_s", "band_hz", "power_dbm")
RECEPTION_COLUMNS = ("transmission", "rx", "rat", "packet", "attempt", "distance_m", "prx_dbm",
                     "sinr_db", "decoded", "overlap_count", "overlap_offset")


class ReportError(Exception):
    """A problem with an input file; the message names the file."""


def rat_name(rat):
    return RAT_NAMES.get(int(rat), f"rat{int(rat)}")


def _text(value):
    if isinstance(value, bytes):
        return value.decode("utf-8")
    return str(value)


def _num(value):
    """A JSON-safe float: NaN and infinities become None."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def _find_key(obj, key):
    """The value of `key` anywhere in parsed JSON (config may nest its sections)."""
    if isinstance(obj, dict):
        if key in obj:
            return obj[key]
        for v in obj.values():
            found = _find_key(v, key)
            if found is not None:
                return found
    elif isinstance(obj, list):
        for v in obj:
            found = _find_key(v, key)
            if found is not None:
                return found
    return None


# ---------------------------------------------------------------------------------------
# Statistics
# ---------------------------------------------------------------------------------------

def bimodality_coefficient(x):
    """Sarle's finite-sample bimodality coefficient
        b = (G1^2 + 1) / (G2 + 3 (n-1)^2 / ((n-2)(n-3)))
    with G1, G2 the bias-corrected sample skewness and excess kurtosis. NaN when n < 4
    or the values are all equal. b > 5/9 (a uniform distribution) suggests bimodality."""
    x = np.asarray(x, dtype=np.float64)
    n = x.size
    if n < 4:
        return math.nan
    d = x - x.mean()
    m2 = float(np.mean(d * d))
    if m2 <= 0:
        return math.nan
    m3 = float(np.mean(d ** 3))
    m4 = float(np.mean(d ** 4))
    g1 = m3 / m2 ** 1.5
    g2 = m4 / m2 ** 2 - 3.0
    G1 = g1 * math.sqrt(n * (n - 1)) / (n - 2)
    G2 = ((n + 1) * g2 + 6.0) * (n - 1) / ((n - 2) * (n - 3))
    return (G1 * G1 + 1.0) / (G2 + 3.0 * (n - 1) ** 2 / ((n - 2) * (n - 3)))


def disagreement(n_a, n_b, n_both):
    """DR = |A delta B| / |A union B| from the set sizes; 0 when the union is empty."""
    union = n_a + n_b - n_both
    sym = union - n_both
    return {"dr": (sym / union) if union else 0.0, "reference": int(n_a), "file": int(n_b),
            "both": int(n_both), "symmetric_difference": int(sym), "union": int(union)}


def group_sums(group, weights_a, weights_b):
    """Per distinct value of `group`: its values and the sums of both weight arrays."""
    values, inverse = np.unique(group, return_inverse=True)
    a = np.bincount(inverse, weights=weights_a, minlength=values.size)
    b = np.bincount(inverse, weights=weights_b, minlength=values.size)
    return values, a, b


# ---------------------------------------------------------------------------------------
# Reading one file
# ---------------------------------------------------------------------------------------

def open_sinr(path):
    """Opens and checks a SINR file; raises ReportError naming it."""
    if not os.path.exists(path):
        raise ReportError(f"{path}: no such file")
    if not os.path.isfile(path):
        raise ReportError(f"{path}: not a regular file")
    try:
        if not h5py.is_hdf5(path):
            raise ReportError(f"{path}: not an HDF5 file")
        f = h5py.File(path, "r")
    except OSError as e:
        raise ReportError(f"{path}: cannot be opened as HDF5 ({e})") from None
    try:
        attrs = f.attrs
        fmt = _text(attrs["format"]) if "format" in attrs else None
        if fmt != FORMAT:
            raise ReportError(f"{path}: not a {FORMAT} file (format attribute {fmt!r})")
        version = _text(attrs["schema_version"]) if "schema_version" in attrs else None
        try:
            major = int(version.split(".")[0])
        except (AttributeError, ValueError):
            major = None
        if major != SUPPORTED_MAJOR:
            raise ReportError(f"{path}: schema version {version!r} is not supported "
                              f"(this report reads major version {SUPPORTED_MAJOR})")
        if int(attrs.get("complete", 0)) != 1:
            raise ReportError(f"{path}: incomplete file (complete != 1: the writer did not finish)")
    except Exception:
        f.close()
        raise
    return f


def _dataset(f, path, name):
    try:
        return f[name]
    except KeyError:
        raise ReportError(f"{path}: dataset /{name} is missing") from None


def _column(f, path, name, rows=slice(None)):
    """A whole dataset (or a row range of it) as a numpy array."""
    return _dataset(f, path, name)[rows]


def _schedule_digest(f, path):
    """SHA-256 over the /transmissions columns: equal digests mean identical schedules."""
    h = hashlib.sha256()
    for c in TRANSMISSION_COLUMNS:
        col = np.ascontiguousarray(_column(f, path, "transmissions/" + c))
        h.update(f"{c}:{col.dtype.str}:{col.shape}".encode())
        h.update(col.tobytes())
    return h.hexdigest()


def _prr_distance(rec, rats, bin_m):
    """PRR against distance per RAT: the (packet, rx) pairs of the first attempts,
    binned by their distance; a pair counts as received when any attempt was decoded."""
    packet, rx, decoded = rec["packet"], rec["rx"], rec["decoded"]
    order = np.lexsort((rx, packet))
    ps, rs = packet[order], rx[order]
    starts = np.ones(order.size, dtype=bool)
    starts[1:] = (ps[1:] != ps[:-1]) | (rs[1:] != rs[:-1])
    group_sorted = np.cumsum(starts) - 1
    received = np.maximum.reduceat(decoded[order], np.flatnonzero(starts)) if order.size else np.zeros(0, bool)
    group = np.empty(order.size, dtype=np.int64)
    group[order] = group_sorted

    first = np.flatnonzero(rec["attempt"] == 0)
    out = {}
    for rat in rats:
        rows = first[rec["rat"][first] == rat]
        d = rec["distance_m"][rows].astype(np.float64)
        ok = received[group[rows]].astype(np.float64)
        keep = np.isfinite(d) & (d >= 0)
        b = np.floor(d[keep] / bin_m).astype(np.int64)
        n = np.bincount(b)
        got = np.bincount(b, weights=ok[keep], minlength=n.size)
        nz = np.flatnonzero(n)
        out[rat] = {"bin_m": bin_m, "lower_m": (nz * bin_m).tolist(), "samples": n[nz].tolist(),
                    "prr": (got[nz] / n[nz]).tolist()}
    return out


def _interferer_pairs(f, path, ends):
    """(reception row, interferer transmission row) of the /interferers rows with
    inter_rat = 1 and counted = 1, read in blocks of INTERFERER_BLOCK rows."""
    x_count = _dataset(f, path, "interferers/transmission").shape[0]
    rows, txs = [], []
    for x0 in range(0, x_count, INTERFERER_BLOCK):
        block = slice(x0, min(x_count, x0 + INTERFERER_BLOCK))
        hit = np.flatnonzero((_column(f, path, "interferers/inter_rat", block) == 1) &
                             (_column(f, path, "interferers/counted", block) == 1))
        if hit.size == 0:
            continue
        txs.append(_column(f, path, "interferers/transmission", block)[hit])
        # reception r owns the rows [offset[r], ends[r]): the owner of row x is the first r with ends[r] > x
        rows.append(np.searchsorted(ends, (hit + x0).astype(np.uint64), side="right"))
    if not rows:
        return np.zeros(0, np.int64), np.zeros(0, np.uint32)
    return np.concatenate(rows).astype(np.int64), np.concatenate(txs).astype(np.uint32)


def load(path, bin_m):
    """Reads one SINR file: its statistics, and what the comparisons need (reception
    keys, decoded flags, RATs, inter-RAT interferer pairs, schedule digest)."""
    with open_sinr(path) as f:
        a = f.attrs
        config = {}
        if "config" in a:
            try:
                config = json.loads(_text(a["config"]))
            except ValueError:
                raise ReportError(f"{path}: attribute config is not JSON") from None
        model = _text(a.get("channel_model", "unknown"))
        los_from_ray = int(a.get("los_from_ray", 0)) == 1
        sensitivity = float(a.get("sensitivity_dbm", -math.inf))
        threshold = float(a["sinr_threshold_db"]) if "sinr_threshold_db" in a else math.nan
        version = _text(a["schema_version"])

        rec = {c: _column(f, path, "receptions/" + c) for c in RECEPTION_COLUMNS}
        transmissions = int(_dataset(f, path, "transmissions/node").shape[0])
        digest = _schedule_digest(f, path)

        # Reception keys: (transmission, rx) packed into 64 bits, both u32 so no overflow.
        keys = (rec["transmission"].astype(np.uint64) << np.uint64(32)) | rec["rx"].astype(np.uint64)
        if keys.size > 1 and not np.all(keys[1:] > keys[:-1]):
            raise ReportError(f"{path}: /receptions is not strictly sorted by (transmission, rx)")

        counts = rec["overlap_count"].astype(np.uint64)
        offsets = rec["overlap_offset"].astype(np.uint64)
        ends = offsets + counts
        x_count = _dataset(f, path, "interferers/transmission").shape[0]
        if counts.size and (offsets[0] != 0 or np.any(offsets[1:] != ends[:-1]) or ends[-1] != x_count):
            raise ReportError(f"{path}: /receptions/overlap_offset is not the running sum of overlap_count")
        irow, itx = _interferer_pairs(f, path, ends)

        prr_rats = {c: _column(f, path, "prr_rats/" + c) for c in ("rat", "packets", "received", "prr")}
        links = {c: _column(f, path, "prr_links/" + c) for c in ("tx", "rat", "packets", "received")}

    decoded = rec["decoded"] != 0
    rat = rec["rat"]
    rats = sorted((set(np.unique(rat).tolist()) | set(np.unique(prr_rats["rat"]).tolist())) - {0})
    sinr = rec["sinr_db"]
    usable = np.isfinite(sinr) & (rec["prx_dbm"] >= sensitivity)
    curves = _prr_distance(rec, rats, bin_m)

    per_rat = {}
    sinr_values = {}
    for r in rats:
        mine = rat == r
        n_rec = int(np.count_nonzero(mine))
        n_dec = int(np.count_nonzero(decoded & mine))
        values = sinr[mine & usable]
        sinr_values[r] = values
        q = np.flatnonzero(prr_rats["rat"] == r)
        prr = None
        if q.size:
            i = q[0]
            prr = {"prr": _num(prr_rats["prr"][i]), "packets": int(prr_rats["packets"][i]),
                   "received": int(prr_rats["received"][i])}
        lk = links["rat"] == r
        _, sent, got = group_sums(links["tx"][lk], links["packets"][lk].astype(np.float64),
                                      links["received"][lk].astype(np.float64))
        have = sent > 0
        node_prr = got[have] / sent[have]
        per_rat[rat_name(r)] = {
            "prr": prr,
            "receptions": n_rec,
            "decoded": n_dec,
            "decoded_fraction": _num(n_dec / n_rec) if n_rec else None,
            "sinr": {
                "n": int(values.size),
                "mean_db": _num(np.mean(values, dtype=np.float64)) if values.size else None,
                "median_db": _num(np.median(values)) if values.size else None,
                "bimodality": _num(bimodality_coefficient(values)),
            },
            "tx_node_prr": {
                "nodes": int(node_prr.size),
                "mean": _num(node_prr.mean()) if node_prr.size else None,
                "min": _num(node_prr.min()) if node_prr.size else None,
                "max": _num(node_prr.max()) if node_prr.size else None,
            },
            "prr_distance": curves[r],
        }

    summary = {
        "path": path,
        "channel_model": model,
        "los_from_ray": los_from_ray,
        "schema_version": version,
        "sinr_threshold_db": _num(threshold),
        "sensitivity_dbm": _num(sensitivity),
        "prr_range_m": _num(_find_key(config, "prr_range_m")),
        "transmissions": transmissions,
        "receptions": int(keys.size),
        "rats": per_rat,
    }
    data = {"keys": keys, "decoded": decoded, "rat": rat, "irow": irow, "itx": itx,
            "digest": digest, "sinr": sinr_values, "threshold": threshold, "sensitivity": sensitivity}
    return summary, data


# ---------------------------------------------------------------------------------------
# Comparison with the reference
# ---------------------------------------------------------------------------------------

def common_rows(ka, kb):
    """Rows ia of ka and ib of kb with ka[ia] == kb[ib]; both strictly increasing."""
    if ka.size == 0 or kb.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    idx = np.searchsorted(kb, ka)
    clipped = np.minimum(idx, kb.size - 1)
    hit = kb[clipped] == ka
    return np.flatnonzero(hit), idx[hit].astype(np.int64)


def pair_keys(common, itx, n_common, t_max):
    """Set keys of (common reception index, interferer transmission): packed into
    uint64 when common * (t_max + 1) + itx fits, otherwise a structured array that
    numpy sorts lexicographically. Returns (unique keys, common index of each)."""
    if n_common * (t_max + 1) < 2 ** 64:
        k = common.astype(np.uint64) * np.uint64(t_max + 1) + itx.astype(np.uint64)
        k = np.unique(k)
        return k, (k // np.uint64(t_max + 1)).astype(np.int64)
    k = np.empty(common.size, dtype=[("c", "<u8"), ("t", "<u4")])
    k["c"], k["t"] = common, itx
    k = np.unique(k)
    return k, k["c"].astype(np.int64)


def compare(ref, other, ref_rats, other_rats):
    """Disagreement of `other` with the reference `ref` (data dicts of load())."""
    ia, ib = common_rows(ref["keys"], other["keys"])
    n_common = ia.size
    rat_common = ref["rat"][ia]
    rats = sorted(set(ref_rats) | set(other_rats))
    identical = ref["digest"] == other["digest"]

    # (a) decodability: decoded (transmission, rx) keys over the keys in both files.
    da, db = ref["decoded"][ia], other["decoded"][ib]
    dec = disagreement(int(da.sum()), int(db.sum()), int((da & db).sum()))
    dec.update(common_keys=int(n_common), only_in_reference=int(ref["keys"].size - n_common),
               only_in_file=int(other["keys"].size - n_common))
    dec["per_rat"] = {}
    for r in rats:
        m = rat_common == r
        a, b = da[m], db[m]
        dec["per_rat"][rat_name(r)] = disagreement(int(a.sum()), int(b.sum()), int((a & b).sum()))

    # (b) inter-RAT interferer detection: (reception, interferer) pairs with inter_rat = 1
    # and counted = 1, over the receptions in both files (indexed by their common index).
    pos_a = np.full(ref["keys"].size, -1, np.int64)
    pos_a[ia] = np.arange(n_common)
    pos_b = np.full(other["keys"].size, -1, np.int64)
    pos_b[ib] = np.arange(n_common)
    ca, cb = pos_a[ref["irow"]], pos_b[other["irow"]]
    ta, tb = ref["itx"][ca >= 0], other["itx"][cb >= 0]
    ca, cb = ca[ca >= 0], cb[cb >= 0]
    t_max = int(max(ta.max(initial=0), tb.max(initial=0)))
    ka, ga = pair_keys(ca, ta, n_common, t_max)
    kb, gb = pair_keys(cb, tb, n_common, t_max)
    both, i_a, _ = np.intersect1d(ka, kb, assume_unique=True, return_indices=True)
    inter = disagreement(ka.size, kb.size, both.size)
    inter["per_rat"] = {}
    ra, rb, rboth = rat_common[ga], rat_common[gb], rat_common[ga[i_a]]
    for r in rats:
        inter["per_rat"][rat_name(r)] = disagreement(int(np.count_nonzero(ra == r)), int(np.count_nonzero(rb == r)),
                                                     int(np.count_nonzero(rboth == r)))
    out = {"schedules_identical": bool(identical), "decodability": dec, "interferer_detection": inter}
    if not identical:
        out["note"] = ("comparison over differing schedules: the /transmissions tables differ, "
                       "DR is computed over (transmission row, rx) keys anyway")
    return out


# ---------------------------------------------------------------------------------------
# Output
# ---------------------------------------------------------------------------------------

def write_atomic(outdir, name, write):
    """Calls write(tmp_path) on a temporary name in outdir, then renames it to name."""
    fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=".tmp", dir=outdir)
    os.close(fd)
    try:
        write(tmp)
        os.replace(tmp, os.path.join(outdir, name))
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


def _write_text(text):
    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
    return write


def _subplots(count):
    count = max(count, 1)
    fig, axes = plt.subplots(1, count, figsize=(6.2 * count, 4.6), squeeze=False)
    return fig, axes[0]


def _save(fig):
    def write(tmp):
        fig.savefig(tmp, format="png", dpi=120)
    return write


def plot_sinr_pdf(outdir, labels, data, rats):
    fig, axes = _subplots(len(rats))
    if not rats:
        axes[0].text(0.5, 0.5, "no receptions", ha="center", va="center", transform=axes[0].transAxes)
    for ax, r in zip(axes, rats):
        values = [d["sinr"].get(r, np.zeros(0, np.float32)) for d in data]
        finite = [v for v in values if v.size]
        if finite:
            lo = math.floor(min(float(v.min()) for v in finite))
            hi = math.floor(max(float(v.max()) for v in finite)) + 1
            edges = np.arange(lo, hi + 1, 1.0)
            for label, v in zip(labels, values):
                if v.size:
                    density, _ = np.histogram(v, bins=edges, density=True)
                    ax.stairs(density, edges, label=f"{label} (n={v.size})")
        else:
            ax.text(0.5, 0.5, "no receptions above sensitivity", ha="center", va="center",
                    transform=ax.transAxes)
        for t in sorted({d["threshold"] for d in data if math.isfinite(d["threshold"])}):
            ax.axvline(t, color="k", linestyle="--", linewidth=1, label=f"SINR threshold {t:g} dB")
        sens = sorted({d["sensitivity"] for d in data if math.isfinite(d["sensitivity"])})
        sens_text = ", ".join(f"{s:g}" for s in sens) or "-"
        ax.set_title(f"{rat_name(r)}: SINR density, finite SINR with\nprx >= sensitivity ({sens_text} dBm): "
                     "the decision region", fontsize=10)
        ax.set_xlabel("SINR [dB] (1 dB bins)")
        ax.set_ylabel("probability density [1/dB]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    write_atomic(outdir, "sinr_pdf.png", _save(fig))
    plt.close(fig)


def plot_prr_distance(outdir, labels, summaries, rats, bin_m):
    fig, axes = _subplots(len(rats))
    if not rats:
        axes[0].text(0.5, 0.5, "no receptions", ha="center", va="center", transform=axes[0].transAxes)
    for ax, r in zip(axes, rats):
        drawn = False
        for label, s in zip(labels, summaries):
            c = s["rats"].get(rat_name(r), {}).get("prr_distance")
            if not c:
                continue
            n = np.asarray(c["samples"])
            keep = n >= MIN_BIN_SAMPLES
            if not keep.any():
                continue
            x = np.asarray(c["lower_m"], dtype=np.float64)[keep] + bin_m / 2
            ax.plot(x, np.asarray(c["prr"])[keep], marker="o", markersize=3, label=label)
            drawn = True
        if not drawn:
            ax.text(0.5, 0.5, f"no bin with >= {MIN_BIN_SAMPLES} samples", ha="center", va="center",
                    transform=ax.transAxes)
        ax.set_title(f"{rat_name(r)}: PRR vs distance (first attempts,\n{bin_m:g} m bins, "
                     f">= {MIN_BIN_SAMPLES} (packet, rx) per bin)", fontsize=10)
        ax.set_xlabel("tx-rx distance at the first attempt [m]")
        ax.set_ylabel("PRR (any attempt decoded)")
        ax.set_ylim(-0.02, 1.02)
        ax.grid(alpha=0.3)
        if drawn:
            ax.legend(fontsize=8)
    fig.tight_layout()
    write_atomic(outdir, "prr_distance.png", _save(fig))
    plt.close(fig)


def _fmt(v, digits=4):
    if v is None:
        return "n/a"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return str(v)
    return f"{v:.{digits}f}"


def _dr_cell(d):
    return f"{_fmt(d['dr'])} ({d['symmetric_difference']}/{d['union']})"


def markdown(report):
    files = report["files"]
    rats = report["rats"]
    ref = report["reference"]
    header = "| metric | " + " | ".join(f["label"] for f in files) + " |"
    lines = [header, "|" + "---|" * (len(files) + 1)]

    def row(name, cells):
        lines.append(f"| {name} | " + " | ".join(cells) + " |")

    def per_rat(f, r):
        return f["rats"].get(r, {})

    row("channel_model", [f["channel_model"] for f in files])
    row("los_from_ray", [_fmt(f["los_from_ray"]) for f in files])
    row("transmissions", [_fmt(f["transmissions"]) for f in files])
    row("receptions", [_fmt(f["receptions"]) for f in files])
    for r in rats:
        cells = []
        for f in files:
            p = per_rat(f, r).get("prr")
            cells.append(f"{_fmt(p['prr'])} ({p['received']}/{p['packets']})" if p else "n/a")
        row(f"PRR {r} (/prr_rats)", cells)
    for r in rats:
        row(f"decoded fraction {r}", [
            f"{_fmt(per_rat(f, r).get('decoded_fraction'))} ({per_rat(f, r).get('decoded', 0)}/"
            f"{per_rat(f, r).get('receptions', 0)})" for f in files])
    for r in rats:
        cells = []
        for f in files:
            s = per_rat(f, r).get("sinr", {})
            cells.append(f"{_fmt(s.get('mean_db'), 2)} / {_fmt(s.get('median_db'), 2)} (n={s.get('n', 0)})")
        row(f"SINR mean / median {r} [dB]", cells)
    for r in rats:
        row(f"bimodality b {r}", [_fmt(per_rat(f, r).get("sinr", {}).get("bimodality"), 3) for f in files])
    for r in rats:
        cells = []
        for f in files:
            t = per_rat(f, r).get("tx_node_prr")
            cells.append(f"{_fmt(t['mean'])} [{_fmt(t['min'])}, {_fmt(t['max'])}] ({t['nodes']} nodes)"
                         if t and t["nodes"] else "n/a")
        row(f"tx-node PRR {r} mean [min, max]", cells)

    def comp(fn):
        return ["reference" if f["comparison"] is None else fn(f["comparison"]) for f in files]

    row("schedule vs reference", comp(lambda c: "identical" if c["schedules_identical"] else "differs"))
    row("DR decodability", comp(lambda c: _dr_cell(c["decodability"])))
    for r in rats:
        row(f"DR decodability {r}", comp(lambda c: _dr_cell(c["decodability"]["per_rat"][r])
                                         if r in c["decodability"]["per_rat"] else "n/a"))
    row("keys only in reference / only in file",
        comp(lambda c: f"{c['decodability']['only_in_reference']} / {c['decodability']['only_in_file']}"))
    row("DR inter-RAT interferer detection", comp(lambda c: _dr_cell(c["interferer_detection"])))
    for r in rats:
        row(f"DR interferer detection {r}", comp(lambda c: _dr_cell(c["interferer_detection"]["per_rat"][r])
                                                 if r in c["interferer_detection"]["per_rat"] else "n/a"))

    notes = [
        "",
        f"Reference: {ref}. DR = |R delta M| / |R union M| (counts in parentheses; 0 when the union is empty).",
        "Decodability: (transmission, rx) keys with decoded = 1, over the keys present in both files. "
        "Interferer detection: (transmission, rx, interferer transmission) with inter_rat = 1 and counted = 1, "
        "over the receptions present in both files.",
        "SINR mean/median and the bimodality coefficient use the receptions with a finite SINR and "
        "prx >= sensitivity (the population of sinr_pdf.png). Sarle's b = (skew^2 + 1) / (excess kurtosis + "
        f"3(n-1)^2/((n-2)(n-3))), bias-corrected moments; b > 5/9 = {BIMODAL_THRESHOLD:.3f} suggests bimodality.",
        "tx-node PRR: /prr_links summed per transmitting node (sum received / sum packets), then mean, min "
        "and max over the nodes.",
    ]
    for f in files:
        c = f["comparison"]
        if c is not None and not c["schedules_identical"]:
            notes.append(f"{f['label']}: comparison over differing schedules (its /transmissions table differs "
                         "from the reference's); DR is computed over keys anyway.")
    return "\n".join(lines + notes) + "\n"


# ---------------------------------------------------------------------------------------
# Main
# ---------------------------------------------------------------------------------------

def default_labels(summaries):
    labels = [s["channel_model"] + ("+los-from-ray" if s["los_from_ray"] else "") for s in summaries]
    for label in set(labels):
        same = [i for i, l in enumerate(labels) if l == label]
        if len(same) > 1:
            for i in same:
                labels[i] = f"{label} ({os.path.splitext(os.path.basename(summaries[i]['path']))[0]})"
    for i, label in enumerate(labels):  # stems may collide too
        if labels.count(label) > 1:
            labels[i] = f"{label} #{i}"
    return labels


def parse_args(argv):
    p = argparse.ArgumentParser(description="Report on raysweep SINR outcome files.")
    p.add_argument("outdir")
    p.add_argument("files", nargs="+", metavar="FILE.h5")
    p.add_argument("--labels", help="comma-separated labels, one per file")
    p.add_argument("--reference", type=int, default=0, help="index of the reference file (default 0)")
    p.add_argument("--distance-bin", type=float, default=25.0, help="PRR-distance bin width in metres")
    args = p.parse_args(argv)
    if args.labels is not None:
        args.labels = [s.strip() for s in args.labels.split(",")]
        if len(args.labels) != len(args.files) or not all(args.labels) or len(set(args.labels)) != len(args.labels):
            p.error(f"--labels needs {len(args.files)} distinct non-empty labels, one per file")
    if not 0 <= args.reference < len(args.files):
        p.error(f"--reference must be in 0..{len(args.files) - 1}")
    if not (args.distance_bin > 0 and math.isfinite(args.distance_bin)):
        p.error("--distance-bin must be positive")
    return args


def main(argv=None):
    args = parse_args(sys.argv[1:] if argv is None else argv)
    try:
        for path in args.files:  # check every file before the slow reading
            open_sinr(path).close()
        loaded = [load(path, args.distance_bin) for path in args.files]
    except ReportError as e:
        print(f"sinr_report: error: {e}", file=sys.stderr)
        return 2
    summaries = [s for s, _ in loaded]
    data = [d for _, d in loaded]
    labels = args.labels or default_labels(summaries)
    rat_codes = sorted({r for d in data for r in d["sinr"]})
    ref = args.reference

    files = []
    for i, (s, label) in enumerate(zip(summaries, labels)):
        comparison = None
        if i != ref:
            comparison = dict(reference=labels[ref],
                              **compare(data[ref], data[i], list(data[ref]["sinr"]), list(data[i]["sinr"])))
        files.append(dict(label=label, **s, comparison=comparison))

    report = {
        "format": "raysweep-sinr-report",
        "reference": labels[ref],
        "distance_bin_m": args.distance_bin,
        "min_bin_samples": MIN_BIN_SAMPLES,
        "rats": [rat_name(r) for r in rat_codes],
        "files": files,
    }
    os.makedirs(args.outdir, exist_ok=True)
    plot_sinr_pdf(args.outdir, labels, data, rat_codes)
    plot_prr_distance(args.outdir, labels, report["files"], rat_codes, args.distance_bin)
    write_atomic(args.outdir, "report.json", _write_text(json.dumps(report, indent=2, allow_nan=False) + "\n"))
    md = markdown(report)
    write_atomic(args.outdir, "report.md", _write_text(md))
    sys.stdout.write(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())

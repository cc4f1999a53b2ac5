"""The rules both tools' paths go through before they are compared.

Imported by `compare` (Debian's Python) and by `sionna_paths.py` (the peer's
virtual environment, for its convergence test), so both sides apply the very
same rules. numpy only.

A path is a row of interaction codes, Sionna's `InteractionType` bits (0 none,
1 specular, 2 diffuse, 4 refraction, 8 diffraction), padded with 0, plus a flag
per interaction telling whether it lies on a vehicle.
"""
import math

import numpy as np

NONE, SPECULAR, DIFFUSE, REFRACTION, DIFFRACTION = 0, 1, 2, 4, 8
CODE = {"specular": SPECULAR, "diffuse": DIFFUSE, "refraction": REFRACTION, "diffraction": DIFFRACTION}
LETTER = {SPECULAR: "R", DIFFUSE: "S", REFRACTION: "T", DIFFRACTION: "D"}
# Mechanism of a path: the first that applies, in this order.
MECHANISMS = ["los", "specular", "refraction", "diffraction", "diffuse"]
C_LIGHT = 299792458.0
# Peak gain (dBi) of raysweep's antennas: the range cut uses it on both ends.
PEAK_GAIN_DBI = {"isotropic": 0.0, "dipole": 10 * math.log10(1.5), "halfwave": 10 * math.log10(1.641)}


def counts(types):
    """Per path: reflections, diffuse, refractions, diffractions."""
    t = np.asarray(types)
    return [(t == c).sum(axis=1) for c in (SPECULAR, DIFFUSE, REFRACTION, DIFFRACTION)]


def mechanism(types):
    """Index into MECHANISMS: diffuse if any diffuse interaction, else diffraction
    if any, else refraction if any, else specular if any reflection, else LoS."""
    spec, dif, refr, dfr = counts(types)
    m = np.zeros(len(spec), dtype=np.int8)
    m[spec > 0] = 1
    m[refr > 0] = 2
    m[dfr > 0] = 3
    m[dif > 0] = 4
    return m


def in_model(types, on_vehicle, tracer):
    """Paths of the classes raysweep traces with these [tracer] settings (the
    peer may find longer or mixed ones: its depth counts every interaction).

    - LoS, reflections and slabs: at most max_depth reflections and at most
      max_transmissions slabs (raysweep caps them separately);
    - diffraction: one edge, no slab, no diffuse; with diffraction_reflection
      one reflection on a static face before or after it; on a vehicle's edge
      (vehicle_edge_diffraction) nothing else;
    - diffuse: one scattering, which counts as a bounce (reflections + 1 <=
      max_depth), slabs within max_transmissions, no edge, and the scattering
      first or last (raysweep's rays gather from the hits of one end's chain;
      a scattering between reflections is in neither end's chain).
    """
    t = np.asarray(types)
    veh = np.asarray(on_vehicle, dtype=bool)
    spec, dif, refr, dfr = counts(t)
    depth = int(tracer.get("max_depth", 3))
    slabs = int(tracer.get("max_transmissions", 2)) if tracer.get("refraction", True) else 0
    plain = (dfr == 0) & (dif == 0) & (spec <= depth) & (refr <= slabs)
    refl_max = 1 if tracer.get("diffraction_reflection", True) else 0
    veh_edge = ((t == DIFFRACTION) & veh).any(axis=1)
    veh_refl = ((t == SPECULAR) & veh).any(axis=1)
    edge = (dfr == 1) & (dif == 0) & (refr == 0) & (spec <= refl_max) & ~veh_refl
    edge &= ~veh_edge | ((spec == 0) & bool(tracer.get("vehicle_edge_diffraction", False)))
    n = np.count_nonzero(t, axis=1)
    at_end = (t[:, 0] == DIFFUSE) | (t[np.arange(len(t)), np.maximum(n - 1, 0)] == DIFFUSE) if t.size else n > 0
    diffuse = (dif == 1) & (dfr == 0) & (spec + 1 <= depth) & (refr <= slabs) & at_end
    return plain | edge | diffuse


def diffuse_then_reflection(types):
    """Paths that scatter diffusely and then reflect or cross a slab (from tx
    to rx). Sionna hashes such a chain as a specular one with the diffuse
    interaction as a code, not a point: one path per plane sequence survives,
    with one sample's weight, so its power in this class is biased low.
    raysweep traces the class (the receiver end's rays gather it)."""
    t = np.asarray(types)
    if t.size == 0:
        return np.zeros(len(t), dtype=bool)
    dif = np.cumsum(t == DIFFUSE, axis=1) > 0
    after = dif & ((t == SPECULAR) | (t == REFRACTION))
    return after.any(axis=1)


def duplicates(pair, tau, types, objects, tol_s=2e-11):
    """Paths that repeat an earlier one of their pair: the same interactions on
    the same objects and a delay within tol_s (Sionna can return one path
    several times, found through two hashes of its candidate chain or through
    coplanar triangles of one wall). 2e-11 s is 6 mm: Sionna computes in
    single precision, and at Bad Hersfeld's SUMO coordinates (8 km from the
    origin, 1 mm per float ulp) copies of one path differ by up to 2 mm."""
    n = len(pair)
    if n == 0:
        return np.zeros(0, dtype=bool)
    order = np.lexsort((tau, pair))
    p, t = pair[order], tau[order]
    ty, ob = np.asarray(types)[order], np.asarray(objects)[order]
    dup = np.zeros(n, dtype=bool)
    for lag in range(1, 4):  # coincident delays of different paths interleave
        same = (p[lag:] == p[:-lag]) & (np.abs(t[lag:] - t[:-lag]) < tol_s)
        same &= (ty[lag:] == ty[:-lag]).all(axis=1) & (ob[lag:] == ob[:-lag]).all(axis=1)
        dup[lag:] |= same
    out = np.zeros(n, dtype=bool)
    out[order] = dup
    return out


def keep_above_threshold(pair, power, threshold_db):
    """raysweep's path_threshold_db: drop paths this far below their pair's
    strongest (<= 0: keep all)."""
    if threshold_db <= 0 or len(power) == 0:
        return np.ones(len(power), dtype=bool)
    strongest = np.zeros(pair.max() + 1)
    np.maximum.at(strongest, pair, power)
    return power >= strongest[pair] * 10 ** (-threshold_db / 10)


def max_range_m(radio, tracer):
    """raysweep's range cut: the free-space reach of the sensitivity with the
    antennas' peak gains and range_margin_db; pairs farther apart carry no paths."""
    g = PEAK_GAIN_DBI.get(radio.get("antenna", "isotropic"), 0.0)
    budget = radio["tx_power_dbm"] - radio["sensitivity_dbm"] + 2 * g + tracer.get("range_margin_db", 6.0)
    lam = C_LIGHT / radio["frequency_hz"]
    return lam / (4 * math.pi) * 10 ** (budget / 20)


def gain_db(power_sum):
    """10 log10 of summed |a|^2; -inf for no paths."""
    p = np.asarray(power_sum, dtype=float)
    with np.errstate(divide="ignore"):
        return np.where(p > 0, 10 * np.log10(np.maximum(p, 1e-300)), -np.inf)


def pair_power(pair, power, n_pairs):
    out = np.zeros(n_pairs)
    np.add.at(out, pair, power)
    return out


def run_change(prev_db, cur_db, total_db, floor_db):
    """What one more Sionna run changed, over the pairs at or above the floor
    (by their total gain total_db): the largest |change| of the runs' united
    (non-diffuse) gain, its p95, and how many such pairs had no paths before."""
    prev_db, cur_db, total_db = np.asarray(prev_db), np.asarray(cur_db), np.asarray(total_db)
    use = np.isfinite(total_db) & (total_db >= floor_db)
    both = use & np.isfinite(cur_db) & np.isfinite(prev_db)
    d = np.abs(cur_db[both] - prev_db[both])
    appeared = int((use & np.isfinite(cur_db) & ~np.isfinite(prev_db)).sum())
    return (float(d.max()) if len(d) else 0.0, float(np.percentile(d, 95)) if len(d) else 0.0, appeared)


def standard_error_db(per_run_power, total_db):
    """Per pair, the standard error of the mean over runs of its diffuse power
    (per_run_power: runs x pairs), relative to the pair's total power, in dB:
    10 log10(1 + SE / P)."""
    x = np.asarray(per_run_power, dtype=float)
    se = x.std(axis=0, ddof=1) / np.sqrt(x.shape[0])
    total = np.where(np.isfinite(total_db), 10 ** (np.asarray(total_db, dtype=float) / 10), 0.0)
    return 10 * np.log10(1 + se / np.maximum(total, 1e-300))


def signature(types):
    """A path's interaction sequence in letters (R reflection, T slab, D edge,
    S diffuse; LoS for none)."""
    s = "".join(LETTER[int(c)] for c in types if int(c) in LETTER)
    return s or "LoS"

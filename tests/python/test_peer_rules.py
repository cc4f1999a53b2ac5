#!/usr/bin/python3
"""Checks bench/peers/sionna/peer_rules.py, the rules both tools' paths go
through before the Sionna RT comparison, on hand-made paths: which classes
raysweep traces, duplicates, the path threshold, the range cut against Friis,
the convergence figures. Runs without the peer.

usage: PYTHONPATH=bench/peers/sionna:python test_peer_rules.py
Exits 0 when every check passes; prints the failures and exits 1 otherwise.
"""
import math
import sys

import numpy as np

import peer_rules as rules
from test_reader import check, report

R, S, T, D = rules.SPECULAR, rules.DIFFUSE, rules.REFRACTION, rules.DIFFRACTION


def in_model(paths, tracer, vehicle=None):
    types = np.array([p + [0] * (5 - len(p)) for p in paths])
    veh = np.zeros(types.shape, dtype=bool) if vehicle is None else np.array(vehicle)
    return rules.in_model(types, veh, tracer).tolist()


def classes():
    tracer = {"max_depth": 3, "max_transmissions": 2, "diffraction_reflection": True}
    got = in_model([[], [R, R, R], [R, R, R, R], [T, T], [T, T, T], [T, R, R, R, T], [T, R, R, R, R]], tracer)
    check(got == [True, True, False, True, False, True, False], f"reflections and slabs capped apart: {got}")
    got = in_model([[D], [R, D], [D, R], [R, D, R], [D, T], [D, D]], tracer)
    check(got == [True, True, True, False, False, False], f"one edge, one static reflection: {got}")
    got = in_model([[R, D]], dict(tracer, diffraction_reflection=False))
    check(got == [False], "no reflection beside the edge when diffraction_reflection is off")
    # An edge on a vehicle: alone only, and only with vehicle_edge_diffraction.
    on_veh = [[True, False, False, False, False]]
    check(in_model([[D]], tracer, on_veh) == [False], "a vehicle's edge without vehicle_edge_diffraction")
    check(in_model([[D]], dict(tracer, vehicle_edge_diffraction=True), on_veh) == [True], "a vehicle's edge")
    got = in_model([[D, R]], dict(tracer, vehicle_edge_diffraction=True), [[False, True, False, False, False]])
    check(got == [False], "an edge with a reflection on a vehicle")
    got = in_model([[S], [R, R, S], [R, R, R, S], [T, T, S], [S, D]], tracer)
    check(got == [True, True, False, True, False], f"a scattering counts as a bounce: {got}")
    # raysweep's rays gather from the hits of one end's chain: the scattering
    # is the first or the last interaction, never between two others.
    got = in_model([[S, R, R], [S, T], [R, S, R], [T, S, T], [R, S, T]], tracer)
    check(got == [True, True, False, False, False], f"the scattering at an end of the chain: {got}")


def diffuse_then_reflection():
    types = np.array([[S, R, 0], [R, S, 0], [S, T, 0], [S, 0, 0], [R, R, 0], [R, S, R], [0, 0, 0]])
    got = rules.diffuse_then_reflection(types).tolist()
    check(got == [True, False, True, False, False, True, False], f"diffuse then a reflection or slab: {got}")
    check(rules.diffuse_then_reflection(np.zeros((0, 3), dtype=np.uint8)).size == 0, "no paths, none")


def mechanisms():
    types = np.array([[0, 0], [R, 0], [R, T], [D, R], [R, S]])
    got = [rules.MECHANISMS[m] for m in rules.mechanism(types)]
    check(got == ["los", "specular", "refraction", "diffraction", "diffuse"], f"mechanisms: {got}")
    check(rules.signature([R, T, 0]) == "RT" and rules.signature([0, 0]) == "LoS", "signatures")


def duplicates():
    pair = np.array([0, 0, 0, 1, 0, 0])
    tau = np.array([1e-6, 1e-6 + 7e-12, 1e-6, 1e-6, 1e-6 + 1e-10, 2e-6])
    types = np.array([[R, 0], [R, 0], [R, 0], [R, 0], [R, 0], [R, 0]])
    objects = np.array([[3, 0], [3, 0], [4, 0], [3, 0], [3, 0], [3, 0]])
    got = rules.duplicates(pair, tau, types, objects).tolist()
    # Only the second repeats an earlier path (2 mm longer: single-precision
    # copies): the third is another object, the fourth another pair, the
    # fifth 3 cm longer, the sixth another delay altogether.
    check(got == [False, True, False, False, False, False], f"duplicates: {got}")
    check(rules.duplicates(np.array([], int), np.array([]), np.zeros((0, 2)), np.zeros((0, 2))).size == 0,
          "no paths, no duplicates")


def threshold_and_power():
    pair = np.array([0, 0, 0, 1])
    power = np.array([1.0, 1e-7, 1e-5, 1e-9])
    got = rules.keep_above_threshold(pair, power, 60).tolist()
    check(got == [True, False, True, True], f"60 dB below the pair's strongest: {got}")
    check(rules.keep_above_threshold(pair, power, 0).all(), "threshold 0 keeps all")
    g = rules.gain_db(rules.pair_power(pair, power, 3))
    check(abs(g[0] - 10 * math.log10(1 + 1e-7 + 1e-5)) < 1e-12 and g[2] == -math.inf, f"pair gains: {g}")


def range_cut():
    radio = {"antenna": "dipole", "tx_power_dbm": 20.0, "sensitivity_dbm": -92.0, "frequency_hz": 5.9e9}
    d = rules.max_range_m(radio, {"range_margin_db": 6.0})
    # Friis with both dipoles' peak gain (1.5 each): the loss at d equals the budget.
    lam = 299792458.0 / 5.9e9
    friis_db = 20 * math.log10(4 * math.pi * d / lam) - 2 * 10 * math.log10(1.5)
    check(abs(friis_db - (20 + 92 + 6)) < 1e-9, f"range cut: Friis {friis_db} dB at {d} m")


def convergence():
    inf = np.inf
    prev = np.array([-80.0, -100.0, -inf, -130.0, -90.0])
    cur = np.array([-80.05, -100.0, -110.0, -125.0, -inf])
    total = np.array([-80.0, -100.0, -110.0, -125.0, -inf])
    worst, p95, appeared = rules.run_change(prev, cur, total, -123.0)
    # Pair 3 is below the floor (its 5 dB change does not count); pair 2 got
    # its first paths above it.
    check(abs(worst - 0.05) < 1e-9 and appeared == 1, f"one more run's change: {worst} {appeared}")
    check(rules.run_change(prev, prev, total, -123.0)[:2] == (0.0, 0.0), "an unchanged run")
    # Diffuse powers of two pairs over four runs: mean 1e-10 and 0; the first
    # pair's total 1e-9: SE = std / 2 relative to it.
    runs = np.array([[0.5e-10, 0], [1.5e-10, 0], [0.5e-10, 0], [1.5e-10, 0]])
    se = rules.standard_error_db(runs, np.array([-90.0, -100.0]))
    want = 10 * math.log10(1 + np.std(runs[:, 0], ddof=1) / 2 / 1e-9)
    check(abs(se[0] - want) < 1e-12 and se[1] == 0.0, f"standard error: {se} {want}")


def main():
    for f in (classes, diffuse_then_reflection, mechanisms, duplicates, threshold_and_power, range_cut, convergence):
        f()
    return report()


if __name__ == "__main__":
    sys.exit(main())

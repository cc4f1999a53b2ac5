"""Splits, fitting and scoring of every model on every split."""
import time

import numpy as np

import raysweep_dataset as rd

from . import baselines, models, tasks
from .data import InputError

BASELINE, BASELINE_TRUE = "tr37885", "tr37885+true-los"


class Split:
    """train/val/test: lists of (City, link row indices); *_rec: (City, reception indices)."""

    def __init__(self, name, kind, train, val, test, val_rec, test_rec):
        self.name, self.kind = name, kind
        self.train, self.val, self.test = train, val, test
        self.val_rec, self.test_rec = val_rec, test_rec


def _windows(city):
    try:
        return rd.time_splits(city.times, (0.7, 0.15, 0.15), gap_s=1.0)
    except ValueError as e:
        raise InputError(f"{city.run_dir}/dataset.h5: {e}") from None


def _links(city, frames):
    return np.nonzero(city.in_sample & np.isin(city.frame, frames))[0]


def _recs(city, frames):
    if city.rec is None:
        return np.empty(0, np.int64)
    return np.nonzero(np.isin(city.rec["frame"], frames))[0]


def make_splits(cities):
    """Leave-one-city-out with two or more cities (train on the others' train windows, stop early on
    their val windows, test on the whole held-out city), then each city's time split."""
    win = {c.name: _windows(c) for c in cities}
    every = {c.name: np.arange(len(c.times)) for c in cities}
    out = []
    if len(cities) > 1:
        for train_names, held in rd.city_rotations([c.name for c in cities]):
            others = [c for c in cities if c.name in train_names]
            h = next(c for c in cities if c.name == held)
            out.append(Split(held, "city", [(c, _links(c, win[c.name]["train"])) for c in others],
                             [(c, _links(c, win[c.name]["val"])) for c in others], (h, _links(h, every[held])),
                             [(c, _recs(c, win[c.name]["val"])) for c in others], (h, _recs(h, every[held]))))
    for c in cities:
        w = win[c.name]
        out.append(Split(f"{c.name}:time", "time", [(c, _links(c, w["train"]))], [(c, _links(c, w["val"]))],
                         (c, _links(c, w["test"])), [(c, _recs(c, w["val"]))], (c, _recs(c, w["test"]))))
    return out


def learned_models(split, n_materials, seed, threads=2):
    """gbdt always (with context aggregates when every city of the split has features.h5); cnn only
    then, and only when the cities' grids agree."""
    cities = [c for c, _ in split.train + split.val] + [split.test[0]]
    with_ctx = all(c.ctx is not None for c in cities)
    same_grid = with_ctx and len({(c.grid["A"], c.grid["C"]) for c in cities}) == 1
    out = [models.Gbdt(with_ctx, seed)]
    if same_grid:
        out.append(models.Cnn(n_materials, seed, threads))
    return out


def _baseline_predictions(city, idx, rec_idx, true_los):
    tr = baselines.Tr37885(city.scenario, city.fc_hz, city.heights)
    truth = city.cls[idx] if true_los else None
    p = tr.predict(city.d2[idx], city.d3[idx], city.floor_db, truth)
    packets = np.empty(0)
    if city.rec is not None and len(rec_idx):
        rows = city.rec["row"][rec_idx]
        q = tr.predict(city.d2[rows], city.d3[rows], city.floor_db, city.cls[rows] if true_los else None)
        packets = baselines.decode_probability(q["mean"], q["sigma"], q["proba"], city.rec["tx_power_dbm"][rec_idx],
                                               city.rec["required_dbm"][rec_idx])
    return {"cls": p["cls"], "proba": p["proba"], "gain_db": p["gain_db"], "p_decoded": packets}


def _learned_predictions(model, split, deadline):
    model.fit(split.train, split.val, deadline)
    model.fit_packet(split.val, split.val_rec)
    city, idx = split.test
    p = model.predict(city, idx)
    rec_idx = split.test_rec[1]
    p["p_decoded"] = model.predict_packets(city, rec_idx) if city.rec is not None and len(rec_idx) else np.empty(0)
    return p


def truth_of(split):
    city, idx = split.test
    rec_idx = split.test_rec[1]
    has_rec = city.rec is not None and len(rec_idx) > 0
    return {"cls": city.cls[idx], "gain": city.gain[idx], "d3": city.d3[idx], "frame": city.frame[idx],
            "decoded": city.rec["decoded"][rec_idx] if has_rec else None,
            "rec_frame": city.rec["frame"][rec_idx] if has_rec else None}


def task_inputs(task, model, truth, p):
    """(truth, prediction, frames) of a task, or None when it does not apply."""
    if task == tasks.TASK_A:
        # With the true class the LoS task is answered by its label: nothing to score.
        return None if model == BASELINE_TRUE else ({"cls": truth["cls"]}, {"cls": p["cls"]}, truth["frame"])
    if task == tasks.TASK_B:
        ok = np.isfinite(truth["gain"])  # out-of-range links have no gain label
        return ({"gain": truth["gain"][ok], "cls": truth["cls"][ok], "d3": truth["d3"][ok]},
                {"gain": p["gain_db"][ok]}, truth["frame"][ok])
    if truth["decoded"] is None:
        return None
    return {"decoded": truth["decoded"]}, {"p": p["p_decoded"]}, truth["rec_frame"]


def score_split(split, preds, resamples, seed):
    truth, rows = truth_of(split), []
    for model, p in preds.items():
        for task in tasks.TASKS:
            got = task_inputs(task, model, truth, p)
            if got is None:
                continue
            t, q, frames = got
            rows += tasks.score(task, model, split.name, t, q, frames, resamples, seed)
            if model not in (BASELINE, BASELINE_TRUE):
                ref = task_inputs(task, BASELINE, truth, preds[BASELINE])[1]
                rows.append(tasks.compare(task, model, split.name, t, q, ref, frames, resamples, seed))
    return rows


def describe(split, fitted):
    """Facts the report uses to explain results: sizes, class shares, label noise, distances."""
    tr = np.concatenate([c.cls[i] for c, i in split.train]) if split.train else np.empty(0, int)
    city, idx = split.test
    share = lambda y: (np.bincount(y, minlength=3) / max(len(y), 1)).tolist()
    return {"split": split.name, "kind": split.kind, "test_city": city.name,
            "n_train": int(len(tr)), "n_val": int(sum(len(i) for _, i in split.val)), "n_test": int(len(idx)),
            "n_test_receptions": int(len(split.test_rec[1])),
            "class_share_train": share(tr), "class_share_test": share(city.cls[idx]),
            "label_noise_test": float(np.mean(city.cls[idx] != city.los_geo[idx])) if len(idx) else None,
            "median_d_train": float(np.median(np.concatenate([c.d3[i] for c, i in split.train]))) if len(tr) else None,
            "median_d_test": float(np.median(city.d3[idx])) if len(idx) else None,
            "beyond_train_d": _beyond(split, city.d3[idx]), "models": fitted}


def _beyond(split, d_test):
    """Share of test links farther than the 99th percentile of the training distances: where a
    learned model extrapolates."""
    d_train = np.concatenate([c.d3[i] for c, i in split.train]) if split.train else np.empty(0)
    if not len(d_train) or not len(d_test):
        return None
    return float(np.mean(d_test > np.percentile(d_train, 99)))


def run_split(split, n_materials, budget_s, seed, resamples, log, threads=2):
    start = time.monotonic()
    city, idx = split.test
    rec_idx = split.test_rec[1]
    preds = {BASELINE: _baseline_predictions(city, idx, rec_idx, False),
             BASELINE_TRUE: _baseline_predictions(city, idx, rec_idx, True)}
    fitted = {}
    for m in learned_models(split, n_materials, seed, threads):
        t0 = time.monotonic()
        # gbdt may use the first 30 % of the split's budget, the cnn what is left.
        deadline = start + budget_s * (0.3 if m.name == "gbdt" else 1.0)
        preds[m.name] = _learned_predictions(m, split, deadline)
        fitted[m.name] = {"fit_s": round(time.monotonic() - t0, 1), "sigma_db": m.sigma,
                          "context": getattr(m, "use_context", True), "steps": getattr(m, "steps", None)}
        log(f"  {split.name}: {m.name} fitted in {fitted[m.name]['fit_s']} s")
    rows = score_split(split, preds, resamples, seed)
    return rows, preds, describe(split, fitted)


def run(cities, n_materials, max_train_s, seed=1, resamples=200, log=print, threads=2):
    """Every split: results rows, and per split (predictions, facts) for the report."""
    splits = make_splits(cities)
    budget = max_train_s / max(len(splits), 1)
    rows, per_split = [], []
    for split in splits:
        log(f"split {split.name}: {sum(len(i) for _, i in split.train)} train / "
            f"{sum(len(i) for _, i in split.val)} val / {len(split.test[1])} test links")
        r, preds, facts = run_split(split, n_materials, budget, seed, resamples, log, threads)
        rows += r
        per_split.append((split, preds, facts))
    return rows, per_split

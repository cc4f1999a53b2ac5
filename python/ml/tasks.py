"""The three benchmark tasks and their metrics.

(a) los_class: the LoS class by the first Fresnel zone (/links/los_class_fresnel: 0 LOS, 1 NLOSV,
    2 NLOS) of every link: macro-F1 and per-class recall.
(b) path_gain: the wideband path gain /links/gain_incoherent_db floored at the sensitivity floor
    (sensitivity - tx power; -inf without paths becomes the floor) of the links in range: RMSE and
    MAE in dB, overall, per true class and per 3-D distance bin.
(c) packet_decoded: whether an 802.11p reception of sinr/ray.h5 was decoded: accuracy (at 0.5) and
    Brier score of P(decoded).
Every metric comes with a 95 % frame-bootstrap interval (metrics.bootstrap).
"""
import numpy as np

from . import metrics as m

TASK_A, TASK_B, TASK_C = "los_class", "path_gain", "packet_decoded"
TASKS = (TASK_A, TASK_B, TASK_C)
# The headline metric of a task and its sense (+1: higher is better).
PRIMARY = {TASK_A: ("macro_f1", +1), TASK_B: ("rmse_db", -1), TASK_C: ("brier", -1)}


def _masked(stats, mask):
    """Stats of a subset with the other items zeroed, so frames stay aligned for the bootstrap."""
    return stats * np.asarray(mask, float)[:, None]


def metric_specs(task, truth, pred):
    """[(metric name, per-item stats, finisher)] of one task. truth/pred: dicts of arrays:
    a: truth cls, pred cls; b: truth gain, cls, d3, pred gain; c: truth decoded, pred p."""
    if task == TASK_A:
        s = m.confusion_stats(truth["cls"], pred["cls"])
        return [("macro_f1", s, m.macro_f1)] + [(f"recall_{n}", s, m.recall(i)) for i, n in enumerate(m.CLASS_NAMES)]
    if task == TASK_B:
        s = m.error_stats(truth["gain"], pred["gain"])
        specs = [("rmse_db", s, m.rmse), ("mae_db", s, m.mae)]
        for i, n in enumerate(m.CLASS_NAMES):
            part = _masked(s, truth["cls"] == i)
            specs += [(f"rmse_db_class_{n}", part, m.rmse), (f"mae_db_class_{n}", part, m.mae)]
        for lo, hi in m.DISTANCE_BINS:
            part = _masked(s, (truth["d3"] >= lo) & (truth["d3"] < hi))
            b = m.bin_name(lo, hi)
            specs += [(f"rmse_db_d_{b}", part, m.rmse), (f"mae_db_d_{b}", part, m.mae)]
        return specs
    s = m.probability_stats(truth["decoded"], pred["p"])
    return [("accuracy", s, m.accuracy), ("brier", s, m.brier)]


def score(task, model, split, truth, pred, frames, resamples=200, seed=1):
    """results.json rows of one (task, model, split)."""
    rows = []
    for name, stats, finish in metric_specs(task, truth, pred):
        value, lo, hi = m.bootstrap(stats, frames, finish, resamples, seed)
        rows.append({"task": task, "model": model, "split": split, "metric": name, "value": value,
                     "ci_low": lo, "ci_high": hi, "n": int(np.any(stats != 0, axis=1).sum())})
    return rows


def compare(task, model, split, truth, pred, ref_pred, frames, resamples=200, seed=1):
    """Row of the paired difference model - reference on the task's headline metric."""
    name, _ = PRIMARY[task]
    spec = {n: (s, f) for n, s, f in metric_specs(task, truth, pred)}
    ref = {n: s for n, s, _ in metric_specs(task, truth, ref_pred)}
    stats, finish = spec[name]
    value, lo, hi = m.bootstrap_delta(ref[name], stats, frames, finish, resamples, seed)
    return {"task": task, "model": model, "split": split, "metric": f"delta_{name}_vs_tr37885", "value": value,
            "ci_low": lo, "ci_high": hi, "n": int(np.any(stats != 0, axis=1).sum())}

"""Metrics with frame-bootstrap intervals.

Every metric is computed from per-item statistics summed over items (a confusion matrix, sums of
squared errors ...). Summing per frame first makes the bootstrap cheap and correct: a resample
draws frames with replacement (the links of a frame are correlated, so links are not independent
draws) and its statistics are the frame sums weighted by how often each frame was drawn.
"""
import warnings

import numpy as np

CLASS_NAMES = ("LOS", "NLOSV", "NLOS")
DISTANCE_BINS = ((0, 50), (50, 100), (100, 200), (200, 400), (400, np.inf))


def bin_name(lo, hi):
    return f"{lo:g}-{hi:g}" if np.isfinite(hi) else f"{lo:g}+"


# --- per-item statistics and their finishers ---------------------------------------------------

def confusion_stats(y, yhat, k=3):
    """(n, k*k) one-hot of the cell (true, predicted); summed it is the confusion matrix."""
    s = np.zeros((len(y), k * k))
    s[np.arange(len(y)), np.asarray(y, int) * k + np.asarray(yhat, int)] = 1.0
    return s


def _confusion(total):
    k = int(round(np.sqrt(total.shape[-1])))
    return total.reshape(total.shape[:-1] + (k, k))


def macro_f1(total):
    """Macro-F1 of summed confusion_stats; a class absent from truth and prediction is left out."""
    c = _confusion(total)
    tp = np.diagonal(c, axis1=-2, axis2=-1)
    support, predicted = c.sum(-1), c.sum(-2)
    denom = support + predicted
    with np.errstate(invalid="ignore", divide="ignore"):
        f1 = np.where(denom > 0, 2 * tp / denom, np.nan)
    with warnings.catch_warnings():  # all-NaN rows (no item at all) give NaN, as they should
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(f1, axis=-1)


def recall(cls):
    def finish(total):
        c = _confusion(total)
        support = c.sum(-1)[..., cls]
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(support > 0, c[..., cls, cls] / support, np.nan)
    return finish


def error_stats(y, yhat):
    """(n, 3): squared error, absolute error, 1."""
    e = np.asarray(yhat, float) - np.asarray(y, float)
    return np.stack([e * e, np.abs(e), np.ones_like(e)], axis=1)


def rmse(total):
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.sqrt(total[..., 0] / total[..., 2])


def mae(total):
    with np.errstate(invalid="ignore", divide="ignore"):
        return total[..., 1] / total[..., 2]


def probability_stats(y, p):
    """(n, 3): squared probability error, correct at 0.5, 1 (for Brier score and accuracy)."""
    y = np.asarray(y, float)
    p = np.asarray(p, float)
    return np.stack([(p - y) ** 2, ((p >= 0.5) == (y >= 0.5)).astype(float), np.ones_like(y)], axis=1)


def brier(total):
    with np.errstate(invalid="ignore", divide="ignore"):
        return total[..., 0] / total[..., 2]


def accuracy(total):
    with np.errstate(invalid="ignore", divide="ignore"):
        return total[..., 1] / total[..., 2]


# --- bootstrap ----------------------------------------------------------------------------------

def group_sums(stats, groups):
    """Statistics summed per group (frame): (G, k) for the G distinct groups."""
    _, inverse = np.unique(np.asarray(groups), return_inverse=True)
    out = np.zeros((inverse.max() + 1 if len(inverse) else 0, stats.shape[1]))
    np.add.at(out, inverse, stats)
    return out


def bootstrap_values(stats, groups, finish, resamples=200, seed=1):
    """finish() of `resamples` frame resamples: frames drawn with replacement, each bringing all its
    items (multinomial counts times the per-frame sums)."""
    per_group = group_sums(np.asarray(stats, float), groups)
    g = len(per_group)
    rng = np.random.default_rng(seed)
    counts = rng.multinomial(g, np.full(g, 1.0 / g), size=resamples)  # how often each frame is drawn
    return np.asarray(finish(counts @ per_group), float)


def bootstrap(stats, groups, finish, resamples=200, seed=1, level=0.95):
    """(value, ci_low, ci_high) of finish(sum of stats), the percentile interval of frame resamples;
    NaN interval with fewer than two frames."""
    stats = np.asarray(stats, float)
    value = float(finish(stats.sum(0))) if len(stats) else np.nan
    if len(np.unique(groups)) < 2 or not np.isfinite(value):
        return value, np.nan, np.nan
    values = bootstrap_values(stats, groups, finish, resamples, seed)
    values = values[np.isfinite(values)]  # a resample can miss every item of a class or bin
    if not len(values):
        return value, np.nan, np.nan
    a = (1 - level) / 2
    lo, hi = np.quantile(values, [a, 1 - a])
    return value, float(lo), float(hi)


def bootstrap_delta(stats_a, stats_b, groups, finish, resamples=200, seed=1, level=0.95):
    """finish(b) - finish(a) for two models scored on the same items, with a paired frame-bootstrap
    interval (the same resampled frames for both, so their shared difficulty cancels)."""
    k = stats_a.shape[1]
    both = np.concatenate([stats_a, stats_b], axis=1)
    diff = lambda total: finish(total[..., k:]) - finish(total[..., :k])
    return bootstrap(both, groups, diff, resamples, seed, level)

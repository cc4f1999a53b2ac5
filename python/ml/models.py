"""Learned models: gradient-boosted trees (gbdt) and a small multi-task CNN (cnn).

Both are fit on the training links of a split, stopped early on its validation links (never on the
test city), and predict the LoS class (a), the floored gain (b) and, for (c), P(decoded) by the
threshold rule: P = Phi((tx power + predicted gain - required power) / sigma), sigma the residual
spread learned on the validation receptions (the value minimising their Brier score), or the
validation gain RMSE where the validation windows hold fewer than MIN_VAL_RECEPTIONS receptions.

A part is a (City, row indices) pair; training sets are lists of parts (several cities).
"""
import time

import numpy as np
from scipy.special import ndtr

from . import context
from .data import SCALAR_FEATURES

MIN_VAL_RECEPTIONS = 50
SIGMAS = np.linspace(1.0, 20.0, 77)


def concat(parts, get):
    arrays = [get(c, idx) for c, idx in parts]
    return np.concatenate(arrays) if arrays else np.empty(0)


def excess(city, idx):
    """The learned models' gain target: the floored gain above free space (NaN out of range)."""
    return city.gain[idx] - city.prior[idx]


def balanced_weights(y, k=3):
    """Per-item weight n / (k n_class): macro-F1 counts every class alike, so should the loss."""
    counts = np.bincount(y, minlength=k).astype(float)
    w = len(y) / (k * np.maximum(counts, 1))
    return w[y]


def decode_probability(gain_db, tx_power_dbm, required_dbm, sigma):
    return ndtr((tx_power_dbm + gain_db - required_dbm) / max(sigma, 1e-6))


def fit_sigma(val_recs, val_gain_rmse):
    """sigma of the threshold rule: Brier-optimal on the validation receptions when they are enough.
    val_recs: (predicted gain, tx power, required, decoded) arrays."""
    gain, power, required, decoded = val_recs
    if len(decoded) < MIN_VAL_RECEPTIONS or not np.isfinite(val_gain_rmse):
        return float(val_gain_rmse) if np.isfinite(val_gain_rmse) else 6.0
    briers = [np.mean((decode_probability(gain, power, required, s) - decoded) ** 2) for s in SIGMAS]
    return float(SIGMAS[int(np.argmin(briers))])


def reception_parts(rec_parts):
    """(City, reception indices) parts -> (city, link rows) parts and the receptions' arrays;
    cities without a SINR file bring none."""
    rec_parts = [(c, i) for c, i in rec_parts if c.rec is not None and len(i)]
    rows = [(c, c.rec["row"][i]) for c, i in rec_parts]
    cols = [concat(rec_parts, lambda c, i, k=k: c.rec[k][i]) for k in ("tx_power_dbm", "required_dbm", "decoded")]
    return rows, cols


class Model:
    """Common part: the packet rule on top of a gain predictor."""

    name = "?"
    sigma = 6.0

    def fit_packet(self, val_parts, val_rec_parts):
        rows, (power, required, decoded) = reception_parts(val_rec_parts)
        gain = self.predict_parts(rows)["gain_db"] if len(decoded) else np.empty(0)
        truth = concat(val_parts, lambda c, i: c.gain[i])
        pred = self.predict_parts(val_parts)["gain_db"] if len(truth) else np.empty(0)
        ok = np.isfinite(truth)
        rmse = np.sqrt(np.mean((pred[ok] - truth[ok]) ** 2)) if ok.any() else np.nan
        self.sigma = fit_sigma((gain, power, required, decoded), rmse)

    def predict_packets(self, city, rec_idx):
        gain = self.predict_parts([(city, city.rec["row"][rec_idx])])["gain_db"]
        return decode_probability(gain, city.rec["tx_power_dbm"][rec_idx], city.rec["required_dbm"][rec_idx],
                                  self.sigma)

    def predict_parts(self, parts):
        outs = [self.predict(c, i) for c, i in parts]
        return {k: np.concatenate([o[k] for o in outs]) for k in ("proba", "cls", "gain_db")}


# --- gradient-boosted trees -------------------------------------------------------------------

class Constant:
    """Stands in for a tree model where the training set is degenerate (one class, no gains)."""

    def __init__(self, classes=(0,), value=0.0):
        self.classes_, self.value = np.asarray(classes, int), value

    def predict_proba(self, x):
        return np.ones((len(x), 1))

    def predict(self, x):
        return np.full(len(x), self.value)


def _val_log_loss(est, xv, yv, log_loss):
    """Balanced validation log loss over the classes the model knows (others cannot be scored)."""
    known = np.isin(yv, est.classes_)
    if not known.any():
        return 0.0
    return log_loss(yv[known], est.predict_proba(xv[known]), labels=est.classes_,
                    sample_weight=balanced_weights(yv[known]))


class Gbdt(Model):
    """sklearn HistGradientBoosting on the scalar inputs plus, with context, its aggregates
    (context.AGGREGATES). Trees are added 25 at a time (warm start) while the validation loss
    improves: early stopping on the validation window, not on a random share of the training
    links (neighbouring frames would leak)."""

    name = "gbdt"
    STEP, MAX_ITER, PATIENCE = 25, 400, 2

    def __init__(self, use_context, seed=1):
        self.use_context, self.seed = use_context, seed
        self.feature_names = SCALAR_FEATURES + (context.AGGREGATES if use_context else ())

    def inputs(self, city, idx):
        x = city.X[idx]
        return np.hstack([x, city.agg[idx]]) if self.use_context else x

    def _grow(self, est, x, y, w, score, deadline):
        """Warm-start growth; keeps the best validation score seen (est ends a few steps past it)."""
        best, since = np.inf, 0
        while est.max_iter == 0 or (est.max_iter < self.MAX_ITER and since < self.PATIENCE
                                    and time.monotonic() < deadline):  # at least one step
            est.max_iter += self.STEP
            est.fit(x, y, sample_weight=w)
            s = score(est)
            best, since = (s, 0) if s < best - 1e-6 else (best, since + 1)
        return est

    def fit(self, train, val, deadline):
        from sklearn.ensemble import HistGradientBoostingClassifier, HistGradientBoostingRegressor
        from sklearn.metrics import log_loss
        x, xv = concat(train, self.inputs), concat(val, self.inputs)
        y, yv = concat(train, lambda c, i: c.cls[i]), concat(val, lambda c, i: c.cls[i])
        # Gains relative to free space (data.free_space_gain_db): trees cannot extrapolate a trend.
        g, gv = concat(train, excess), concat(val, excess)
        common = dict(max_iter=0, warm_start=True, early_stopping=False, random_state=self.seed, max_leaf_nodes=31)
        # Half the time for the classifier: the regressor must get a turn before the deadline.
        half = time.monotonic() + (deadline - time.monotonic()) / 2
        if len(np.unique(y)) < 2:  # tiny runs: one class seen, nothing to separate
            self.clf = Constant(classes=np.unique(y) if len(y) else [0])
        else:
            self.clf = self._grow(HistGradientBoostingClassifier(**common), x, y, balanced_weights(y),
                                  lambda e: _val_log_loss(e, xv, yv, log_loss), half)
        ok, okv = np.isfinite(g), np.isfinite(gv)
        if ok.sum() < 2:
            self.reg = Constant(value=float(np.mean(g[ok])) if ok.any() else 0.0)
        else:
            self.reg = self._grow(HistGradientBoostingRegressor(**common), x[ok], g[ok], None,
                                  lambda e: np.mean((e.predict(xv[okv]) - gv[okv]) ** 2) if okv.any() else 0.0,
                                  deadline)
        return self

    def predict(self, city, idx):
        x = self.inputs(city, idx)
        if not len(x):
            return {"proba": np.empty((0, 3)), "cls": np.empty(0, int), "gain_db": np.empty(0)}
        proba = np.zeros((len(x), 3))
        proba[:, self.clf.classes_] = self.clf.predict_proba(x)  # a class absent in training stays 0
        gain = city.prior[idx] + self.reg.predict(x)
        return {"proba": proba, "cls": np.argmax(proba, 1), "gain_db": np.maximum(gain, city.floor_db)}


# --- CNN ----------------------------------------------------------------------------------------

def raster(city, idx, n_materials):
    """(n, channels, A, C) float32 input raster: building height (/10 m), building mask, material
    one-hot (no channel for "none"), tallest vehicle height (/3 m) and vehicle mask. Built per batch
    from the u8 arrays: a float raster of every link would not fit in memory."""
    g = city.grid
    h = city.ctx["height"][idx].astype(np.float32) * g["height_scale"]
    mat = city.ctx["material"][idx]
    veh = context.vehicle_raster(city.ctx["vehicles"][idx], city.d_centre[idx], (g["A"], g["C"]), g["W"])
    chans = [h / 10.0, (h > 0)] + [mat == k for k in range(1, n_materials)] + [veh / 3.0, veh > 0]
    return np.stack([np.asarray(c, np.float32) for c in chans], axis=1)


def scalar_inputs(city, idx):
    """Scalar inputs plus log10 distance (path loss is linear in it)."""
    x = city.X[idx]
    return np.hstack([x, np.log10(np.maximum(x[:, :1], 1.0))]).astype(np.float32)


def make_net(channels, n_scalars):
    import torch.nn as nn

    class Net(nn.Module):
        """Corridor raster (A x C) -> three conv layers (1/16 of the cells after the second) -> pooled
        to 4 along x 2 across (where along the link an obstacle stands matters); scalars through a
        small layer; a shared trunk; two heads."""

        def __init__(self):
            super().__init__()
            self.conv = nn.Sequential(
                # Strided and pooled early: it trains on 2 CPU cores within minutes.
                nn.Conv2d(channels, 16, 3, stride=2, padding=1), nn.ReLU(), nn.MaxPool2d(2, ceil_mode=True),
                nn.Conv2d(16, 32, 3, padding=1), nn.ReLU(), nn.MaxPool2d(2, ceil_mode=True),
                nn.Conv2d(32, 32, 3, padding=1), nn.ReLU(), nn.AdaptiveMaxPool2d((4, 2)), nn.Flatten())
            self.scalar = nn.Sequential(nn.Linear(n_scalars, 32), nn.ReLU())
            self.trunk = nn.Sequential(nn.Linear(32 * 8 + 32, 64), nn.ReLU())
            self.cls = nn.Linear(64, 3)
            self.gain = nn.Linear(64, 1)

        def forward(self, r, s):
            import torch
            z = self.trunk(torch.cat([self.conv(r), self.scalar(s)], dim=1))
            return self.cls(z), self.gain(z).squeeze(1)

    return Net()


class Cnn(Model):
    """Multi-task CNN: class logits (cross-entropy, balanced class weights) and the standardised
    floored gain above free space (squared error, links in range only), summed. Adam, fixed seeds, deterministic
    kernels, 2 threads; validation loss every EVAL_EVERY steps (at most once per epoch), the best
    weights kept, stops after PATIENCE evaluations without improvement or at the deadline."""

    name = "cnn"
    BATCH, LR, EVAL_EVERY, PATIENCE, MAX_VAL = 256, 2e-3, 200, 5, 20000

    def __init__(self, n_materials, seed=1, threads=2):
        self.n_materials, self.seed, self.threads = n_materials, seed, threads
        self.steps = 0

    def _batch(self, parts, flat):
        """Tensors of the items `flat` (rows of the concatenated parts)."""
        import torch
        offsets = np.cumsum([0] + [len(i) for _, i in parts])
        chunks = []
        for p, (c, idx) in enumerate(parts):
            sel = flat[(flat >= offsets[p]) & (flat < offsets[p + 1])] - offsets[p]
            if len(sel):
                rows = idx[sel]
                chunks.append((raster(c, rows, self.n_materials), scalar_inputs(c, rows), c.cls[rows],
                               excess(c, rows)))
        r, s, y, g = (np.concatenate(x) for x in zip(*chunks))
        s = np.clip(np.nan_to_num((s - self.s_mean) / self.s_std), -10, 10)  # far outside training: bounded
        ok = np.isfinite(g)
        g = np.where(ok, (g - self.g_mean) / self.g_std, 0.0)
        return (torch.from_numpy(r), torch.from_numpy(s.astype(np.float32)), torch.from_numpy(y),
                torch.from_numpy(g.astype(np.float32)), torch.from_numpy(ok.astype(np.float32)))

    def _loss(self, batch):
        import torch.nn.functional as F
        r, s, y, g, ok = batch
        logits, gain = self.net(r, s)
        mse = ((gain - g) ** 2 * ok).sum() / ok.sum().clamp(min=1.0)
        return F.cross_entropy(logits, y, weight=self.class_w) + mse

    def _standardise(self, train):
        import torch
        s = concat(train, scalar_inputs)
        # A constant input in training (one vehicle class, say) is only centred: dividing by ~0
        # would blow up the values another city brings.
        self.s_mean, std = s.mean(0), s.std(0)
        self.s_std = np.where(std > 1e-3, std, 1.0)
        g = concat(train, excess)
        g = g[np.isfinite(g)]
        self.g_mean, self.g_std = (g.mean(), g.std() + 1e-6) if len(g) else (0.0, 1.0)
        y = concat(train, lambda c, i: c.cls[i]).astype(int)
        counts = np.bincount(y, minlength=3).astype(float)
        self.class_w = torch.tensor(len(y) / (3 * np.maximum(counts, 1)), dtype=torch.float32)

    def _val_loss(self, val, order):
        import torch
        with torch.no_grad():
            total = [float(self._loss(self._batch(val, order[b:b + 1024]))) * len(order[b:b + 1024])
                     for b in range(0, len(order), 1024)]
        return sum(total) / max(len(order), 1)

    def fit(self, train, val, deadline):
        import torch
        # 2 by default; on a loaded machine 1 thread can be several times faster (spinning threads).
        torch.set_num_threads(self.threads)
        torch.manual_seed(self.seed)
        torch.use_deterministic_algorithms(True)
        rng = np.random.default_rng(self.seed)
        self._standardise(train)
        self.net = make_net(4 + self.n_materials - 1, len(SCALAR_FEATURES) + 1)
        opt = torch.optim.Adam(self.net.parameters(), lr=self.LR)
        n, n_val = sum(len(i) for _, i in train), sum(len(i) for _, i in val)
        val_order = np.sort(rng.permutation(n_val)[:self.MAX_VAL])
        best, best_state, bad = np.inf, None, 0
        eval_every = max(1, min(self.EVAL_EVERY, -(-n // self.BATCH)))
        while time.monotonic() < deadline and bad < self.PATIENCE:
            perm = rng.permutation(n)
            for b in range(0, n, self.BATCH):
                self.net.train()
                loss = self._loss(self._batch(train, perm[b:b + self.BATCH]))
                opt.zero_grad()
                loss.backward()
                opt.step()
                self.steps += 1
                if self.steps % eval_every == 0 and n_val:
                    self.net.eval()
                    v = self._val_loss(val, val_order)
                    best, bad = (v, 0) if v < best - 1e-4 else (best, bad + 1)
                    if bad == 0:
                        best_state = {k: t.clone() for k, t in self.net.state_dict().items()}
                if bad >= self.PATIENCE or time.monotonic() >= deadline:
                    break
        if best_state is not None:
            self.net.load_state_dict(best_state)
        self.net.eval()
        return self

    def predict(self, city, idx):
        import torch
        idx = np.asarray(idx)
        parts = [(city, idx)]
        out_p, out_g = [], []
        with torch.no_grad():
            for b in range(0, len(idx), 1024):
                r, s, _, _, _ = self._batch(parts, np.arange(b, min(b + 1024, len(idx))))
                logits, gain = self.net(r, s)
                out_p.append(torch.softmax(logits, 1).numpy())
                out_g.append(gain.numpy() * self.g_std + self.g_mean + city.prior[idx[b:b + 1024]])
        proba = np.concatenate(out_p) if out_p else np.empty((0, 3))
        gain = np.concatenate(out_g) if out_g else np.empty(0)
        return {"proba": proba.astype(float), "cls": np.argmax(proba, 1) if len(proba) else np.empty(0, int),
                "gain_db": np.maximum(gain.astype(float), city.floor_db)}

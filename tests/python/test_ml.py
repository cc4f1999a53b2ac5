#!/usr/bin/python3
"""Checks python/ml (the ML benchmark): TR 37.885 formulas, metrics, the frame bootstrap,
a CNN training step, features.h5 reading, and the whole pipeline on two tiny synthetic cities.

usage: test_ml.py [DATASET.h5]   (optional: a small channel dataset, e.g. the one of
tests/generators/test_dataset.cpp, to check a features.h5 written for it reads back aligned)
Run with PYTHONPATH=python (test_reader.py and ml_fixture.py are found next to this file).
Exits 0 when every check passes; prints the failures and exits 1 otherwise.
"""
import io
import json
import os
import sys
import tempfile
from contextlib import redirect_stderr, redirect_stdout

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "python"))

import ml_fixture  # noqa: E402
from ml import baselines, context, metrics, models  # noqa: E402
from test_reader import check, report  # noqa: E402

REQUIRED_KEYS = {"task", "model", "split", "metric", "value", "ci_low", "ci_high"}


def near(a, b, tol=1e-3):
    return abs(float(a) - float(b)) <= tol


def test_tr37885():
    # Hand-computed from TR 37.885 Tables 6.2-1 and 6.2.1-1 (log10 5.9 = 0.770852).
    check(near(baselines.pathloss_db("urban", 0, 100.0, 5.9e9), 38.77 + 33.4 + 18.2 * 0.770852),
          "urban LOS path loss at 100 m, 5.9 GHz = 86.1995 dB")
    check(near(baselines.pathloss_db("urban", 2, 100.0, 5.9e9), 96.85 + 18.9 * 0.770852), "NLOS at 100 m = 111.419 dB")
    check(near(baselines.pathloss_db("highway", 0, 100.0, 5.9e9), 72.4 + 20 * 0.770852), "highway LOS at 100 m")
    check(near(baselines.pathloss_db("urban", 1, 100.0, 5.9e9), 86.1995), "NLOSV path loss = LOS before blockage")
    p = baselines.p_los("urban", np.array([50.0, 200.0]))
    check(near(p[0], 0.593802) and near(p[1], 0.107398), f"urban P_LOS at 50/200 m {p}")
    p = baselines.p_los("highway", np.array([100.0, 600.0]))
    check(near(p[0], 0.840313) and near(p[1], 0.415), f"highway P_LOS at 100/600 m {p}")
    probs = baselines.class_probabilities("urban", [100.0])[0]
    check(near(probs[0], 0.335810) and near(probs[2], 0.300175) and near(probs.sum(), 1.0), f"urban states {probs}")
    check(near(baselines.class_probabilities("highway", [100.0])[0][2], 0.0), "highway has no NLOS state")
    mu, sigma = baselines.nlosv_blockage(np.array([100.0, 1000.0]))
    check(near(mu[0], 9.0) and near(mu[1], 13.0) and near(sigma[0], 4.5), f"NLOSV blockage {mu} {sigma}")
    mu, _ = baselines.nlosv_blockage(np.array([100.0]), 2.0, 2.0, 1.6)
    check(near(mu[0], 0.0), "no blockage with both antennas above the blocker")
    p = baselines.decode_probability(np.array([[-80.0]]), np.array([[3.0]]), np.ones((1, 1)), [20.0], [-60.0])
    check(near(p[0], 0.5), "P(decoded) is 0.5 at zero margin")


def test_metrics():
    y, yhat = np.array([0, 0, 0, 1, 1, 2]), np.array([0, 0, 1, 1, 2, 2])
    total = metrics.confusion_stats(y, yhat).sum(0)
    check(near(metrics.macro_f1(total), (0.8 + 0.5 + 2 / 3) / 3), f"macro-F1 {metrics.macro_f1(total)}")
    check(near(metrics.recall(0)(total), 2 / 3), "recall LOS 2/3")
    s = metrics.probability_stats([1, 0, 1, 1], [0.9, 0.2, 0.6, 1.0]).sum(0)
    check(near(metrics.brier(s), 0.0525) and near(metrics.accuracy(s), 1.0), f"Brier {metrics.brier(s)}")
    s = metrics.error_stats([0, 0, 0], [1, -2, 3]).sum(0)
    check(near(metrics.rmse(s), np.sqrt(14 / 3)) and near(metrics.mae(s), 2.0), f"RMSE {metrics.rmse(s)}")


def test_bootstrap():
    # Frame 0: 8 links with error 0, frame 1: 2 links with error 10. Resampling frames can only
    # give RMSE of {0 0}, {0 1} or {1 1}; resampling links would give many other values.
    err = np.array([0.0] * 8 + [10.0] * 2)
    stats = metrics.error_stats(np.zeros(10), err)
    frames = np.array([0] * 8 + [1] * 2)
    values = metrics.bootstrap_values(stats, frames, metrics.rmse, 200, seed=3)
    allowed = np.array([0.0, np.sqrt(200 / 10), 10.0])
    check(np.all(np.min(np.abs(values[:, None] - allowed[None, :]), axis=1) < 1e-9), "bootstrap resamples frames")
    rng = np.random.default_rng(0)
    frames = np.repeat(np.arange(30), 20)
    stats = metrics.error_stats(np.zeros(600), rng.normal(0, 2, 600) + frames % 3)
    v, lo, hi = metrics.bootstrap(stats, frames, metrics.rmse, 200, seed=1)
    check(lo <= v <= hi and hi > lo, f"interval [{lo}, {hi}] holds the estimate {v}")
    again = metrics.bootstrap(stats, frames, metrics.rmse, 200, seed=1)
    check(again == (v, lo, hi), "bootstrap is reproducible with a fixed seed")


def test_training_step():
    import torch
    torch.manual_seed(0)
    cnn = models.Cnn(n_materials=3, seed=0, threads=1)
    cnn.net = models.make_net(4 + 2, 5)
    cnn.class_w = torch.ones(3)
    rng = np.random.default_rng(0)
    y = rng.integers(0, 3, 32)
    r = rng.random((32, 6, 8, 4)).astype(np.float32)
    r[:, 0] += y[:, None, None]  # learnable: the class shows in channel 0
    batch = (torch.from_numpy(r), torch.from_numpy(rng.normal(size=(32, 5)).astype(np.float32)), torch.from_numpy(y),
             torch.from_numpy(y.astype(np.float32)), torch.ones(32))
    opt = torch.optim.Adam(cnn.net.parameters(), lr=1e-2)
    first = float(cnn._loss(batch))
    for _ in range(15):
        loss = cnn._loss(batch)
        opt.zero_grad()
        loss.backward()
        opt.step()
    check(float(cnn._loss(batch)) < first, f"training lowers the loss ({first:.3f} -> {float(cnn._loss(batch)):.3f})")


def run_cli(argv):
    """python -m ml in-process: (exit status, stderr text)."""
    from ml.__main__ import main
    err = io.StringIO()
    with redirect_stdout(io.StringIO()), redirect_stderr(err):
        try:
            rc = main(argv)
        except SystemExit as e:
            rc = e.code
    return rc, err.getvalue()


def test_pipeline(tmp):
    a = ml_fixture.make_run_dir(os.path.join(tmp, "a"), seed=0)
    # b: another grid (like the C++ CLI test's 16 x 4) and no SINR file.
    b = ml_fixture.make_run_dir(os.path.join(tmp, "b"), seed=1, with_sinr=False, nodes=4, grid=(16, 4))
    out = os.path.join(tmp, "out")
    rc, err = run_cli(["--city", f"a={a}", "--city", f"b={b}", "--out", out, "--max-train-s", "4",
                       "--resamples", "20", "--threads", "1"])
    check(rc == 0, f"pipeline exit {rc}: {err[-2000:]}")
    if rc != 0:
        return
    rows = json.load(open(os.path.join(out, "results.json")))
    check(len(rows) > 0 and all(REQUIRED_KEYS <= set(r) for r in rows), "results.json rows have the required keys")
    splits = {r["split"] for r in rows}
    check(splits == {"a", "b", "a:time", "b:time"}, f"splits {splits}")
    have = {(r["task"], r["model"]) for r in rows}
    for task in ("los_class", "path_gain", "packet_decoded"):
        for model in ("tr37885", "gbdt", "cnn"):
            check((task, model) in have, f"no rows for {task} / {model}")
    cnn_splits = {r["split"] for r in rows if r["model"] == "cnn"}
    check(cnn_splits == {"a:time", "b:time"}, f"cnn only where the grids agree: {cnn_splits}")
    check(not any(r["task"] == "packet_decoded" and r["split"] in ("b", "b:time") for r in rows),
          "task (c) skipped for the city without sinr/ray.h5")
    check({"recall_NLOSV", "rmse_db_class_LOS", "rmse_db_d_50-100"} <= {r["metric"] for r in rows},
          "per-class and per-bin metrics")
    check(os.path.isfile(os.path.join(out, "report.md")) and os.path.isfile(os.path.join(out, "confusion_a.png")),
          "report.md and figures written")
    check(not [f for f in os.listdir(out) if f.startswith(".")], "no temporary files left")
    rc, err = run_cli(["--city", f"x={os.path.join(tmp, 'missing')}", "--out", out])
    check(rc == 2 and "missing" in err and "dataset.h5" in err and len(err.strip().splitlines()) == 1,
          f"a missing input: exit {rc}, one line naming the file: {err!r}")


def test_features_of(dataset, tmp):
    """features.h5 written for a given dataset (every second frame) reads back aligned."""
    path = os.path.join(tmp, "features.h5")
    ml_fixture.write_features(dataset, path, stride=2)
    import raysweep_dataset as rd
    with rd.open_dataset(dataset) as ds:
        ff = context.FeatureFile(path, ds.link_count)
        frames = ds._column("links/frame")
        check(np.all(frames[ff.links] % 2 == 0) and len(ff.links) == int(np.sum(frames % 2 == 0)), "stride rows")
        got = ff.read(np.arange(len(ff.links))[::-1][::-1])
        check(got["height"].shape == (len(ff.links), ff.A, ff.C), "corridor shape")
        agg = context.aggregates(got, ff.height_scale, ff.W)
        check(agg.shape == (len(ff.links), len(context.AGGREGATES)) and np.all(np.isfinite(agg)), "aggregates")
        ff.close()
        try:
            context.FeatureFile(path, ds.link_count + 1)
            check(False, "features of another dataset accepted")
        except ValueError as e:
            check(path in str(e) and "dataset_link_count" in str(e), f"message {e}")


def main():
    tests = [test_tr37885, test_metrics, test_bootstrap, test_training_step]
    for t in tests:
        t()
    with tempfile.TemporaryDirectory() as tmp:
        test_pipeline(tmp)
        if len(sys.argv) > 1:
            test_features_of(sys.argv[1], tmp)
    return report()


if __name__ == "__main__":
    sys.exit(main())

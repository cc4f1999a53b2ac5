"""report.md and its figures: headline tables, verdicts against tr37885, explanations, PNGs."""
import os
import tempfile

import numpy as np

from . import metrics, tasks
from .pipeline import BASELINE, BASELINE_TRUE, truth_of

LEARNED = ("gbdt", "cnn")
TASK_TITLE = {tasks.TASK_A: "(a) LoS class (first Fresnel zone)", tasks.TASK_B: "(b) wideband path gain",
              tasks.TASK_C: "(c) 802.11p packet decoded"}


def _row(rows, task, model, split, metric):
    for r in rows:
        if (r["task"], r["model"], r["split"], r["metric"]) == (task, model, split, metric):
            return r
    return None


def _fmt(r, digits=3):
    if r is None or r["value"] is None or not np.isfinite(r["value"]):
        return "n/a"
    if r["ci_low"] is None or not np.isfinite(r["ci_low"]):
        return f"{r['value']:.{digits}f}"
    return f"{r['value']:.{digits}f} [{r['ci_low']:.{digits}f}, {r['ci_high']:.{digits}f}]"


def held_out(per_split):
    """The splits the verdicts are about: held-out cities, or the time splits with one city."""
    city = [s for s in per_split if s[0].kind == "city"]
    return city or per_split


def verdict(rows, task, model, split):
    """(word, sentence) of model against tr37885 on the task's headline metric."""
    name, sense = tasks.PRIMARY[task]
    d = _row(rows, task, model, split, f"delta_{name}_vs_tr37885")
    if d is None or d["value"] is None or not np.isfinite(d["value"]):
        return "n/a", "not scored"
    lo, hi = d["ci_low"], d["ci_high"]
    better = d["value"] * sense > 0
    significant = lo is not None and np.isfinite(lo) and (lo > 0 or hi < 0)
    word = ("beats" if better else "is worse than") if significant else "does not significantly differ from"
    return word, f"{model} {word} tr37885: {name} difference {_fmt(d)} ({model} - tr37885)"


def _shares(s):
    return ", ".join(f"{n} {100 * v:.0f} %" for n, v in zip(metrics.CLASS_NAMES, s))


def explain(rows, task, model, split, facts, truth):
    """Bullets of measured facts that bear on a model not beating the baseline."""
    out = [f"training volume: {facts['n_train']} links (validation {facts['n_val']}), test {facts['n_test']}"]
    if task == tasks.TASK_A:
        out.append(f"class balance: train {_shares(facts['class_share_train'])}; "
                   f"test {_shares(facts['class_share_test'])}")
        recalls = {n: _row(rows, task, model, split, f"recall_{n}") for n in metrics.CLASS_NAMES}
        worst = min(recalls, key=lambda n: (recalls[n] or {}).get("value") or 0)
        out.append(f"weakest class of {model}: {worst} (recall {_fmt(recalls[worst])})")
    if task == tasks.TASK_B:
        gaps = []
        for n in metrics.CLASS_NAMES:
            a, b = (_row(rows, task, m, split, f"rmse_db_class_{n}") for m in (model, BASELINE))
            if a and b and a["value"] is not None and b["value"] is not None:
                gaps.append((a["value"] - b["value"], n))
        if gaps:
            g, n = max(gaps)
            out.append(f"largest RMSE excess over tr37885 in class {n}: {g:+.1f} dB")
    if task == tasks.TASK_C and truth["decoded"] is not None:
        share = float(np.mean(truth["decoded"]))
        out.append(f"{100 * share:.1f} % of the test receptions were decoded: always predicting the majority "
                   f"scores accuracy {max(share, 1 - share):.3f}, Brier {share * (1 - share):.3f} at the base rate")
        out.append(f"{model}'s residual sigma for the threshold rule: {facts['models'][model]['sigma_db']:.1f} dB")
    if facts["label_noise_test"] is not None:
        # Not noise in the labels themselves: how far the class hinges on the Fresnel zone's margin,
        # which no input places to a metre.
        out.append(f"label ambiguity: the Fresnel label differs from the direct ray's (geometric los_class) on "
                   f"{100 * facts['label_noise_test']:.1f} % of the test links")
    if facts["median_d_train"] is not None:
        out.append(f"distance shift: median 3-D distance train {facts['median_d_train']:.0f} m, "
                   f"test {facts['median_d_test']:.0f} m; {100 * facts['beyond_train_d']:.1f} % of the test links "
                   f"lie beyond the 99th percentile of the training distances")
    if not facts["models"][model]["context"]:
        out.append("no context features in this split (a city lacks features.h5)")
    return out


def headline_table(rows, split, models):
    lines = ["| task | metric | " + " | ".join(models) + " |", "|---|---|" + "---|" * len(models)]
    for task in tasks.TASKS:
        name, _ = tasks.PRIMARY[task]
        second = {tasks.TASK_A: "recall_NLOSV", tasks.TASK_B: "mae_db", tasks.TASK_C: "accuracy"}[task]
        for metric in (name, second):
            cells = [_fmt(_row(rows, task, m, split, metric)) for m in models]
            if any(c != "n/a" for c in cells):
                lines.append(f"| {task} | {metric} | " + " | ".join(cells) + " |")
    return lines


def _save(fig, path):
    """Saved under a temporary name and renamed: a reader never sees half a PNG."""
    fd, tmp = tempfile.mkstemp(prefix=".fig.", suffix=".png", dir=os.path.dirname(path))
    os.close(fd)
    fig.savefig(tmp, dpi=110)
    os.replace(tmp, path)


def _plot_confusions(plt, path, truth, preds, models):
    fig, axes = plt.subplots(1, len(models), figsize=(3.6 * len(models), 3.4), squeeze=False)
    for ax, m in zip(axes[0], models):
        c = metrics.confusion_stats(truth["cls"], preds[m]["cls"]).sum(0).reshape(3, 3)
        norm = c / np.maximum(c.sum(1, keepdims=True), 1)
        ax.imshow(norm, vmin=0, vmax=1, cmap="Blues")
        for i in range(3):
            for j in range(3):
                ax.text(j, i, f"{norm[i, j]:.2f}\n{int(c[i, j])}", ha="center", va="center", fontsize=8,
                        color="white" if norm[i, j] > 0.6 else "black")
        ax.set_xticks(range(3), metrics.CLASS_NAMES)
        ax.set_yticks(range(3), metrics.CLASS_NAMES)
        ax.set_title(m)
        ax.set_xlabel("predicted")
    axes[0][0].set_ylabel("true (Fresnel)")
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)


def _plot_scatter(plt, path, truth, preds, models, seed=1):
    ok = np.nonzero(np.isfinite(truth["gain"]))[0]
    pick = np.sort(np.random.default_rng(seed).permutation(ok)[:20000])  # readable and small
    fig, axes = plt.subplots(1, len(models), figsize=(3.6 * len(models), 3.6), squeeze=False, sharey=True)
    lo, hi = (np.min(truth["gain"][ok]), np.max(truth["gain"][ok])) if len(ok) else (-150, -40)
    for ax, m in zip(axes[0], models):
        ax.scatter(truth["gain"][pick], preds[m]["gain_db"][pick], s=2, alpha=0.3, c=truth["cls"][pick],
                   cmap="viridis", vmin=0, vmax=2)
        ax.plot([lo, hi], [lo, hi], "k--", lw=0.8)
        ax.set_title(m)
        ax.set_xlabel("traced gain (dB)")
    axes[0][0].set_ylabel("predicted gain (dB)")
    fig.suptitle("colour: true class (purple LOS, teal NLOSV, yellow NLOS); dashed: y = x", fontsize=9)
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)


def _plot_distance(plt, path, rows, split, models):
    fig, ax = plt.subplots(figsize=(6, 3.6))
    names = [metrics.bin_name(lo, hi) for lo, hi in metrics.DISTANCE_BINS]
    x = np.arange(len(names))
    for k, m in enumerate(models):
        rs = [_row(rows, tasks.TASK_B, m, split, f"rmse_db_d_{n}") for n in names]
        v = np.array([np.nan if r is None or r["value"] is None else r["value"] for r in rs], float)
        lo = np.array([np.nan if r is None or r["ci_low"] is None else r["ci_low"] for r in rs], float)
        hi = np.array([np.nan if r is None or r["ci_high"] is None else r["ci_high"] for r in rs], float)
        err = np.nan_to_num(np.vstack([v - lo, hi - v]))
        ax.errorbar(x + 0.08 * (k - len(models) / 2), v, yerr=err, marker="o", capsize=3, label=m)
    ax.set_xticks(x, [n + " m" for n in names])
    ax.set_ylabel("gain RMSE (dB)")
    ax.set_title(f"error vs distance, {split}")
    ax.legend(fontsize=8)
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)


def figures(out, rows, per_split):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    made = {}
    for split, preds, _ in held_out(per_split):
        stem = split.name.replace(":", "_")
        truth = truth_of(split)
        models = [m for m in (BASELINE, BASELINE_TRUE) + LEARNED if m in preds]
        names = [f"confusion_{stem}.png", f"gain_scatter_{stem}.png", f"error_vs_distance_{stem}.png"]
        _plot_confusions(plt, os.path.join(out, names[0]), truth, preds, [m for m in models if m != BASELINE_TRUE])
        _plot_scatter(plt, os.path.join(out, names[1]), truth, preds, models)
        _plot_distance(plt, os.path.join(out, names[2]), rows, split.name, models)
        made[split.name] = names
    return made


def _data_section(cities):
    lines = ["## Data", "",
             "| city | scenario | links in dataset | links used | sampled | 802.11p receptions | context |",
             "|---|---|---|---|---|---|---|"]
    for c in cities:
        n_rec = "absent" if c.rec is None else str(len(c.rec["row"]))
        lines.append(f"| {c.name} | {c.scenario} | {c.link_total} | {len(c.rows)} | {int(c.in_sample.sum())} | "
                     f"{n_rec} | {'features.h5' if c.ctx is not None else 'none'} |")
    notes = [f"- {c.name}: {n}" for c in cities for n in c.notes]
    return lines + ([""] + notes if notes else []) + [""]


def _verdict_section(rows, per_split):
    lines = ["## Learned models against tr37885 (held-out data)", "",
             "Headline metric per task: macro-F1 (higher is better), gain RMSE and Brier score (lower is "
             "better). Differences are paired: the same bootstrap resamples of frames for both models, "
             "95 % interval; a difference counts only when its interval excludes 0.", ""]
    for split, preds, facts in held_out(per_split):
        lines += [f"### {split.name}", ""]
        truth = truth_of(split)
        for task in tasks.TASKS:
            for m in LEARNED:
                if m not in preds:
                    continue
                word, sentence = verdict(rows, task, m, split.name)
                if word == "n/a":
                    continue
                lines.append(f"- {TASK_TITLE[task]}: {sentence}.")
                if word != "beats":
                    lines += [f"  - {b}" for b in explain(rows, task, m, split.name, facts, truth)]
        skipped = [m for m in LEARNED if m not in preds]
        if skipped:
            lines.append(f"- not run here: {', '.join(skipped)} (needs features.h5 with one grid in every city)")
        lines.append("")
    return lines


def write(out, cities, rows, per_split, args, runtime_s):
    made = figures(out, rows, per_split)
    lines = ["# raysweep ML benchmark (issue 40)", "",
             f"Cities: {', '.join(n + ' = ' + p for n, p in args['cities'])}. Seed {args['seed']}, training "
             f"budget {args['max_train_s']:.0f} s over all splits, at most {args['max_links']} links per city "
             f"(a deterministic uniform subsample shared by every split), {args['resamples']} bootstrap "
             f"resamples of frames. Runtime {runtime_s:.0f} s. Numbers: value [95 % interval].", ""]
    lines += _data_section(cities) + _verdict_section(rows, per_split)
    lines += ["## All splits", ""]
    for split, preds, facts in per_split:
        models = [m for m in (BASELINE, BASELINE_TRUE) + LEARNED if m in preds]
        fitted = ", ".join(f"{m} {v['fit_s']} s" + (f" ({v['steps']} steps)" if v["steps"] else "")
                           for m, v in facts["models"].items())
        lines += [f"### {split.name} ({'held-out city' if split.kind == 'city' else 'time split'})", "",
                  f"train {facts['n_train']} / val {facts['n_val']} / test {facts['n_test']} links, "
                  f"{facts['n_test_receptions']} test receptions; fit and predict: {fitted or 'none'}", ""]
        lines += headline_table(rows, split.name, models) + [""]
    for split_name, names in made.items():
        lines += [f"### Figures, {split_name}", ""] + [f"![{n}]({n})" for n in names] + [""]
    lines += ["Every metric, per class and per distance bin, is in results.json; python/ml/README.md "
              "describes the tasks, models and rows.", ""]
    fd, tmp = tempfile.mkstemp(prefix=".report.", dir=out)
    with os.fdopen(fd, "w") as f:
        f.write("\n".join(lines))
    os.replace(tmp, os.path.join(out, "report.md"))


def summary(rows, per_split):
    """A few lines for the terminal: the headline metric per held-out split, task and model."""
    out = []
    for split, preds, _ in held_out(per_split):
        for task in tasks.TASKS:
            name, _ = tasks.PRIMARY[task]
            cells = [f"{m} {_fmt(_row(rows, task, m, split.name, name), 3)}" for m in preds
                     if _row(rows, task, m, split.name, name)]
            if cells:
                out.append(f"{split.name} {task} {name}: " + "; ".join(cells))
    return "\n".join(out)

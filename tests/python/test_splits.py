#!/usr/bin/python3
"""Checks the splits of python/raysweep_dataset.py: time windows that share no frame and lie at
least the gap apart, leave-one-city-out rotations, and LinkDataset restricted to a split's frames.

usage: test_splits.py DATASET.h5   (the 3-frame file of tests/generators/test_dataset.cpp)
Exits 0 when every check passes; prints the failures and exits 1 otherwise.
"""
import sys

import numpy as np

import raysweep_dataset as rd
from test_reader import check, report


def windows_ok(times, splits, gap_s, what):
    seen = np.concatenate(list(splits.values()))
    check(len(seen) == len(np.unique(seen)), f"{what}: a frame in two splits")
    spans = [(times[f].min(), times[f].max()) for f in splits.values() if len(f)]
    for (_, end), (start, _) in zip(spans, spans[1:]):
        check(start - end >= gap_s - 1e-9, f"{what}: windows {start - end:.3f} s apart, under {gap_s} s")


def main():
    # 60 s at 10 Hz, handed over in shuffled order: indices refer to that order.
    rng = np.random.default_rng(3)
    times = 60 + 0.1 * np.arange(600)
    order = rng.permutation(600)
    shuffled = times[order]
    splits = rd.time_splits(shuffled, (0.7, 0.15, 0.15), gap_s=1.0)
    windows_ok(shuffled, splits, 1.0, "10 Hz")
    check(list(splits) == ["train", "val", "test"], f"names {list(splits)}")
    # 59.9 s less two 1-s gaps = 57.9 s: train 40.53 s, val and test 8.685 s each.
    n = {k: len(v) for k, v in splits.items()}
    check(abs(n["train"] - 406) <= 1 and abs(n["val"] - 87) <= 1 and abs(n["test"] - 87) <= 1, f"sizes {n}")
    check(600 - sum(n.values()) in (19, 20, 21), f"{600 - sum(n.values())} frames in the gaps")
    check(shuffled[splits["train"]].max() < shuffled[splits["val"]].min(), "train before val")
    # No gap: every frame in exactly one split.
    whole = rd.time_splits(times, (1, 1), gap_s=0, names=("a", "b"))
    check(sorted(np.concatenate(list(whole.values())).tolist()) == list(range(600)), "gap 0 covers every frame")
    try:
        rd.time_splits(0.1 * np.arange(21), gap_s=1.0)  # 2 s cannot hold three windows 1 s apart
        check(False, "a sweep too short for the gaps was split")
    except ValueError as e:
        check("cannot hold 3 windows" in str(e), f"message {e}")
    rot = rd.city_rotations(["demo", "ring", "badhersfeld"])
    check(len(rot) == 3 and all(held not in train and len(train) == 2 for train, held in rot), f"rotations {rot}")

    # A split's links in the dataset.
    path = sys.argv[1]
    with rd.open_dataset(path) as ds:
        check(ds.links_of_frames([2]).tolist() == [5], f"links of frame 2 {ds.links_of_frames([2])}")
        check(ds.links_of_frames([1, 0]).tolist() == [0, 1, 2, 3, 4], "links of frames 0 and 1")
    a = rd.LinkDataset(path, frames=[0])
    b = rd.LinkDataset(path, frames=[1, 2])
    check(len(a) == 3 and len(b) == 3, f"split sizes {len(a)}, {len(b)}")
    check(set(a.link_index.tolist()).isdisjoint(b.link_index.tolist()), "a link in two splits")
    return report()


if __name__ == "__main__":
    sys.exit(main())

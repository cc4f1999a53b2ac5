#!/usr/bin/python3
"""Summary of a raysweep channel dataset, optionally a plot of path gain vs distance by LoS class.

usage: example_dataset.py FILE [--png OUT.png]
Needs numpy, h5py and (for --png) matplotlib; run with /usr/bin/python3 on Debian.
"""
import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from raysweep_dataset import FLAG_CACHED, FLAG_ENCLOSED, FLAG_OUT_OF_RANGE, LOS_CLASSES, open_dataset  # noqa: E402

COLORS = {0: "#2a9d8f", 1: "#e9c46a", 2: "#e76f51"}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file")
    ap.add_argument("--png", help="write a plot of coherent path gain vs distance, coloured by LoS class")
    args = ap.parse_args()

    with open_dataset(args.file) as ds:
        attrs = ds.attrs
        links = ds.links_table()
        nodes = ds.nodes
        times = ds.times
        distance = ds.link_distances()
        print(f"file          {args.file}{'' if ds.complete else '  (INCOMPLETE)'}")
        print(f"schema        {attrs['schema_version']}, raysweep {attrs.get('raysweep_version', '?')} "
              f"({attrs.get('git_hash', '?')})")
        span = f" ({times[0]:.3f} s .. {times[-1]:.3f} s)" if len(times) else ""
        print(f"frames        {ds.frame_count}{span}")
        vehicles = int(np.sum(nodes["kind"] == 0))
        print(f"nodes         {len(nodes)} ({vehicles} vehicles, {len(nodes) - vehicles} RSUs)")
        n = ds.link_count
        cached = int(np.sum(links["flags"] & FLAG_CACHED != 0))
        oor = int(np.sum(links["flags"] & FLAG_OUT_OF_RANGE != 0))
        enclosed = int(np.sum(links["flags"] & FLAG_ENCLOSED != 0))
        print(f"links         {n} ({cached} cached, {oor} out of range, {enclosed} with an antenna inside a building)")
        print(f"paths         {ds.path_count} ({ds.path_count / max(n, 1):.2f} per link)")
        print(f"cfr           {'yes' if ds.has_cfr else 'no'}")
        print("LoS class     share     median coherent gain (links with paths)")
        gain = links["gain_coherent_db"]
        for code, name in LOS_CLASSES.items():
            sel = links["los_class"] == code
            finite = sel & np.isfinite(gain)
            share = 100.0 * np.sum(sel) / max(n, 1)
            median = f"{np.median(gain[finite]):8.2f} dB" if np.any(finite) else "       - "
            print(f"  {name:<10s} {share:6.2f} %   {median}")

        if args.png:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt

            fig, ax = plt.subplots(figsize=(7, 4.5), dpi=120)
            for code, name in LOS_CLASSES.items():
                sel = (links["los_class"] == code) & np.isfinite(gain)
                ax.scatter(distance[sel], gain[sel], s=4, alpha=0.5, color=COLORS[code],
                           label=f"{name} ({np.sum(sel)})", edgecolors="none")
            ax.set_xlabel("tx-rx distance (m)")
            ax.set_ylabel("coherent path gain (dB)")
            ax.set_title(os.path.basename(args.file))
            ax.grid(True, alpha=0.3)
            ax.legend(markerscale=3, loc="upper right")
            fig.tight_layout()
            fig.savefig(args.png)
            plt.close(fig)
            print(f"wrote {args.png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

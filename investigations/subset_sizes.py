"""How many servers SafeTail sends each request to, per seed of a reproduction: the counts of
each subset size in the test phase and the mean over each β test requests (Fig. (e)'s points,
which the paper's "1 to 3 servers" claims read).

    python investigations/subset_sizes.py OUT [--method SafeTail]

OUT is a ``reproduce_all.py`` (or ``bench_fidelity.py``) folder: every ``uc<N>-<preset>/seed<S>/``
in it is read. Seconds.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from yafs_safetail.results import read_requests_csv, read_run_json


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--method", default="SafeTail")
    args = parser.parse_args()
    for folder in sorted(path.parent for path in args.out.glob("uc*-*/seed*/run.json")):
        run = read_run_json(folder)
        rows = read_requests_csv(folder)
        test = rows[(rows["method"] == args.method) & (rows["phase"] == "test")].sort_values("step")
        sizes = test["n_selected"].to_numpy()
        windows = sizes[: len(sizes) // run.beta * run.beta].reshape(-1, run.beta).mean(axis=1)
        counts = {int(k): int(v) for k, v in zip(*np.unique(sizes, return_counts=True), strict=True)}
        share = {k: f"{v / len(sizes):.0%}" for k, v in counts.items()}
        print(f"{folder.parent.name}/{folder.name}: servers per request {share}; β-window means "
              f"{windows.min():.2f}-{windows.max():.2f} ({int((windows > 3).sum())} of {len(windows)} above 3)")


if __name__ == "__main__":
    main()

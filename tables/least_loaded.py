"""SafeTail beside the strongest simple policy: the least-loaded servers of all five.

§V-B's reading of MinLoad-x (``--baseline-reading paper-text``) sends each request to the x
servers with the fewest active users among all n. This runs the default preset with that reading
per use case and seed (SafeTail's rows are those of the default run: the baselines draw nothing
SafeTail sees) and prints, per use case, the mean over seeds of SafeTail's servers per request,
median and p99 beside MinLoad-1's, MinLoad-2's and MinLoad-3's, and in how many seeds each is
faster than SafeTail. The README's "Against the strongest simple policy" is this table.

    python tables/least_loaded.py [--seeds 7400,7401,7402,7403,7404] [--out DIR]

About 5 minutes on 2 cores at the full budget; run folders already in ``--out`` are read, not
rerun.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd

from yafs_safetail.commands import run_usecase

LEAST_LOADED = ("MinLoad-1", "MinLoad-2", "MinLoad-3")


def run_folder(out: Path, use_case: int, seed: int) -> Path:
    """The run of ``use_case`` and ``seed`` with §V-B's baselines, made unless already there."""
    folder = out / f"uc{use_case}-s{seed}"
    if not (folder / "summary.csv").is_file():
        failed = run_usecase.main(["--uc", str(use_case), "--seed", str(seed), "--baseline-reading",
                                   "paper-text", "--no-figures", "--out", str(folder), "-q"])
        if failed:
            sys.exit(failed)
    return folder


def table(summaries: dict[int, list[pd.DataFrame]]) -> list[str]:
    """The markdown rows: per use case, the means over seeds and the seeds each is faster in."""
    lines = ["| use case | SafeTail: servers, median, p99 (s) | "
             + " | ".join(f"least-loaded {m[-1]}: median, p99 (s); faster than SafeTail in seeds" for m in LEAST_LOADED)
             + " |", "|---" * (2 + len(LEAST_LOADED)) + "|"]
    for use_case, runs in summaries.items():
        frame = pd.concat(runs, keys=range(len(runs)))
        mean = frame.groupby(level=1)[["mean_n_selected", "p50_s", "p99_s"]].mean()
        safetail = mean.loc["SafeTail"]
        cells = [f"{safetail.mean_n_selected:.2f}, {safetail.p50_s:.3f}, {safetail.p99_s:.3f}"]
        for method in LEAST_LOADED:
            faster_p50 = sum(s.loc[method, "p50_s"] < s.loc["SafeTail", "p50_s"] for s in runs)
            faster_p99 = sum(s.loc[method, "p99_s"] < s.loc["SafeTail", "p99_s"] for s in runs)
            cells.append(f"{mean.loc[method, 'p50_s']:.3f}, {mean.loc[method, 'p99_s']:.3f}; "
                         f"median {faster_p50}, p99 {faster_p99} of {len(runs)}")
        lines.append(f"| {use_case} | " + " | ".join(cells) + " |")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="7400,7401,7402,7403,7404")
    parser.add_argument("--out", type=Path, default=Path("results/least_loaded"))
    parser.add_argument("--uc", default="1,2,3", help="use cases, comma-separated (default 1,2,3)")
    args = parser.parse_args(argv)
    try:
        seeds = [int(s) for s in args.seeds.split(",")]
        use_cases = [int(u) for u in args.uc.split(",")]
    except ValueError:
        parser.error("--seeds and --uc: expected comma-separated integers")
    summaries = {use_case: [pd.read_csv(run_folder(args.out, use_case, seed) / "summary.csv").set_index("method")
                            for seed in seeds] for use_case in use_cases}
    print("\n".join(table(summaries)))
    return 0


if __name__ == "__main__":
    sys.exit(main())

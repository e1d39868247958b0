"""Compare two results folders: each method's test-phase p50/p90/p95/p99 and servers per request
in run A and run B, the ratio B / A and its 95% bootstrap interval: paired when both runs met
the same test requests (the same seed and world), each run resampled on its own otherwise.

    yafs-safetail compare RUN_A RUN_B [--out DIR] [--seed 0]

Prints the table, and one warning line on stderr when the two runs' worlds differ (topology,
placement, use case, preset, world settings, failures, energy models: read from both run.json
files); with --out also writes DIR/compare.csv and DIR/compare.png (a new folder), and
--quiet then prints only DIR.
"""

from __future__ import annotations

import argparse
import logging
from collections.abc import Sequence
from pathlib import Path

from yafs_safetail.cli import (
    ArgumentParser,
    add_plumbing,
    add_verbosity_options,
    configure_verbosity,
    print_result,
)
from yafs_safetail.settings.experiment import ExperimentConfig
from yafs_safetail.settings.options import add_options

log = logging.getLogger(__name__)


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog="compare_runs.py", description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    add_plumbing(parser, "run_a", type=Path, help="results folder A")
    add_plumbing(parser, "run_b", type=Path, help="results folder B")
    add_plumbing(parser, "--out", type=Path, default=None, help="write compare.csv and compare.png into this new folder")
    add_options(parser, ExperimentConfig, only=("seed",), seed={"help": "bootstrap seed (default 0)"})
    add_verbosity_options(parser)
    args = parser.parse_args(argv)
    configure_verbosity(args)
    # The arguments are checked: now the folders, with pandas and matplotlib.
    from yafs_safetail.results.compare import compare_runs, world_warning
    from yafs_safetail.results.figures.compare import plot_comparison
    from yafs_safetail.runs.output import StagedOutput

    output = StagedOutput(args.out) if args.out is not None else None  # the target is checked first
    table = compare_runs(args.run_a, args.run_b, args.seed)
    # After the table: bad input stays the one error line. A warning, not an error: comparing
    # two worlds on purpose (a topology's effect) is a use too; it only must not go unnoticed.
    warning = world_warning(args.run_a, args.run_b)
    if warning is not None:
        log.warning("%s", warning)
    if output is not None:  # written before anything is printed: a closed pipe cannot stop it
        with output as staging:
            table.to_csv(staging / "compare.csv", index=False, float_format="%.6g")
            plot_comparison(table, staging / "compare.png", str(args.run_a), str(args.run_b))
            output.publish()
    report = (f"A = {args.run_a}\nB = {args.run_b}\n"
              + table.to_string(index=False, float_format=lambda v: f"{v:.3f}") + "\n")
    if output is None:  # no folder: the table is the result, --quiet or not
        print(report, end="")
    else:
        print_result(args, args.out, report + f"written: {args.out / 'compare.csv'}")
    return 0


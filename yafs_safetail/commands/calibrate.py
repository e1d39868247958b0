"""Fit the world parameters the paper never published, without the learner.

    yafs-safetail calibrate                               # the shipped fit (about 5 min on 2 cores)
    yafs-safetail calibrate --apply                       # ... and install the result
    yafs-safetail calibrate --seeds 1000 --out /tmp/cal   # a quick look

Every point of a fixed grid (load start x load peak x bandwidth share exponent x fallback
multiple) is scored on use case 1's test worlds of the world-calibration seeds: Rand-1's,
MinLoad-1's and MinProp-1's latency over Oracle's at the median, p90, p95 and p99, against what
the paper's numbers imply (calibration, rule 1, in the documentation). SafeTail is not in the objective.
Writes OUT/evaluations.csv (every candidate) and OUT/calibration.json (the best, with its
provenance); with --apply the result also replaces the package's edge/calibration.json, which
the `paper` and `tuned` presets' world reads.
"""

from __future__ import annotations

import argparse
import dataclasses
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path

from yafs_safetail.cli import (
    ArgumentParser,
    add_plumbing,
    add_verbosity_options,
    configure_verbosity,
    invocation,
    positive_int,
    print_result,
)
from yafs_safetail.runs.engine_options import (
    CALIBRATION_WORKER_BYTES,
    default_workers_help,
    local_workers,
)
from yafs_safetail.settings.experiment import ExperimentConfig
from yafs_safetail.settings.options import add_list_options


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog="calibrate.py", description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    add_list_options(parser, ExperimentConfig, {"seed": "--seeds"},
                     seed={"help": "world-calibration seeds (default: seed_sets.json's, 1000-1009)"})
    add_plumbing(parser, "--grid", type=Path, default=None,
                 help="a JSON file mapping each parameter (load_start, load_peak_users, "
                             "bandwidth_share_exponent, fallback_compute_multiple) to its values "
                             "(default: the shipped grid; calibration in the documentation)")
    add_plumbing(parser, "--workers", type=positive_int, default=None,
                 help=f"parallel processes (default: {default_workers_help(CALIBRATION_WORKER_BYTES)}; "
                             "the result does not depend on it)")
    add_plumbing(parser, "--out", type=Path, default=Path("results/calibration"),
                 help="output folder (default results/calibration)")
    add_plumbing(parser, "--apply", action="store_true",
                 help="install the result as the package's edge/calibration.json")
    add_verbosity_options(parser)
    args = parser.parse_args(argv)
    configure_verbosity(args)
    # The arguments are checked: now the calibration, with NumPy and the world.
    from yafs_safetail.edge.calibration import seed_set
    from yafs_safetail.runs.calibrate import (
        GRID,
        CalibrationConfig,
        calibrate,
        check_calibration_config,
        read_grid,
    )

    command = shlex.join([*invocation("experiments/calibrate.py"), *(sys.argv[1:] if argv is None else argv)])
    seeds = tuple(seed_set("world_calibration") if args.seeds is None else args.seeds)
    grid = GRID if args.grid is None else read_grid(args.grid)
    config = CalibrationConfig(seeds=seeds, grid=grid, workers=1, out_dir=args.out, apply=args.apply,
                               command=command)
    check_calibration_config(config)  # bad input is one line, before anything is logged
    config = dataclasses.replace(config, workers=local_workers(args.workers, CALIBRATION_WORKER_BYTES))
    document = calibrate(config)
    provenance = document["provenance"]
    print_result(args, args.out,
                 f"best: {document['parameters']} ({document['readings']['load_start']} load start), "
                 f"objective {provenance['objective_value']} (runner-up {provenance['runner_up_objective']}), "
                 f"within ±20% {provenance['within_20_percent']:.0%}\n"
                 f"written: {args.out / 'calibration.json'}" + (" (installed)" if args.apply else ""))
    return 0


"""Fit the world parameters the paper never published to its use-case-1 x = 1 baseline ratios.

    python experiments/calibrate.py                       # 3 calibration seeds, full budget (~1 h)
    python experiments/calibrate.py --apply               # ... and install the result
    python experiments/calibrate.py --steps-scale 0.2 --max-evaluations 8 --out /tmp/cal   # a quick look

Writes OUT/evaluations.csv (every candidate: parameters, objective, the twelve ratios) and
OUT/calibration.json (the best parameters with their provenance). With --apply the result also
replaces yafs_safetail/edge/calibration.json, which the `paper` and `tuned` presets' world reads.
Only the calibration subset (use case 1: SafeTail against Rand-1, MinLoad-1, MinProp-1 at the
median, p90, p95, p99) is used; every other published number stays held out.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path

from yafs_safetail.cli import (
    ArgumentParser,
    add_verbosity_options,
    configure_verbosity,
    int_list,
    positive_float,
    positive_int,
    run_cli,
)
from yafs_safetail.methods.safetail.presets import PRESET_NAMES
from yafs_safetail.runs.calibrate import (
    DEFAULT_SEEDS,
    NU_CHOICES,
    CalibrationConfig,
    calibrate,
)


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog="calibrate.py", description=__doc__,
                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--preset", default="paper", choices=PRESET_NAMES,
                        help="learner preset whose SafeTail enters the ratios (default paper)")
    parser.add_argument("--seeds", type=int_list, default=DEFAULT_SEEDS,
                        help="calibration seeds, disjoint from report seeds (default 1000,1001,1002)")
    parser.add_argument("--nu", type=int_list, default=NU_CHOICES,
                        help="values of ν the search tries (default "
                             + ",".join(map(str, NU_CHOICES)) + ")")
    parser.add_argument("--steps-scale", type=positive_float, default=1.0,
                        help="fraction of the step budget per run (default 1)")
    parser.add_argument("--max-evaluations", type=positive_int, default=32,
                        help="candidates evaluated at most (default 32)")
    parser.add_argument("--workers", type=positive_int, default=2, help="parallel runs (default 2)")
    parser.add_argument("--out", type=Path, default=Path("results/calibration"),
                        help="output folder (default results/calibration)")
    parser.add_argument("--apply", action="store_true",
                        help="install the result as yafs_safetail/edge/calibration.json")
    add_verbosity_options(parser)
    args = parser.parse_args(argv)
    configure_verbosity(args)
    command = shlex.join(["python", "experiments/calibrate.py", *(sys.argv[1:] if argv is None else argv)])
    document = calibrate(CalibrationConfig(
        preset=args.preset, seeds=args.seeds, steps_scale=args.steps_scale,
        max_evaluations=args.max_evaluations, nu_choices=tuple(args.nu), workers=args.workers,
        out_dir=args.out,
        apply=args.apply, command=command,
    ))  # progress lines are logged (stderr; none with --quiet)
    print(f"best: {document['parameters']} ({document['readings']['load_start']} load start), "
          f"objective {document['provenance']['objective_value']}, within ±20% "
          f"{document['provenance']['within_20_percent']:.0%}")
    print(f"written: {args.out / 'calibration.json'}" + (" (installed)" if args.apply else ""))
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main))

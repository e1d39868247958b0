"""Choose the `paper` preset's learning rate per use case by the calibration rule.

    yafs-safetail learning-rate                 # the rule as written (~15 min)
    yafs-safetail learning-rate --uc 1 --steps-scale 0.05 --seeds 1000 --out /tmp/lr

For each use case and each rate of the grid (1e-5 ... 3e-3), trains `paper` at that rate on the
learner-calibration seeds (seed_sets.json) in the calibrated world and scores the greedy
policy's mean Eq. 5 reward over its test requests; the highest wins, ties to the smaller rate.
Writes OUT/learning_rates.csv (every run) and OUT/learning_rates.json (the choice and its
provenance). The scorecard's numbers never enter. The shipped rates are
yafs_safetail.methods.safetail.presets.PAPER_LEARNING_RATES (calibration in the documentation).
"""

from __future__ import annotations

import argparse
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
from yafs_safetail.defaults import LEARNING_RATE_GRID as RATE_GRID
from yafs_safetail.edge.published import USE_CASES
from yafs_safetail.settings.experiment import ExperimentConfig
from yafs_safetail.settings.options import add_list_options, add_options

# The runner (pandas, the simulator, TensorFlow behind it) is imported after the options are
# read, so --help and a bad option answer at once (issue 30).


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog="choose_learning_rate.py", description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    add_list_options(parser, ExperimentConfig, {"use_case": "--uc", "seed": "--seeds"},
                     use_case={"default": USE_CASES, "help": "use cases (default 1,2,3)"},
                     seed={"help": "learner-calibration seeds (default: seed_sets.json's, 1000-1002)"})
    add_list_options(parser, ExperimentConfig, {"learning_rate": "--rates"}, ascending=True,
                     learning_rate={"default": RATE_GRID, "help": "the candidate rates (default the rule's grid: "
                                    + ",".join(f"{r:g}" for r in RATE_GRID) + "; another grid is not the rule)"})
    add_options(parser, ExperimentConfig, only=("steps_scale",),
                steps_scale={"help": "fraction of the full budget (default 1: the rule as written)"})
    add_plumbing(parser, "--workers", type=positive_int, default=2, help="parallel runs (default 2)")
    add_plumbing(parser, "--criterion", choices=("mean-reward", "zero-share"), default="mean-reward",
                 help="what a rate is chosen by: mean-reward (the rule as written: the mean Eq. 5 test "
                      "reward) or zero-share (the share of test rewards of exactly 0, what the paper's "
                      "target vector trains toward; not the rule)")
    add_plumbing(parser, "--out", type=Path, default=Path("results/learning-rate"),
                 help="output folder (default results/learning-rate)")
    add_verbosity_options(parser)
    args = parser.parse_args(argv)
    from yafs_safetail.runs.learning_rate import (
        LearningRateConfig,
        choose_learning_rates,
        main_rows,
    )
    configure_verbosity(args)
    command = shlex.join([*invocation("experiments/choose_learning_rate.py"),
                          *(sys.argv[1:] if argv is None else argv)])
    from yafs_safetail.edge.calibration import seed_set
    seeds = tuple(seed_set("learner_calibration") if args.seeds is None else args.seeds)
    document = choose_learning_rates(LearningRateConfig(
        use_cases=tuple(args.uc), rates=tuple(args.rates), seeds=seeds, steps_scale=args.steps_scale,
        workers=args.workers, out_dir=args.out, command=command, criterion=args.criterion))
    print_result(args, args.out, "".join(f"{line}\n" for line in main_rows(document))
                 + f"written: {args.out / 'learning_rates.json'}")
    return 0


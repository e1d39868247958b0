"""Why the paper's learner collapses under contention, measured over its training.

    yafs-safetail mechanism --uc 1 --users 50 --loads 0.1,0.5,0.9 --seed 17 \\
        --steps-scale 0.3 --out results/mechanism_uc1

Trains each SafeTail of the load sweep at each load exactly as yafs-safetail sweep does
(same world, seeds and requests, so the trained policies are the sweep's) and records, per
training request, the copies sent and the users active per server when it chose (the queue
its copies join). Writes OUT/mechanism.csv (means per window of training: method, load,
window, first_request, requests, mean_copies, mean_active_per_server, mean_latency_s,
p99_latency_s), OUT/mechanism.png (copies and queue length against training progress, one
line per load, one column per SafeTail) and OUT/run.json. See the contention world in the documentation.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

# Light modules only until the arguments are checked (--help answers at once); the training and
# its figure, with NumPy, pandas and TensorFlow behind them, are imported in main.
from yafs_safetail.cli import (
    ArgumentParser,
    add_plumbing,
    add_verbosity_options,
    configure_verbosity,
    invocation,
    print_result,
)
from yafs_safetail.commands.sweeps import add_users_options, add_world_options, contention_base
from yafs_safetail.contention.config import ContentionConfig
from yafs_safetail.runs.sweep_config import SweepConfig
from yafs_safetail.settings.checks import POSITIVE_INTEGER
from yafs_safetail.settings.declare import setting
from yafs_safetail.settings.options import add_options, config_from_args

#: Windows of training per load (runs.mechanism.DEFAULT_WINDOWS; here so --help loads nothing).
DEFAULT_WINDOWS = 20
MECHANISM_KIND = "training_mechanism"


@dataclass(frozen=True)
class Measurement:
    """How the training is watched (the command's one setting beside the sweep's)."""

    windows: int = setting(DEFAULT_WINDOWS, f"windows of training per load (default {DEFAULT_WINDOWS})",
                           check=POSITIVE_INTEGER)


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog="training_mechanism.py", description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    add_users_options(parser)
    add_options(parser, ContentionConfig, only=("seed",))
    # The load sweep's own settings, declared once in runs.sweep_config.SweepConfig.
    add_options(parser, SweepConfig, only=("loads", "steps_scale", "preset", "reward", "target", "objectives",
                                           "n_networks", "dispatch"))
    add_options(parser, Measurement)
    # The load sweep's world (its defaults: queues, cancel on reply, shared links, no background).
    add_world_options(parser)
    add_plumbing(parser, "--out", type=Path, required=True, help="new output folder")
    add_plumbing(parser, "--overwrite", action="store_true", help="replace an earlier mechanism folder there")
    add_verbosity_options(parser)
    args = parser.parse_args(argv)
    configure_verbosity(args)

    from yafs_safetail import __version__
    from yafs_safetail.results.figures.mechanism import mechanism_figure
    from yafs_safetail.results.files import write_text_atomic
    from yafs_safetail.runs.mechanism import measure_training
    from yafs_safetail.runs.output import MECHANISM_FILE, StagedOutput
    from yafs_safetail.versions import run_json_fields

    config: SweepConfig = config_from_args(args, SweepConfig, base=contention_base(args, args.seed))
    command = " ".join([*invocation("experiments/training_mechanism.py"),
                        *(sys.argv[1:] if argv is None else argv)])
    output = StagedOutput(args.out, args.overwrite)
    with output as staging:
        # Its lines of progress are stdout's report; --quiet keeps stdout to the folder's path.
        table = measure_training(config, args.windows, log=(lambda line: None) if args.quiet else print)
        write_text_atomic(staging / MECHANISM_FILE, table.to_csv(index=False, float_format="%.6g"))
        mechanism_figure(table, staging / "mechanism.png")
        write_text_atomic(staging / "run.json", json.dumps({
            "package_version": __version__, **run_json_fields(), "command": command, "kind": MECHANISM_KIND,
            "use_case": config.base.use_case,
            "users": config.base.users, "seed": config.base.seed, "loads": list(config.loads), "steps_scale": config.steps_scale,
            "target": config.target, "windows": args.windows,
            "safetails": [asdict(variant) for variant in config.safetails]}, indent=1) + "\n")
        output.publish()
    print_result(args, args.out, f"written: {Path(args.out) / MECHANISM_FILE}")
    return 0

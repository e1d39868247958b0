"""Train SafeTail on one use case, test it against the paper's baselines, write results and figures.

    yafs-safetail run --uc 1                                     # paper preset, full budget
    yafs-safetail run --uc 2 --preset tuned --seed 3 --out results/uc2-tuned
    yafs-safetail run --uc 1 --steps-scale 0.1                   # a quick look
    yafs-safetail run --uc 1 --policy results/uc1/policy.keras --out results/uc1-eval
    yafs-safetail run --uc 1 --method my_policy.py:MyPolicy      # your own policy beside them

Progress goes to stderr: bars on a terminal, otherwise one line per phase start and end and
every 10% of a long phase; --quiet keeps warnings and errors only, --verbose adds debug lines.
stdout gets summary.md and the folder's path; with --quiet only the path.
The output folder gets run.log (the command, the configuration, every phase with its time),
requests.csv (one row per request and method), summary.csv and
summary.md (percentiles, access rates, the paper's ratios), run.json, the trained policy,
Figs. (a)-(g) under figures/ as PNG (--figure-format png,pdf adds PDF copies), and with --yafs-csv each method's YAFS result
CSVs under yafs/ (about 70 MB for a full UC1 run, so only on request).

A --method policy subclasses yafs_safetail.methods.Policy and implements choose(observation),
returning the indices (0..n-1, distinct, at least one) of the servers that get a copy; what the
observation holds, with units: python -m pydoc yafs_safetail.edge.observation. Each policy is
asked for the first test request's servers before anything trains: one that cannot choose
stops the run at once, naming its file, its class and what is wrong.
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path

# Light modules only until the arguments are checked (--help answers at once); the experiment,
# with NumPy, simpy and TensorFlow behind it, is imported in main.
from yafs_safetail.cli import (
    ArgumentParser,
    add_verbosity_options,
    configure_verbosity,
    invocation,
    print_result,
)
from yafs_safetail.defaults import DEFAULT_TOPOLOGY, default_placement
from yafs_safetail.edge.topology_io import ScenarioError
from yafs_safetail.logs import is_terminal

# Each objective's class adds its name to what --objective accepts (light: the standard library).
from yafs_safetail.methods import objectives as _objectives  # noqa: F401
from yafs_safetail.settings.experiment import ExperimentConfig
from yafs_safetail.settings.options import add_options, config_from_args

#: The run's options in the order --help lists them (each declared once, in settings.experiment).
OPTIONS = ("use_case", "preset", "seed", "out_dir", "force", "overwrite", "resume", "checkpoint_every_s",
           "steps_scale", "redundancy_levels", "topology", "placement", "traces_dir", "methods", "policy",
           "step_interval_s", "target_latency_s", "load_peak_users", "target_compute", "baseline_reading",
           "learning_rate",
           "workers")


def _parser() -> ArgumentParser:
    parser = ArgumentParser(prog="run_usecase.py", description=__doc__,
                     formatter_class=argparse.RawDescriptionHelpFormatter)
    add_options(parser, ExperimentConfig, only=OPTIONS,
                use_case={"required": True},
                out_dir={"default": None,
                         "help": "results folder (default results/uc<N>-<preset>-s<seed>, with "
                                 "-lr<rate> after the preset with --learning-rate, then "
                                 "-<topology file name> with a --topology other than the paper's, "
                                 "-x<scale> after the seed with --steps-scale, and +<name> at the "
                                 "end for each --method); never replaced unless --overwrite"},
                placement={"default": None})
    add_options(parser, ExperimentConfig, only=("write_yafs_csv", "figures"))
    # Any other setting with an option (a learner hyperparameter added to settings.experiment) too.
    add_options(parser, ExperimentConfig, exclude=(*OPTIONS, "write_yafs_csv", "figures"))
    add_verbosity_options(parser)
    return parser


def default_out_dir(args: argparse.Namespace, method_names: Sequence[str] = ()) -> Path:
    """The results folder of a run without ``--out``.

    ``results/uc<N>-<preset>[-lr<rate>][-<objective>][-<baseline reading>][-<topology>]-s<seed>
    [-x<scale>][+<method>...]``; the objective and the baseline reading only when given. The
    topology is in the name so that a run on another topology does not land in the paper
    topology's folder and stop at "holds an earlier run"; its file name (without ``.json``)
    appears only for a topology other than the paper's, so the paper's runs keep the names the
    docs and tests use. Each ``--method`` adds ``+<its name>`` for the same reason: a second
    policy's run gets a folder of its own, and a run without one keeps the plain name.

    Args:
        args: the parsed command line (named as ExperimentConfig's fields).
        method_names: the names of the run's added methods (``--method``), in order.

    Returns:
        The folder, relative to the working folder.
    """
    scale = "" if args.steps_scale == 1 else f"-x{args.steps_scale:g}"
    rate = "" if args.learning_rate is None else f"-lr{args.learning_rate:g}"
    # Options that change what a run measures: a second run with one of them gets a folder of
    # its own instead of stopping at "holds an earlier run".
    readings = "".join(f"-{value}" for value in (args.objective, args.baseline_reading) if value is not None)
    # Compared as resolved files: the paper's topology given by a relative or linked path is
    # still the paper's.
    paper_topology = Path(args.topology).resolve() == DEFAULT_TOPOLOGY.resolve()
    topology = "" if paper_topology else f"-{Path(args.topology).stem}"
    # A policy's name is the user's (a class attribute may hold spaces or slashes): only the
    # characters that are safe in a folder name on every system stay.
    methods = "".join(f"+{re.sub(r'[^A-Za-z0-9._=-]+', '_', name)}" for name in method_names)
    return Path("results") / f"uc{args.use_case}-{args.preset}{rate}{readings}{topology}-s{args.seed}{scale}{methods}"


def parse_args(argv: Sequence[str] | None) -> ExperimentConfig:
    """The run's configuration from the command line (no logging set up)."""
    return _config(_parser().parse_args(argv), argv)


def _config(args: argparse.Namespace, argv: Sequence[str] | None) -> ExperimentConfig:
    placement = args.placement
    if placement is None:
        placement = default_placement(args.topology)
        if not placement.is_file() and Path(args.topology).is_file():
            # The loader's own "not found" names a file the user never gave: say where the
            # name came from and what to pass instead. (A missing topology is the loader's to
            # report first: the placement's name is derived from it.)
            raise ScenarioError(str(placement), "file",
                                f"placement file not found, the default for --topology {args.topology}; "
                                "pass --placement with the placement JSON of that topology")
    command = shlex.join([*invocation("experiments/run_usecase.py"), *(sys.argv[1:] if argv is None else argv)])
    config: ExperimentConfig = config_from_args(
        args, ExperimentConfig, placement=placement, out_dir=args.out_dir or default_out_dir(args), command=command,
        # Bars only where someone watches; elsewhere the phases' 10% lines say the same.
        progress=not args.quiet and is_terminal(sys.stderr))
    if args.out_dir is None and config.methods:  # their names are known once they are loaded
        config = dataclasses.replace(config, out_dir=default_out_dir(args, [m.name for m in config.methods]))
    return config


def main(argv: Sequence[str] | None = None) -> int:
    """Run one use case as the command line asks; returns the exit code (0)."""
    args = _parser().parse_args(argv)
    configure_verbosity(args)
    config = _config(args, argv)
    from yafs_safetail.runs.experiment import run_experiment

    report = run_experiment(config)
    print_result(args, report.out_dir,
                 (report.out_dir / "summary.md").read_text() + f"\nresults: {report.out_dir}\n")
    return 0

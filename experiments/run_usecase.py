"""Train SafeTail on one use case, test it against the paper's baselines, write results and figures.

    python experiments/run_usecase.py --uc 1                       # paper preset, full budget
    python experiments/run_usecase.py --uc 2 --preset tuned --seed 3 --out results/uc2-tuned
    python experiments/run_usecase.py --uc 1 --steps-scale 0.1     # a quick look
    python experiments/run_usecase.py --uc 1 --policy results/uc1/policy.keras --out results/uc1-eval
    python experiments/run_usecase.py --uc 1 --method examples/custom_policy/nearest_free.py:NearestFree

Progress goes to stderr: bars on a terminal, otherwise one line per phase start and end and
every 10% of a long phase; --quiet keeps warnings and errors only, --verbose adds debug lines.
The output folder gets run.log (the command, the configuration, every phase with its time),
requests.csv (one row per request and method), summary.csv and
summary.md (percentiles, access rates, the paper's ratios), run.json, the trained policy,
Figs. (a)-(g) under figures/ as PNG and PDF, and with --yafs-csv each method's YAFS result
CSVs under yafs/ (about 70 MB for a full UC1 run, so only on request).
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
    non_negative_float,
    non_negative_int,
    positive_float,
    positive_int,
    run_cli,
)
from yafs_safetail.edge.calibration import TARGET_COMPUTES
from yafs_safetail.edge.published import USE_CASES
from yafs_safetail.edge.scenario import default_placement
from yafs_safetail.edge.topology_io import ScenarioError
from yafs_safetail.logs import is_terminal
from yafs_safetail.methods.registry import UserMethod
from yafs_safetail.methods.safetail.presets import PRESET_NAMES
from yafs_safetail.runs.experiment import (
    DEFAULT_TOPOLOGY,
    ExperimentConfig,
    run_experiment,
)
from yafs_safetail.sim.population import DEFAULT_STEP_INTERVAL_S


def _levels(text: str) -> tuple[int, ...]:
    try:
        levels = tuple(int(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers, got {text!r}") from None
    if not levels:
        raise argparse.ArgumentTypeError("expected at least one level")
    return levels


def _parser() -> ArgumentParser:
    parser = ArgumentParser(prog="run_usecase.py", description=__doc__,
                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--uc", type=int, required=True, choices=USE_CASES,
                        help="use case: 1 object detection, 2 instance segmentation, 3 noise removal")
    parser.add_argument("--preset", default="paper", choices=PRESET_NAMES,
                        help="learner preset (default: paper = Table I with the readings under "
                             "which it learns, in the calibrated world; paper-literal = Table I "
                             "verbatim; tuned = ours; docs/deviations.md)")
    parser.add_argument("--seed", type=non_negative_int, default=0, help="the run's seed (default 0)")
    parser.add_argument("--out", type=Path, default=None,
                        help="results folder (default results/uc<N>-<preset>-s<seed>, with "
                             "-lr<rate> after the preset with --learning-rate, then "
                             "-<topology file name> with a --topology other than the paper's, "
                             "and -x<scale> at the end with --steps-scale); never replaced "
                             "unless --overwrite")
    parser.add_argument("--force", action="store_true",
                        help="run a budget beyond the limits (10 GB of results or 4 GB of memory)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an earlier results folder at --out (only a results folder)")
    parser.add_argument("--resume", action="store_true",
                        help="continue an interrupted run's training from its checkpoint (give the "
                             "same options; the results equal an uninterrupted run's)")
    parser.add_argument("--checkpoint-every-s", type=non_negative_float, default=60.0,
                        help="wall-clock seconds between two training checkpoints, kept beside "
                             "--out as .<name>.checkpoint until the run ends (default 60)")
    parser.add_argument("--steps-scale", type=positive_float, default=1.0,
                        help="fraction of the preset's training and testing steps (default 1)")
    parser.add_argument("--redundancy", type=_levels, default=(1, 2, 3),
                        help="levels x of Rand-x, MinLoad-x, MinProp-x (default 1,2,3)")
    parser.add_argument("--topology", type=Path, default=DEFAULT_TOPOLOGY,
                        help="YAFS topology JSON with 1 to 10 edge servers (default topologies/paper_5servers.json)")
    parser.add_argument("--placement", type=Path, default=None,
                        help="YAFS placement JSON (default: placements/<topology file name>)")
    parser.add_argument("--method", action="append", default=[], metavar="[NAME=]FILE.py:CLASS",
                        help="add your own Policy to the comparison (also module:Class; repeatable; "
                             "named after the class unless NAME= is given)")
    parser.add_argument("--policy", type=Path, default=None,
                        help="evaluate this saved policy (.keras) without training")
    parser.add_argument("--step-interval-s", type=positive_float, default=DEFAULT_STEP_INTERVAL_S,
                        help=f"simulated time between two requests, one load-trace row "
                             f"(default {DEFAULT_STEP_INTERVAL_S:g})")
    parser.add_argument("--target-latency-s", type=positive_float, default=None,
                        help="a fixed target latency for every request, in seconds (default: "
                             "Eq. 4's per-request heuristic, as in the paper)")
    parser.add_argument("--load-peak-users", type=non_negative_float, default=None,
                        help="load level: background users on a server at its busiest minute "
                             "(0 = idle, 4 = full at the peak; default: the preset world's, "
                             "recorded in run.json)")
    parser.add_argument("--target-compute", choices=TARGET_COMPUTES, default=None,
                        help="C(s_j) of Eq. 4: 'request', the median compute time at ν of the "
                             "request's own input, or 'trace_median', the compute trace's median "
                             "at ν for every request (default: the preset world's; "
                             "docs/deviations.md D11)")
    parser.add_argument("--learning-rate", type=positive_float, default=None,
                        help="Adam's learning rate for SafeTail instead of the preset's (e.g. "
                             "the paper preset's network with tuned's 1e-3); the run is then no "
                             "longer the preset's, and run.json and summary.md say so")
    parser.add_argument("--workers", type=positive_int, default=2,
                        help="processes: the baselines are tested in workers-1 other processes "
                             "while SafeTail trains (default 2; 1 = one process; same results)")
    yafs_csv = parser.add_mutually_exclusive_group()
    yafs_csv.add_argument("--yafs-csv", action="store_true",
                          help="also write each method's YAFS result CSVs under yafs/ (~70 MB for UC1)")
    yafs_csv.add_argument("--no-yafs-csv", action="store_true",
                          help="do not write the YAFS CSVs (the default; kept for older scripts)")
    parser.add_argument("--no-figures", action="store_true", help="skip the figures")
    add_verbosity_options(parser)
    return parser


def default_out_dir(args: argparse.Namespace) -> Path:
    """The results folder of a run without ``--out``.

    ``results/uc<N>-<preset>[-lr<rate>][-<topology>]-s<seed>[-x<scale>]``. The topology is in
    the name so that a run on another topology does not land in the paper topology's folder
    and stop at "holds an earlier run"; its file name (without ``.json``) appears only for a
    topology other than the paper's, so the paper's runs keep the names the docs and tests use.

    Args:
        args: the parsed command line.

    Returns:
        The folder, relative to the working folder.
    """
    scale = "" if args.steps_scale == 1 else f"-x{args.steps_scale:g}"
    rate = "" if args.learning_rate is None else f"-lr{args.learning_rate:g}"
    # Compared as resolved files: the paper's topology given by a relative or linked path is
    # still the paper's.
    paper_topology = Path(args.topology).resolve() == DEFAULT_TOPOLOGY.resolve()
    topology = "" if paper_topology else f"-{Path(args.topology).stem}"
    return Path("results") / f"uc{args.uc}-{args.preset}{rate}{topology}-s{args.seed}{scale}"


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
    out = args.out or default_out_dir(args)
    command = shlex.join(["python", "experiments/run_usecase.py", *(sys.argv[1:] if argv is None else argv)])
    return ExperimentConfig(
        use_case=args.uc, preset=args.preset, seed=args.seed, out_dir=out,
        topology=args.topology, placement=placement, steps_scale=args.steps_scale,
        redundancy_levels=args.redundancy, policy=args.policy,
        methods=tuple(UserMethod(spec) for spec in args.method),
        write_yafs_csv=args.yafs_csv, figures=not args.no_figures,
        # Bars only where someone watches; elsewhere the phases' 10% lines say the same.
        progress=not args.quiet and is_terminal(sys.stderr), command=command, workers=args.workers,
        overwrite=args.overwrite, force=args.force, step_interval_s=args.step_interval_s,
        resume=args.resume, checkpoint_every_s=args.checkpoint_every_s,
        target_latency_s=args.target_latency_s, load_peak_users=args.load_peak_users,
        target_compute=args.target_compute, learning_rate=args.learning_rate,
    )


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    configure_verbosity(args)
    config = _config(args, argv)
    report = run_experiment(config)
    print((report.out_dir / "summary.md").read_text(), end="")
    print(f"\nresults: {report.out_dir}")
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main))

"""Run every use case over several seeds and write one report against the paper's numbers.

    yafs-safetail reproduce                                  # UC 1-3, seeds 0-4, paper preset
    yafs-safetail reproduce --preset paper,paper-literal,tuned --seeds 0,1,2,3,4,5
    yafs-safetail reproduce --steps-scale 0.1 --out results/quick
    yafs-safetail reproduce --workers 1                      # one run at a time (less memory)
    yafs-safetail reproduce --engine ray                     # on Ray (campaigns in the documentation)
    yafs-safetail reproduce --learning-rate 1e-3 --out results/paper-lr1e-3
    yafs-safetail reproduce --method my_policy.py:MyPolicy   # your policy over seeds, with intervals

For every (use case, preset, seed) it runs exactly what the run command runs, into
``OUT/uc<N>-<preset>/seed<S>/``. Then ``OUT/REPORT.md`` opens with the fidelity scorecard of
each preset (every ratio and claim the paper publishes against ours over the seeds, calibration
subset and held-out numbers apart; also in ``OUT/fidelity.csv`` and the figure
``OUT/fidelity-<preset>.png``), then what any policy could reach in that world (whether the
paper's statements about each percentile can hold together at all, from Oracle's and the
baselines' latencies and the targets alone; ``OUT/feasibility.csv``,
``yafs_safetail.results.feasibility``), and gives, per use case and preset: the latency table (mean over
seeds and a 95% bootstrap interval), our ratios beside the paper's stated ones with a plain
note where they differ, what the learner did (training rounds, final ε, servers used, target
met, fallbacks) as the first place to look for why, figures across seeds with 95% bands
(``OUT/figures/uc<N>-<preset>-latency-bands`` and ``-servers-bands``, PNG, or PDF too with
``--figure-format png,pdf``) and the
figures of the first seed. Every table of the report is also written as LaTeX
(``OUT/tables/*.tex``, listed at the end of REPORT.md). Seeds must be distinct; the scorecard
asks for at least five (with fewer it says so and goes on).

--method adds your own Policy (as the run command's --method) to every run, beside SafeTail and
the baselines: each use case and preset's section then also gives its latency (median, p90,
p95, p99) and servers per request beside SafeTail's and Oracle's, and its speed-ups over both,
with 95% intervals over the seeds (also in ``OUT/methods.csv``).

The runs form one campaign (``yafs_safetail.runs.campaign``): rerunning the same command on the
same --out resumes an interrupted reproduction and recomputes no finished run (a run folder
records its run id, a hash of its configuration and the code version); a run that fails is
reported and the others go on (exit status 1, no report). Progress goes to stderr and
``OUT/campaign.log``, each run's state to ``OUT/campaign.json``. Runs go as many at a time as
this machine's CPUs and available memory allow (1 GB a run; --workers N for fewer); the files
are the same for any number.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Sequence
from pathlib import Path

# Light modules only until the arguments are checked (--help answers at once).
from yafs_safetail.cli import (
    ArgumentParser,
    add_plumbing,
    add_verbosity_options,
    configure_verbosity,
    invocation,
    print_result,
)
from yafs_safetail.edge.published import USE_CASES

# Each objective's class adds its name to what --objective accepts (light: the standard library).
from yafs_safetail.methods import objectives as _objectives  # noqa: F401
from yafs_safetail.runs.engine_options import add_engine_options, engine_keywords
from yafs_safetail.settings.declare import field_of, setting_of
from yafs_safetail.settings.experiment import (
    ExperimentConfig,
    ExperimentError,
    LearnerOverrides,
    Task,
)
from yafs_safetail.settings.options import add_list_options, add_options


def _check_methods(specs: Sequence[str]) -> None:
    """Load every ``--method`` policy once here, so that a bad one is one line before any run
    starts rather than a failure of every run.

    Raises:
        ExperimentError: two policies with one name (a file or class that cannot be loaded
            raises the registry's PolicyError, also one line).
    """
    load = setting_of(field_of(Task, "methods")).from_cli
    names = [method.name for method in (load(specs) if load is not None else ())]
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise ExperimentError(f"--method: two methods are named {repeated[0]!r}")


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog="reproduce_all.py", description=__doc__,
                     formatter_class=argparse.RawDescriptionHelpFormatter)
    # Several values of a run's settings: each read and checked as the run command's option.
    add_list_options(parser, ExperimentConfig, {"use_case": "--uc", "seed": "--seeds", "preset": "--preset"},
                     use_case={"default": USE_CASES, "help": "use cases (default: all)"},
                     seed={"default": (0, 1, 2, 3, 4),
                           "help": "distinct seeds (default 0,1,2,3,4; the scorecard wants five or more)"},
                     preset={"default": ("paper",), "help": "preset(s), comma-separated (default paper)"})
    add_plumbing(parser, "--out", type=Path, default=Path("results/reproduce"),
                 help="output folder (default results/reproduce)")
    # The settings every run shares, each declared once in settings.experiment (its type, check and
    # default); the help says what they mean for the whole reproduction.
    add_options(parser, ExperimentConfig, only=("steps_scale", "target_compute", "traces_dir"),
                steps_scale={"help": "fraction of each preset's steps (default 1)"},
                traces_dir={"default": None},
                target_compute={"help": "C(s_j) of Eq. 4 for every run (default: each preset world's; "
                                        "deviation D11 in the documentation)"})
    add_options(parser, LearnerOverrides,  # every learner hyperparameter a run may override
                learning_rate={"help": "Adam's learning rate for every run instead of each preset's (the "
                                       "report then says these are not the presets' results)"})
    add_options(parser, ExperimentConfig, only=("methods",),
                methods={"help": "add your own Policy to every run and to the report (also "
                                 "module:Class; repeatable; named after the class unless NAME= is given)"})
    add_options(parser, ExperimentConfig, only=("figures", "figure_formats"), figures={"help": "skip the per-run figures"})
    add_plumbing(parser, "--overwrite", action="store_true",
                 help="replace run folders in --out that hold another configuration")
    add_engine_options(parser)
    add_verbosity_options(parser)
    args = parser.parse_args(argv)
    configure_verbosity(args)
    # The arguments are checked: now the campaign and the report, with NumPy and pandas.
    _check_methods(args.methods)
    from yafs_safetail.results.reproduction import RUN_FOLDER, write_report
    from yafs_safetail.runs.campaign import engine_free_command, run_campaign
    from yafs_safetail.runs.grid import expand
    from yafs_safetail.runs.output import refuse_protected

    command = engine_free_command(invocation("experiments/reproduce_all.py"), sys.argv[1:] if argv is None else argv)
    refuse_protected(args.out)
    # Every (use case, preset, seed) is one run of a campaign: resumable, in parallel with
    # --workers, each run's folder where it always was.
    base = {"steps_scale": args.steps_scale, "figures": args.figures,
            "figure_formats": args.figure_formats}
    overridable = ("target_compute", *(item.name for item in dataclasses.fields(LearnerOverrides)))
    base.update({name: getattr(args, name) for name in overridable if getattr(args, name) is not None})
    if args.traces_dir is not None:  # only when given, as the methods: read from the working folder
        base["traces_dir"] = str(args.traces_dir)
    if args.methods:  # only when given, so that the runs without keep their folders' run ids
        base["methods"] = list(args.methods)
    specs = expand(base,
                   {"use_case": list(args.uc), "preset": list(args.preset), "seed": list(args.seeds)},
                   name=RUN_FOLDER, source="reproduce_all.py")
    outcome = run_campaign(specs, args.out, command=command, **engine_keywords(args))
    if outcome.failed:
        print(f"error: {outcome.failed} run(s) failed (see above); no report written; rerun the "
              "same command to retry them (finished runs are kept)", file=sys.stderr)
        return 1
    report = write_report(args.out, args.uc, args.preset, args.seeds, command, args.learning_rate,
                          args.figure_formats)
    print_result(args, args.out, f"report: {report}")
    return 0

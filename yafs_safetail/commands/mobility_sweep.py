"""Every method at a few speeds of a moving user: what learned redundancy is worth on the move.

    yafs-safetail mobility-sweep                                   # UC1, seeds 0,1,2, the campus
    yafs-safetail mobility-sweep --seeds 7200,7201,7202,7203,7204 --out results/mobility
    yafs-safetail mobility-sweep --speeds rest,driving --steps-scale 0.1 --method my.py:Mine

For each named speed (rest: 0 m/s; walking: 1-1.5 m/s; driving: 8-14 m/s) and seed, one run of
what the run command runs with --mobility random-waypoint, into OUT/<speed>/seed<S>/: every
method (SafeTail trained on the move, Oracle, the baselines, your --method) on the same
requests, loads and random waypoints (the same destinations in the same order at every speed:
only how fast the user gets there changes). Then OUT/mobility.csv (per speed, method and
metric, p50, p99 and servers per request: the mean over seeds and a 95% bootstrap interval),
OUT/mobility.md (p99 and servers per request, a method per row, a speed per column) and
OUT/mobility.png (both against speed).

The topology must place its user and every edge server (default
topologies/campus_5servers.json, the paper's five servers on a campus). The runs form one
campaign: the same command on the same --out resumes, runs go as many at a time as the machine
allows (--workers N for fewer), and the files are the same for any number.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass
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
from yafs_safetail.defaults import CAMPUS_TOPOLOGY, MOBILITY_SPEEDS_MPS
from yafs_safetail.runs.engine_options import add_engine_options, engine_keywords
from yafs_safetail.settings.checks import one_of
from yafs_safetail.settings.declare import setting
from yafs_safetail.settings.experiment import ExperimentConfig
from yafs_safetail.settings.options import add_list_options, add_options


@dataclass(frozen=True)
class MobilitySweep:
    """What the sweep varies beside the seed (its one setting beside a run's)."""

    speed: str = setting("walking", "a named speed range: " + ", ".join(
        f"{name} {low:g}-{high:g} m/s" for name, (low, high) in MOBILITY_SPEEDS_MPS.items()),
        check=one_of(tuple(MOBILITY_SPEEDS_MPS)))


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog="mobility_sweep.py", description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    add_list_options(parser, MobilitySweep, {"speed": "--speeds"},
                     speed={"default": tuple(MOBILITY_SPEEDS_MPS),
                            "help": "named speeds, slowest first (default rest,walking,driving)"})
    add_list_options(parser, ExperimentConfig, {"seed": "--seeds"},
                     seed={"default": (0, 1, 2), "help": "distinct seeds (default 0,1,2)"})
    add_options(parser, ExperimentConfig, only=("use_case", "preset", "steps_scale", "topology", "placement",
                                                "pause_s", "step_interval_s", "baseline_reading", "traces_dir",
                                                "methods", "figures", "figure_formats"),
                topology={"default": CAMPUS_TOPOLOGY,
                          "help": "YAFS topology JSON placing the user and every edge server "
                                  "(default topologies/campus_5servers.json)"},
                placement={"default": None, "help": "YAFS placement JSON (default: placements/<topology file name>)"},
                traces_dir={"default": None},
                figures={"help": "skip each run's own figures (the sweep's figure is drawn anyway)"})
    add_plumbing(parser, "--out", type=Path, default=Path("results/mobility"),
                 help="output folder (default results/mobility)")
    add_plumbing(parser, "--overwrite", action="store_true",
                 help="replace run folders in --out that hold another configuration")
    add_engine_options(parser)
    add_verbosity_options(parser)
    args = parser.parse_args(argv)
    configure_verbosity(args)
    # The arguments are checked: now the campaign and its tables, with NumPy and pandas.
    from yafs_safetail.results.figures.mobility import draw_mobility_figure
    from yafs_safetail.results.mobility_sweep import (
        SWEEP_RUN_FOLDER,
        sweep_folders,
        sweep_table,
        write_sweep_tables,
    )
    from yafs_safetail.runs.campaign import engine_free_command, run_campaign
    from yafs_safetail.runs.experiment import check_user_policies
    from yafs_safetail.runs.grid import expand, make_config
    from yafs_safetail.runs.output import refuse_protected
    from yafs_safetail.worlds.recipe import world_recipe

    command = engine_free_command(invocation("experiments/mobility_sweep.py"), sys.argv[1:] if argv is None else argv)
    refuse_protected(args.out)
    base = {"use_case": args.use_case, "preset": args.preset, "steps_scale": args.steps_scale,
            "topology": str(args.topology), "mobility": "random-waypoint", "pause_s": args.pause_s,
            "figures": args.figures, "figure_formats": args.figure_formats}
    # Only when given, so that a sweep without them keeps its runs' ids.
    if args.placement is not None:
        base["placement"] = str(args.placement)
    for name in ("step_interval_s", "baseline_reading"):
        if getattr(args, name) != getattr(ExperimentConfig(), name):
            base[name] = getattr(args, name)
    if args.traces_dir is not None:  # read from the working folder, as the methods' files
        base["traces_dir"] = str(args.traces_dir)
    if args.methods:
        base["methods"] = list(args.methods)
    # One campaign: every (speed, seed) a run, resumable and in parallel, at OUT/<speed>/seed<S>.
    specs = []
    for speed in args.speeds:
        named = SWEEP_RUN_FOLDER.replace("{speed}", speed)
        specs += expand({**base, "speed_mps": list(MOBILITY_SPEEDS_MPS[speed])}, {"seed": list(args.seeds)},
                        name=named, source="mobility_sweep.py")
    # Before the campaign starts: each --method policy asked for its first request (its world
    # read, --traces' files with it), or else every --traces file read and checked.
    if args.methods:
        check_user_policies(make_config(specs[0], args.out / specs[0].name))
    elif args.traces_dir is not None:
        world_recipe(make_config(specs[0], args.out / specs[0].name))
    outcome = run_campaign(specs, args.out, command=command, **engine_keywords(args))
    if outcome.failed:
        print(f"error: {outcome.failed} run(s) failed (see above); no tables written; rerun the "
              "same command to retry them (finished runs are kept)", file=sys.stderr)
        return 1
    table = sweep_table(sweep_folders(args.out, args.speeds, args.seeds), MOBILITY_SPEEDS_MPS)
    title = (f"Mobility sweep: use case {args.use_case}, preset {args.preset}, seeds "
             f"{','.join(map(str, args.seeds))}, {Path(args.topology).name}")
    _, markdown = write_sweep_tables(args.out, table, title)
    draw_mobility_figure(table, args.out, title, args.figure_formats)
    print_result(args, args.out, markdown.read_text())
    return 0

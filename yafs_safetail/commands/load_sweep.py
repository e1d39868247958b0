"""Many users at once: every method's latency and copies against the offered load.

    yafs-safetail sweep --uc 1 --users 50 --loads 0.1,0.3,0.5,0.7,0.9 --seed 0 \\
        --steps-scale 1 --out results/sweep_uc1

Two SafeTails run beside the fixed methods by default, each trained at each load (its preset's
training budget × --steps-scale) and tested greedily: SafeTail, the paper's learner (§III's
target vector, Eq. 5, preset paper, copies sent all at once), and SafeTail-CA, the
contention-aware one beyond the paper (a value learner that prices each copy by the jobs it
joins, preset tuned, tied copies; deviation D13 in the documentation). --learner target-vector or
--learner value runs one of them alone; --no-safetail neither.

Writes OUT/sweep.csv (one row per load and method: load, method, n_requests, p50_s, p99_s,
mean_n_selected, fallback_rate, ...), OUT/SWEEP.md (p99 and copies per load and method, the
full table and the sweep's goals, each computed, never assumed: Oracle's p99 at the highest load
at least 1.5x its p99 at the lowest, and worse than single dispatch beyond some load; each
SafeTail sending fewer copies as the load rises, its p99 at most 1.05x the best fixed method's
at every load, and below Oracle's from load 0.7), OUT/sweep.png (p99 on a log scale and copies
per request against load, both SafeTails highlighted), OUT/sweep_latency.png (p50 and p99) and
OUT/run.json (the settings and this command); see the contention world in the documentation.

With --seeds 0,1,2 (instead of --seed) every seed's sweep goes into OUT/seed-<S>/ as above, and
OUT/seeds.csv (every seed's sweep.csv rows, with a seed column) and OUT/SEEDS.md (each SafeTail's
p99 over the best fixed method's per seed and load, and in how many seeds each goal holds)
compare them.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Mapping, Sequence
from dataclasses import asdict, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

# Light modules only until the arguments are checked (--help answers at once); the sweep, the
# campaign and the report, with NumPy and pandas behind them, are imported where they run.
from yafs_safetail import __version__
from yafs_safetail.cli import (
    ArgumentParser,
    add_verbosity_options,
    configure_verbosity,
    distinct_int_list,
    invocation,
    non_negative_int,
    positive_int,
    print_result,
)
from yafs_safetail.contention.config import LINK_MODELS, ContentionConfig, ContentionError
from yafs_safetail.contention.sweep_config import ContentionSweep, SweepConfig
from yafs_safetail.defaults import DEFAULT_PLACEMENT, DEFAULT_TOPOLOGY
from yafs_safetail.runs.engine_options import add_engine_options, engine_free_command
from yafs_safetail.settings.declare import add_options, config_from_args
from yafs_safetail.versions import run_json_fields

if TYPE_CHECKING:
    import pandas as pd

    from yafs_safetail.runs.grid import RunSpec

#: With --seeds: every seed's sweep.csv rows, with a leading seed column.
SEEDS_FILE = "seeds.csv"
#: run.json's kind: one seed's sweep, and the folder of several.
SWEEP_KIND = "load_sweep"
SEEDS_KIND = "load_sweep_seeds"
#: The sweep's settings given as options beside the axis's (each declared once in
#: contention.sweep_config), in the order --help lists them.
LEARNER_OPTIONS = ("steps_scale", "test_requests_per_load", "preset", "reward", "target", "learners",
                   "value_networks", "dispatch")


# ----------------------------------------------------------------------------- shared by the sweeps


def add_users_options(parser: argparse.ArgumentParser) -> None:
    """--uc and --users, every sweep's first options."""
    parser.add_argument("--uc", type=int, choices=(1, 2, 3), default=1, help="use case (default 1)")
    parser.add_argument("--users", type=positive_int, default=50, help="users U (default 50)")


def add_world_options(parser: argparse.ArgumentParser) -> None:
    """How the contention world's servers, links and users behave (every sweep's)."""
    parser.add_argument("--servers", choices=("queue", "refuse"), default="queue",
                        help="a full server queues copies FIFO (default) or refuses them (the paper)")
    parser.add_argument("--no-cancel", action="store_true", help="let the other copies run to the end")
    parser.add_argument("--links", choices=LINK_MODELS, default="shared",
                        help="transfers share each server's links over their duration (default) or take "
                             "the bandwidth of the level when they start (at-start, the single-user reading)")
    parser.add_argument("--background", action="store_true",
                        help="add the load trace's background tenants on top of the users' load")
    # A word or a file: ~ expanded as in every path option (the words have none to expand).
    parser.add_argument("--user-conditions", default="topology", type=os.path.expanduser,
                        help="each user's distance condition per server: topology (default), generated "
                             "(the topology's ±1 per user and server) or a JSON file (the contention world in the documentation)")


def add_output_options(parser: argparse.ArgumentParser, config_class: type[ContentionSweep]) -> None:
    """The methods, the input files, where the sweep goes and how it runs (every sweep's last
    options)."""
    add_options(parser, config_class, only=("methods", "safetail"))
    parser.add_argument("--topology", type=Path, default=DEFAULT_TOPOLOGY, help="topology JSON")
    parser.add_argument("--placement", type=Path, default=DEFAULT_PLACEMENT, help="placement JSON")
    parser.add_argument("--out", type=Path, required=True, help="new output folder")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace point folders there that hold another configuration's results")
    add_engine_options(parser)
    add_verbosity_options(parser)


def contention_base(args: argparse.Namespace, seed: int) -> ContentionConfig:
    """The contention world every point of a sweep shares, from the options."""
    return ContentionConfig(use_case=args.uc, seed=seed, users=args.users, queue=args.servers == "queue",
                            cancel=not args.no_cancel, background=args.background, links=args.links,
                            topology=args.topology, placement=args.placement,
                            user_conditions=args.user_conditions)


def check_methods(args: argparse.Namespace) -> None:
    """The methods' options that parsing alone cannot check, as a one-line ContentionError
    before the sweep's configuration is built."""
    import numpy as np

    from yafs_safetail.methods.registry import make_baseline

    for name in args.methods:  # unknown names fail before anything runs
        make_baseline(name, 5, np.random.default_rng(0))
    if args.value_networks is not None and "value" not in args.learners:
        raise ContentionError(f"--value-networks {args.value_networks}: only with the value learner "
                              "(SafeTail-CA)")


def check_test_requests(args: argparse.Namespace, config: ContentionSweep) -> None:
    """Enough test requests per point for a p99 (a one-line ContentionError otherwise)."""
    if config.test_requests < 100:
        flag = "--test-requests" if args.test_requests_per_load is not None else f"--steps-scale {args.steps_scale}"
        raise ContentionError(f"{flag}: {config.test_requests} test requests per {config.axis.label}; "
                              "at least 100 are needed for a p99")


def is_sweep_folder(folder: Path, kind: str, runs: tuple[str, ...]) -> bool:
    """A folder a sweep command made for ``kind``: a campaign's state file, and a sweep's
    run.json of that kind or nothing but the campaign's files and its run folders (named with
    one of ``runs``), so another campaign's folder or a results folder is never written into."""
    from yafs_safetail.runs.campaign import STATE_FILE

    if not (folder / STATE_FILE).is_file():
        return False
    if not (folder / "run.json").exists():
        # Interrupted before the table was assembled: only the campaign's files and run folders.
        return all(item.name.startswith((*runs, "campaign.", ".campaign.")) for item in folder.iterdir())
    try:
        return json.loads((folder / "run.json").read_text()).get("kind") == kind
    except (OSError, ValueError, AttributeError):
        return False


def check_out(out: Path, kind: str, runs: tuple[str, ...], what: str) -> None:
    """``--out`` is new, empty, or this kind of sweep's folder (``what`` names it in the error)."""
    if out.exists() and any(out.iterdir()) and not is_sweep_folder(out, kind, runs):
        raise ContentionError(f"--out {out}: exists and is not {what}'s folder; give a new folder")


def run_points(out: Path, specs: Mapping[int, Sequence[RunSpec]], args: argparse.Namespace,
               command: str) -> dict[int, pd.DataFrame] | None:
    """Every point of every seed's sweep as one campaign into ``out`` (each point cached by its
    configuration's hash, resumable, on any engine); each seed's rows read back from its points'
    folders, in point order. None when a point failed (the campaign has said which)."""
    import pandas as pd

    from yafs_safetail.runs.campaign import run_campaign
    from yafs_safetail.runs.output import SWEEP_FILE

    result = run_campaign([spec for seed_specs in specs.values() for spec in seed_specs], out, engine=args.engine,
                          workers=args.workers, ray_address=args.ray_address, command=command,
                          overwrite=args.overwrite)
    if result.failed:
        return None
    return {seed: pd.concat([pd.read_csv(out / spec.name / SWEEP_FILE) for spec in seed_specs], ignore_index=True)
            for seed, seed_specs in specs.items()}


def sweep_run_json(args: argparse.Namespace, config: ContentionSweep, command: str, kind: str,
                   specs: Sequence[RunSpec], **axis: Any) -> dict[str, Any]:
    """A sweep folder's run.json: the command, the axis's settings (``axis``, in order after the
    use case and users), the world's and the methods', and each point's run id."""
    return {
        "package_version": __version__, **run_json_fields(), "command": command, "kind": kind,
        "use_case": args.uc, "users": args.users, **axis, "seed": config.base.seed,
        "steps_scale": config.steps_scale, "target": config.target,
        "safetails": [asdict(variant) for variant in config.safetails],
        "servers": args.servers, "cancel": not args.no_cancel, "background": args.background, "links": args.links,
        "methods": list(config.methods), "test_requests": config.test_requests,
        "topology": str(args.topology),
        "placement": str(args.placement), "user_conditions": str(args.user_conditions),
        f"{config.axis.folder}_runs": {spec.name.rsplit("/", 1)[-1]: spec.run_id for spec in specs}}


def safetail_lines(config: ContentionSweep) -> str:
    """How each SafeTail of the sweep learns and sends, one line each (none: fixed methods only)."""
    lines = [f"{variant.name}: {variant.describe()}, target `{config.target}`." for variant in config.safetails]
    return "".join(f"{line}\n\n" for line in lines)


# ----------------------------------------------------------------------------- the load sweep


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog="load_sweep.py", description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    add_users_options(parser)
    add_options(parser, SweepConfig, only=("loads",))
    seeds = parser.add_mutually_exclusive_group()
    seeds.add_argument("--seed", type=non_negative_int, default=0, help="seed (default 0)")
    seeds.add_argument("--seeds", type=distinct_int_list,
                       help="several distinct seeds, comma-separated: a sweep per seed in OUT/seed-<S>/, "
                            "compared in OUT/SEEDS.md")
    # The sweep's own settings, each declared once in contention.sweep_config.SweepConfig.
    add_options(parser, SweepConfig, only=LEARNER_OPTIONS)
    add_world_options(parser)
    add_output_options(parser, SweepConfig)
    args = parser.parse_args(argv)
    configure_verbosity(args)
    # The arguments are checked: now the sweep and its report, with NumPy and pandas.
    import pandas as pd

    from yafs_safetail.contention.sweep_report import (
        LOAD_REPORT,
        checks_markdown,
        glance_markdown,
        seeds_markdown,
        write_table,
    )
    from yafs_safetail.results.files import write_text_atomic
    from yafs_safetail.runs.output import SWEEP_FILE
    from yafs_safetail.runs.sweep_points import point_specs

    check_methods(args)
    seed_list = args.seeds if args.seeds is not None else (args.seed,)
    several = args.seeds is not None
    config: SweepConfig = config_from_args(args, SweepConfig, base=contention_base(args, seed_list[0]))
    check_test_requests(args, config)
    # The seeds' sweeps differ in nothing else.
    configs = {seed: replace(config, base=replace(config.base, seed=seed)) for seed in seed_list}
    command = engine_free_command(invocation("experiments/load_sweep.py"), sys.argv[1:] if argv is None else argv)
    out = Path(args.out)
    if several:
        check_out(out, SEEDS_KIND, ("seed-", ".seed-"), "a multi-seed load sweep")
    else:
        check_out(out, SWEEP_KIND, ("load-", ".load-"), "a load sweep")
    # Each load of each seed is one campaign run; the tables are assembled from their folders.
    folders = {seed: f"seed-{seed}/" if several else "" for seed in seed_list}
    specs = {seed: [replace(spec, name=folders[seed] + spec.name) for spec in point_specs(configs[seed])]
             for seed in seed_list}
    frames = run_points(out, specs, args, command)
    if frames is None:
        return 1
    for seed in seed_list:
        heading = (f"Load sweep (use case {args.uc}, {args.users} users, {args.servers}, {args.links} links, "
                   f"seed {seed})")
        LOAD_REPORT.write(out / folders[seed], frames[seed], heading,
                          safetail_lines(configs[seed]) + f"`{command}`\n\n",
                          sweep_run_json(args, configs[seed], command, SWEEP_KIND, specs[seed],
                                         loads=list(config.loads)))
    if several:
        rows = pd.concat([frame.assign(seed=seed) for seed, frame in frames.items()], ignore_index=True)
        write_table(out / SEEDS_FILE, rows[["seed", *frames[seed_list[0]].columns]])
        comparison = seeds_markdown(frames)
        write_text_atomic(out / "SEEDS.md",
                          f"# Load sweep over {len(seed_list)} seeds (use case {args.uc}, {args.users} users, "
                          f"{args.servers}, {args.links} links, seeds {', '.join(map(str, seed_list))})\n\n"
                          + safetail_lines(config) + f"`{command}`\n\n" + comparison)
        write_text_atomic(out / "run.json", json.dumps({
            "package_version": __version__, **run_json_fields(), "command": command, "kind": SEEDS_KIND,
            "seeds": list(seed_list),
            "seed_folders": {str(seed): f"seed-{seed}" for seed in seed_list}}, indent=1) + "\n")
        print_result(args, out, f"{comparison}\nwritten: {out / SEEDS_FILE}")
        return 0
    frame = frames[seed_list[0]]
    print_result(args, out, f"{glance_markdown(frame)}\n{checks_markdown(frame)}\nwritten: {out / SWEEP_FILE}")
    return 0

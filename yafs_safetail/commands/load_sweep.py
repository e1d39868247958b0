"""Many users at once: every method's latency and copies against the offered load.

    python experiments/load_sweep.py --uc 1 --users 50 --loads 0.1,0.3,0.5,0.7,0.9 --seed 0 \\
        --steps-scale 1 --out results/sweep_uc1

Two SafeTails run beside the fixed methods by default, each trained at each load (its preset's
training budget × --steps-scale) and tested greedily: SafeTail, the paper's learner (§III's
target vector, Eq. 5, preset paper, copies sent all at once), and SafeTail-CA, the
contention-aware one beyond the paper (a value learner that prices each copy by the jobs it
joins, preset tuned, tied copies; docs/deviations.md D13). --learner target-vector or
--learner value runs one of them alone; --no-safetail neither.

Writes OUT/sweep.csv (one row per load and method: load, method, n_requests, p50_s, p99_s,
mean_n_selected, fallback_rate, ...), OUT/SWEEP.md (p99 and copies per load and method, the
full table and the sweep's goals, each computed, never assumed: Oracle's p99 at the highest load
at least 1.5x its p99 at the lowest, and worse than single dispatch beyond some load; each
SafeTail sending fewer copies as the load rises, its p99 at most 1.05x the best fixed method's
at every load, and below Oracle's from load 0.7), OUT/sweep.png (p99 on a log scale and copies
per request against load, both SafeTails highlighted), OUT/sweep_latency.png (p50 and p99) and
OUT/run.json (the settings and this command); see docs/contention.md.

With --seeds 0,1,2 (instead of --seed) every seed's sweep goes into OUT/seed-<S>/ as above, and
OUT/seeds.csv (every seed's sweep.csv rows, with a seed column) and OUT/SEEDS.md (each SafeTail's
p99 over the best fixed method's per seed and load, and in how many seeds each goal holds)
compare them.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pandas as pd

from yafs_safetail import __version__
from yafs_safetail.cli import (
    ArgumentParser,
    add_verbosity_options,
    configure_verbosity,
    distinct_int_list,
    invocation,
    non_negative_int,
    positive_int,
)
from yafs_safetail.contention.sweep import SweepConfig, load_point_specs
from yafs_safetail.contention.sweep_report import (
    checks_markdown,
    frame_markdown_table,
    glance_markdown,
    plot_sweep,
    seeds_markdown,
)
from yafs_safetail.contention.world import LINK_MODELS, ContentionConfig, ContentionError
from yafs_safetail.edge.scenario import DEFAULT_PLACEMENT, DEFAULT_TOPOLOGY
from yafs_safetail.methods.registry import make_baseline
from yafs_safetail.results.files import write_text_atomic
from yafs_safetail.runs.campaign import (
    STATE_FILE,
    add_engine_options,
    engine_free_command,
    run_campaign,
)
from yafs_safetail.runs.config import add_options, config_from_args
from yafs_safetail.runs.grid import RunSpec
from yafs_safetail.runs.output import SWEEP_FILE

#: With --seeds: every seed's sweep.csv rows, with a leading seed column.
SEEDS_FILE = "seeds.csv"
#: run.json's kind: one seed's sweep, and the folder of several.
SWEEP_KIND = "load_sweep"
SEEDS_KIND = "load_sweep_seeds"


def _is_sweep_folder(folder: Path, kind: str) -> bool:
    """A folder this command made for ``kind`` (one seed or several): a campaign's state file,
    and a sweep's run.json of that kind or nothing but the campaign's files and its load (or
    seed) folders (so another campaign's folder or a results folder is never written into)."""
    if not (folder / STATE_FILE).is_file():
        return False
    if not (folder / "run.json").exists():
        # Interrupted before the table was assembled: only the campaign's files and run folders.
        runs = ("seed-", ".seed-") if kind == SEEDS_KIND else ("load-", ".load-")
        return all(item.name.startswith((*runs, "campaign.", ".campaign.")) for item in folder.iterdir())
    try:
        return json.loads((folder / "run.json").read_text()).get("kind") == kind
    except (OSError, ValueError, AttributeError):
        return False


def _write_sweep(folder: Path, frame: pd.DataFrame, args: argparse.Namespace, config: SweepConfig,
                 command: str, specs: Sequence[RunSpec]) -> None:
    """One seed's sweep.csv, SWEEP.md, figures and run.json into ``folder``."""
    seed = config.base.seed
    _write_csv(folder / SWEEP_FILE, frame)
    table = frame[["load", "method", "n_requests", "p50_s", "p99_s", "mean_n_selected", "fallback_rate"]]
    write_text_atomic(folder / "SWEEP.md",
                      f"# Load sweep (use case {args.uc}, {args.users} users, {args.servers}, {args.links} links, seed {seed})\n\n"
                      + _safetail_lines(config) + f"`{command}`\n\n" + glance_markdown(frame)
                      + "\n## Every row\n\n" + frame_markdown_table(table)
                      + "\n\n## Goals\n\n" + checks_markdown(frame))
    plot_sweep(frame, folder)
    write_text_atomic(folder / "run.json", json.dumps({
        "package_version": __version__, "command": command, "kind": SWEEP_KIND,
        "use_case": args.uc, "users": args.users, "loads": list(config.loads), "seed": seed,
        "steps_scale": config.steps_scale, "target": config.target,
        "safetails": [asdict(variant) for variant in config.safetails],
        "servers": args.servers, "cancel": not args.no_cancel, "background": args.background, "links": args.links,
        "methods": list(config.methods), "test_requests": config.test_requests,
        "topology": str(args.topology),
        "placement": str(args.placement), "user_conditions": str(args.user_conditions),
        "load_runs": {spec.name.rsplit("/", 1)[-1]: spec.run_id for spec in specs}}, indent=1) + "\n")


def _write_csv(path: Path, frame: pd.DataFrame) -> None:
    write_text_atomic(path, frame.to_csv(index=False, float_format="%.6g"))


def _safetail_lines(config: SweepConfig) -> str:
    """How each SafeTail of the sweep learns and sends, one line each (none: fixed methods only)."""
    lines = [f"{variant.name}: {variant.describe()}, target `{config.target}`." for variant in config.safetails]
    return "".join(f"{line}\n\n" for line in lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog="load_sweep.py", description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--uc", type=int, choices=(1, 2, 3), default=1, help="use case (default 1)")
    parser.add_argument("--users", type=positive_int, default=50, help="users U (default 50)")
    add_options(parser, SweepConfig, only=("loads",))
    seeds = parser.add_mutually_exclusive_group()
    seeds.add_argument("--seed", type=non_negative_int, default=0, help="seed (default 0)")
    seeds.add_argument("--seeds", type=distinct_int_list,
                       help="several distinct seeds, comma-separated: a sweep per seed in OUT/seed-<S>/, "
                            "compared in OUT/SEEDS.md")
    # The sweep's own settings, each declared once in contention.sweep.SweepConfig.
    add_options(parser, SweepConfig, only=("steps_scale", "test_requests_per_load", "preset", "reward", "target",
                                           "learners", "value_networks", "dispatch"))
    parser.add_argument("--servers", choices=("queue", "refuse"), default="queue",
                        help="a full server queues copies FIFO (default) or refuses them (the paper)")
    parser.add_argument("--no-cancel", action="store_true", help="let the other copies run to the end")
    parser.add_argument("--links", choices=LINK_MODELS, default="shared",
                        help="transfers share each server's links over their duration (default) or take "
                             "the bandwidth of the level when they start (at-start, the single-user reading)")
    parser.add_argument("--background", action="store_true",
                        help="add the load trace's background tenants on top of the users' load")
    parser.add_argument("--user-conditions", default="topology",
                        help="each user's distance condition per server: topology (default), generated "
                             "(the topology's ±1 per user and server) or a JSON file (docs/contention.md)")
    add_options(parser, SweepConfig, only=("methods", "safetail"))
    parser.add_argument("--topology", type=Path, default=DEFAULT_TOPOLOGY, help="topology JSON")
    parser.add_argument("--placement", type=Path, default=DEFAULT_PLACEMENT, help="placement JSON")
    parser.add_argument("--out", type=Path, required=True, help="new output folder")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace load folders there that hold another configuration's results")
    add_engine_options(parser)
    add_verbosity_options(parser)
    args = parser.parse_args(argv)
    configure_verbosity(args)
    for name in args.methods:  # unknown names fail before anything runs
        make_baseline(name, 5, np.random.default_rng(0))
    if args.value_networks is not None and "value" not in args.learners:
        raise ContentionError(f"--value-networks {args.value_networks}: only with the value learner "
                              "(SafeTail-CA)")
    seed_list = args.seeds if args.seeds is not None else (args.seed,)
    several = args.seeds is not None
    config: SweepConfig = config_from_args(
        args, SweepConfig,
        base=ContentionConfig(use_case=args.uc, seed=seed_list[0], users=args.users,
                              queue=args.servers == "queue", cancel=not args.no_cancel,
                              background=args.background, links=args.links, topology=args.topology,
                              placement=args.placement, user_conditions=args.user_conditions))
    # The seeds' sweeps differ in nothing else.
    configs = {seed: replace(config, base=replace(config.base, seed=seed)) for seed in seed_list}
    if config.test_requests < 100:
        flag = "--test-requests" if args.test_requests_per_load is not None else f"--steps-scale {args.steps_scale}"
        raise ContentionError(f"{flag}: {config.test_requests} test requests per load; "
                              "at least 100 are needed for a p99")
    command = engine_free_command(invocation("experiments/load_sweep.py"), sys.argv[1:] if argv is None else argv)
    out = Path(args.out)
    kind = SEEDS_KIND if several else SWEEP_KIND
    if out.exists() and any(out.iterdir()) and not _is_sweep_folder(out, kind):
        what = "a multi-seed load sweep" if several else "a load sweep"
        raise ContentionError(f"--out {out}: exists and is not {what}'s folder; give a new folder")
    # Each load of each seed is one campaign run (cached by its configuration's hash,
    # resumable, on any engine); the tables are assembled from their folders.
    folders = {seed: f"seed-{seed}/" if several else "" for seed in seed_list}
    specs = {seed: [replace(spec, name=folders[seed] + spec.name) for spec in load_point_specs(configs[seed])]
             for seed in seed_list}
    result = run_campaign([spec for seed in seed_list for spec in specs[seed]], out, engine=args.engine,
                          workers=args.workers, ray_address=args.ray_address, command=command,
                          overwrite=args.overwrite)
    if result.failed:
        return 1
    frames = {}
    for seed in seed_list:
        frames[seed] = pd.concat([pd.read_csv(out / spec.name / SWEEP_FILE) for spec in specs[seed]],
                                 ignore_index=True)
        _write_sweep(out / folders[seed], frames[seed], args, configs[seed], command, specs[seed])
    if several:
        rows = pd.concat([frame.assign(seed=seed) for seed, frame in frames.items()], ignore_index=True)
        _write_csv(out / SEEDS_FILE, rows[["seed", *frames[seed_list[0]].columns]])
        comparison = seeds_markdown(frames)
        write_text_atomic(out / "SEEDS.md",
                          f"# Load sweep over {len(seed_list)} seeds (use case {args.uc}, {args.users} users, "
                          f"{args.servers}, {args.links} links, seeds {', '.join(map(str, seed_list))})\n\n"
                          + _safetail_lines(config) + f"`{command}`\n\n" + comparison)
        write_text_atomic(out / "run.json", json.dumps({
            "package_version": __version__, "command": command, "kind": SEEDS_KIND, "seeds": list(seed_list),
            "seed_folders": {str(seed): f"seed-{seed}" for seed in seed_list}}, indent=1) + "\n")
        print(comparison)
        print(f"written: {out / SEEDS_FILE}")
        return 0
    frame = frames[seed_list[0]]
    print(glance_markdown(frame))
    print(checks_markdown(frame))
    print(f"written: {out / SWEEP_FILE}")
    return 0


"""Many users at once: every method's latency and copies against the offered load.

    yafs-safetail sweep --uc 1 --users 50 --loads 0.1,0.3,0.5,0.7,0.9 --seed 0 \\
        --steps-scale 1 --out results/sweep_uc1

Two SafeTails run beside the fixed methods by default, each trained at each load (its preset's
training budget × --steps-scale) and tested greedily: SafeTail, the paper's learner (§III's
target vector, Eq. 5, preset paper, copies sent all at once), and SafeTail-CA, the
contention-aware one beyond the paper (a value learner that prices each copy by the jobs it
joins, preset tuned, tied copies; deviation D13 in the documentation). --objectives target-vector or
--objectives value runs one of them alone; --no-safetail neither.

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
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

# Light modules only until the arguments are checked (--help answers at once); the sweep, the
# campaign and the report, with NumPy and pandas behind them, are imported where they run.
from yafs_safetail import __version__
from yafs_safetail.cli import (
    ArgumentParser,
    configure_verbosity,
    invocation,
    print_result,
)
from yafs_safetail.commands.sweeps import (
    LEARNER_OPTIONS,
    add_output_options,
    add_users_options,
    add_world_options,
    check_methods,
    check_out,
    check_test_requests,
    check_value_networks,
    contention_base,
    run_points,
    safetail_lines,
    servers_word,
    sweep_run_json,
)
from yafs_safetail.contention.config import ContentionConfig
from yafs_safetail.runs.engine_options import engine_free_command
from yafs_safetail.runs.sweep_config import SweepConfig
from yafs_safetail.settings.options import add_list_options, add_options, config_from_args
from yafs_safetail.versions import run_json_fields

#: With --seeds: every seed's sweep.csv rows, with a leading seed column.
SEEDS_FILE = "seeds.csv"
#: run.json's kind: one seed's sweep, and the folder of several.
SWEEP_KIND = "load_sweep"
SEEDS_KIND = "load_sweep_seeds"


def _parser() -> ArgumentParser:
    parser = ArgumentParser(prog="load_sweep.py", description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    add_users_options(parser)
    add_options(parser, SweepConfig, only=("loads",))
    seeds = parser.add_mutually_exclusive_group()
    add_options(seeds, ContentionConfig, only=("seed",))
    add_list_options(seeds, ContentionConfig, {"seed": "--seeds"},
                     seed={"help": "several distinct seeds, comma-separated: a sweep per seed in OUT/seed-<S>/, "
                                   "compared in OUT/SEEDS.md"})
    # The sweep's own settings, each declared once in runs.sweep_config.SweepConfig.
    add_options(parser, SweepConfig, only=LEARNER_OPTIONS)
    add_world_options(parser)
    add_output_options(parser, SweepConfig)
    return parser


def sweep_configs(args: argparse.Namespace) -> dict[int, SweepConfig]:
    """Each seed's sweep from the parsed options (the seeds' sweeps differ in nothing else)."""
    check_value_networks(args)
    seed_list = args.seeds if args.seeds is not None else (args.seed,)
    config: SweepConfig = config_from_args(args, SweepConfig, base=contention_base(args, seed_list[0]))
    config = check_methods(config)
    check_test_requests(args, config)
    return {seed: replace(config, base=replace(config.base, seed=seed)) for seed in seed_list}


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    configure_verbosity(args)
    # The arguments are checked: now the sweep and its report, with NumPy and pandas.
    import pandas as pd

    from yafs_safetail.results.files import write_text_atomic
    from yafs_safetail.results.sweep_report import (
        LOAD_REPORT,
        checks_markdown,
        glance_markdown,
        seeds_markdown,
        write_table,
    )
    from yafs_safetail.runs.output import SWEEP_FILE
    from yafs_safetail.runs.sweep_points import point_specs

    configs = sweep_configs(args)
    seed_list = tuple(configs)
    several = args.seeds is not None
    config = configs[seed_list[0]]
    base = config.base
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
        heading = (f"Load sweep (use case {base.use_case}, {base.users} users, {servers_word(base)}, "
                   f"{base.links} links, seed {seed})")
        LOAD_REPORT.write(out / folders[seed], frames[seed], heading,
                          safetail_lines(configs[seed]) + f"`{command}`\n\n",
                          sweep_run_json(configs[seed], command, SWEEP_KIND, specs[seed],
                                         loads=list(config.loads)))
    if several:
        rows = pd.concat([frame.assign(seed=seed) for seed, frame in frames.items()], ignore_index=True)
        write_table(out / SEEDS_FILE, rows[["seed", *frames[seed_list[0]].columns]])
        comparison = seeds_markdown(frames)
        write_text_atomic(out / "SEEDS.md",
                          f"# Load sweep over {len(seed_list)} seeds (use case {base.use_case}, {base.users} users, "
                          f"{servers_word(base)}, {base.links} links, seeds {', '.join(map(str, seed_list))})\n\n"
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

"""Run a grid of experiments as one campaign: each run computed once, resumable, in parallel.

    yafs-safetail campaign --grid grid.toml --out results/campaign1 --workers 2
    yafs-safetail campaign --grid grid.toml --out results/campaign1 --engine ray
    yafs-safetail campaign --grid grid.toml --out results/campaign1 --ray-address head:6379

The grid (TOML, YAML or JSON) sets ExperimentConfig fields in ``[base]`` and lists the values
to combine in ``[axes]`` (``python -m pydoc yafs_safetail.runs.grid``; campaigns in the
documentation). A relative path in the grid is read from the grid file's folder, else is the
packaged default of that name (topologies/paper_5servers.json...). The whole grid is checked
before any run starts: each bad entry is one error line, the exit status 2, and nothing is
written. Each run goes
into ``OUT/<axis values>-<run id>/``; rerunning the same command resumes where it stopped and
recomputes nothing finished. Progress goes to stderr (none with --quiet but failed runs) and
``OUT/campaign.log``, each run's state to ``OUT/campaign.json``, each run's own log to its
``run.log``. At the end the latency of every method of the finished runs (median, p90, p95,
p99, servers per request; mean over seeds and 95% bootstrap interval), one table per value of
the grid's axes other than the seed, goes to ``OUT/latency.md`` and ``OUT/latency.csv`` and, with
``results: OUT``, to stdout (--quiet: ``OUT`` alone); the exit status is 1 when a run failed.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from yafs_safetail.cli import (
    EXIT_BAD_INPUT,
    ArgumentParser,
    add_plumbing,
    add_verbosity_options,
    configure_verbosity,
    invocation,
    print_result,
)
from yafs_safetail.runs.engine_options import (
    add_engine_options,
    engine_free_command,
    engine_keywords,
)


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog="campaign.py", description=__doc__,
                     formatter_class=argparse.RawDescriptionHelpFormatter)
    add_plumbing(parser, "--grid", type=Path, required=True, help="the grid file (.toml, .yaml, .json)")
    add_plumbing(parser, "--out", type=Path, required=True, help="the campaign folder")
    add_plumbing(parser, "--overwrite", action="store_true",
                 help="replace run folders that hold another configuration")
    add_engine_options(parser)
    add_verbosity_options(parser)
    args = parser.parse_args(argv)
    configure_verbosity(args)
    # The arguments are checked: now the grid and the campaign, with NumPy and pandas.
    from yafs_safetail.runs.campaign import run_campaign
    from yafs_safetail.runs.grid import GridError, load_grid

    try:
        specs = load_grid(args.grid)  # checked whole before --out is touched
    except GridError as error:
        # Every bad entry on its own line (run_cli would join them into one).
        for line in error.lines:
            print(f"error: {line}", file=sys.stderr)
        return EXIT_BAD_INPUT
    command = engine_free_command(invocation("experiments/campaign.py"), sys.argv[1:] if argv is None else argv)
    result = run_campaign(specs, args.out, command=command, **engine_keywords(args))
    from yafs_safetail.results.seed_tables import write_campaign_latency
    from yafs_safetail.runs.campaign import DONE, EARLIER

    table = write_campaign_latency(args.out, {run.spec.name: run.spec.settings for run in result.runs},
                                   [run.spec.name for run in result.runs if run.status in (DONE, EARLIER)])
    if result.failed:
        return 1
    # The table of runs went to stderr with the progress; stdout gets the latency and the folder.
    print_result(args, args.out, f"{table}results: {args.out}")
    return 0


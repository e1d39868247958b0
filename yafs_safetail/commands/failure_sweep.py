"""Servers that fail: every method's success rate, p99 and energy per request as failures rise.

    yafs-safetail failure-sweep --uc 1 --seed 0 --steps-scale 1 --out results/failures_uc1

At one offered load (--load, default 0.1), each server goes down and comes back (exponential
times to failure and to repair, mean repair --mttr-s) with a stationary probability of being
down that rises through --failure-levels (default 0,0.05,0.1,0.2,0.3; 0 is the world without
failures). A copy on a server that is down, or that goes down before its reply has left, is
lost: the user hears nothing and takes the on-device fallback after its time-out (--timeout-s,
default the world's worst-case latency of a live uncontended copy). Both SafeTails (the paper's,
and SafeTail-CA unless --objectives says otherwise) are trained at each level and tested greedily;
Oracle, Rand/MinLoad/MinProp with x = 1, 2, 3, Hedge and Tied run on the same test world.

Writes OUT/failure_sweep.csv (one row per level and method: failure_level, load, method,
success_rate, p99_s, energy_j_per_request, the shares of requests that ended all lost, timed
out or all refused, ...), OUT/FAILURE_SWEEP.md (success rate, p99 and energy per request per
level and method, every row, and the goals, each computed: Oracle's and the x >= 2 baselines'
success rate above every x = 1 baseline's at every level with failures; each SafeTail's energy
per request below Oracle's at every level), OUT/failure_sweep.png (the three against the
level) and OUT/run.json. Each level is one campaign run (OUT/level-<p>/): rerunning resumes,
--workers spreads the levels; see the contention world in the documentation.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

# Light modules only until the arguments are checked (--help answers at once); the sweep and its
# report, with NumPy and pandas behind them, are imported in main.
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
from yafs_safetail.runs.sweep_config import FailureSweepConfig
from yafs_safetail.settings.options import add_options, config_from_args

#: run.json's kind of a failure sweep's folder.
FAILURE_SWEEP_KIND = "failure_sweep"


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog="failure_sweep.py", description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    add_users_options(parser)
    # The sweep's own settings, each declared once in runs.sweep_config.FailureSweepConfig.
    add_options(parser, FailureSweepConfig, only=("failure_levels", "load", "mttr_s", "timeout_s"))
    add_options(parser, ContentionConfig, only=("seed",))
    add_options(parser, FailureSweepConfig, only=LEARNER_OPTIONS)
    add_world_options(parser)
    add_output_options(parser, FailureSweepConfig)
    args = parser.parse_args(argv)
    configure_verbosity(args)
    # The arguments are checked: now the sweep and its report, with NumPy and pandas.
    from yafs_safetail.results.sweep_report import (
        FAILURE_REPORT,
        checks_markdown,
        failure_checks,
    )
    from yafs_safetail.runs.sweep_points import point_specs

    check_value_networks(args)
    config: FailureSweepConfig = config_from_args(args, FailureSweepConfig, base=contention_base(args, args.seed))
    config = check_methods(config)
    check_test_requests(args, config)
    base = config.base
    command = engine_free_command(invocation("experiments/failure_sweep.py"),
                                  sys.argv[1:] if argv is None else argv)
    out = Path(args.out)
    check_out(out, FAILURE_SWEEP_KIND, ("level-", ".level-"), "a failure sweep")
    specs = {config.base.seed: point_specs(config)}
    frames = run_points(out, specs, args, command)
    if frames is None:
        return 1
    frame = frames[config.base.seed]
    heading = (f"Failure sweep (use case {base.use_case}, {base.users} users, load {config.load:g}, mean repair "
               f"{config.mttr_s:g} s, {servers_word(base)}, {base.links} links, seed {base.seed})")
    timeout = (f"a time-out of {config.timeout_s:g} s" if config.timeout_s is not None
               else "the default time-out (the world's worst-case latency of a live uncontended copy)")
    preface = (f"Each server down with the stationary probability `failure_level`; a lost copy is known "
               f"only by {timeout}; level 0 has no failures and no time-out.\n\n")
    FAILURE_REPORT.write(out, frame, heading, preface + safetail_lines(config) + f"`{command}`\n\n",
                         sweep_run_json(config, command, FAILURE_SWEEP_KIND, specs[config.base.seed],
                                        failure_levels=list(config.points), load=config.load,
                                        mttr_s=config.mttr_s, timeout_s=config.timeout_s))
    print_result(args, out, f"{FAILURE_REPORT.glance(frame)}\n{checks_markdown(frame, failure_checks)}\n"
                            f"written: {out / FAILURE_REPORT.table_file}")
    return 0

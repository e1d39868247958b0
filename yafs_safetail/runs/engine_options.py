"""Where a campaign's runs execute, as command-line options: ``--workers``, ``--engine`` and
``--ray-address``, and the command line a campaign records without them.

Standard library only, so that the campaign scripts answer ``--help`` and bad arguments before
anything heavy loads (runs.campaign and runs.engines run the campaign).
"""

from __future__ import annotations

import argparse
import shlex
from collections.abc import Sequence

#: Where runs execute: spawned local worker processes, or Ray tasks (runs.engines).
ENGINES = ("local", "ray")

#: Command-line options that choose where runs execute, never what they compute.
ENGINE_OPTIONS = {"--workers": True, "--engine": True, "--ray-address": True}


def add_engine_options(parser: argparse.ArgumentParser) -> None:
    """``--workers``, ``--engine`` and ``--ray-address`` (shared by every campaign script)."""
    parser.add_argument("--workers", type=int, default=None,
                        help="runs at a time (default 1 locally, every CPU of a Ray cluster)")
    parser.add_argument("--engine", choices=ENGINES, default="local",
                        help="local worker processes (default) or Ray (pip install -e .[ray])")
    parser.add_argument("--ray-address", default=None, metavar="HOST:PORT",
                        help="run on this existing Ray cluster (implies --engine ray)")


def engine_free_command(program: Sequence[str], argv: Sequence[str]) -> str:
    """The command line without the engine options, as recorded in every run's ``run.json``:
    the same campaign on another engine or worker count writes the same bytes.

    Args:
        program: the words that started the command (``cli.invocation``: ``python
            experiments/campaign.py`` or ``yafs-safetail campaign``).
        argv: its arguments.
    """
    kept: list[str] = []
    skip = False
    for arg in argv:
        if skip:
            skip = False
            continue
        option, eq, _ = arg.partition("=")
        if option in ENGINE_OPTIONS:
            skip = not eq and ENGINE_OPTIONS[option]
            continue
        kept.append(arg)
    return shlex.join([*program, *kept])

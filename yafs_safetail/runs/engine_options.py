"""Where a campaign's runs execute, as command-line options: ``--workers``, ``--engine`` and
``--ray-address``, and the command line a campaign records without them; and how many local
workers a campaign (or the calibration) starts when ``--workers`` is not given.

Standard library only, so that the campaign scripts answer ``--help`` and bad arguments before
anything heavy loads (runs.campaign and runs.engines run the campaign).
"""

from __future__ import annotations

import argparse
import logging
import os
import shlex
from collections.abc import Sequence
from pathlib import Path
from typing import TypedDict

log = logging.getLogger(__name__)

#: Memory one local campaign worker needs at most: a spawned process that imports TensorFlow
#: once and then runs run after run at the presets' full budgets, figures on. Measured (peak
#: resident set, ``/usr/bin/time -v``, 2026-11-27): 0.74-0.79 GB for one run of UC1, UC2 or
#: UC3 (paper preset), 0.88 GB for a worker that ran UC1-3 x paper, paper-literal and tuned
#: one after another; rounded up to 1 GB for the campaign's own process and the page cache.
#: A grid of bigger runs (``steps_scale`` > 1, more servers) should pass ``--workers``.
RUN_WORKER_BYTES = 1_000_000_000
#: The same for a calibration worker (NumPy worlds, no TensorFlow): measured 0.12 GB scoring
#: candidates on the ten world-calibration seeds; rounded up to 0.2 GB.
CALIBRATION_WORKER_BYTES = 200_000_000
#: Where Linux says how much memory can still be had without swapping, and a cgroup v2's
#: limit and use (a container's share of the machine).
MEMINFO_FILE = Path("/proc/meminfo")
CGROUP_DIR = Path("/sys/fs/cgroup")


def default_workers_help(per_worker_bytes: float = RUN_WORKER_BYTES) -> str:
    """How ``--workers`` defaults, for the help texts (:func:`automatic_workers`)."""
    return (f"one per usable CPU while each has {per_worker_bytes / 1e9:g} GB of the available "
            "memory, at least 1 (campaigns in the documentation)")

#: Where runs execute: spawned local worker processes, or Ray tasks (runs.engines).
ENGINES = ("local", "ray")

#: Command-line options that choose where runs execute, never what they compute.
ENGINE_OPTIONS = {"--workers": True, "--engine": True, "--ray-address": True}


def add_engine_options(parser: argparse.ArgumentParser) -> None:
    """``--workers``, ``--engine`` and ``--ray-address`` (shared by every campaign script)."""
    parser.add_argument("--workers", type=int, default=None,
                        help=f"runs at a time, each in its own process (default locally: "
                             f"{default_workers_help()}; with Ray: every CPU of the cluster); "
                             "fewer uses less memory; the results are the same")
    parser.add_argument("--engine", choices=ENGINES, default="local",
                        help="local worker processes (default) or Ray (pip install -e .[ray])")
    parser.add_argument("--ray-address", default=None, metavar="HOST:PORT",
                        help="run on this existing Ray cluster (implies --engine ray)")


class EngineKeywords(TypedDict):
    """``runs.campaign.run_campaign``'s keywords for where and how its runs go."""

    engine: str
    workers: int | None
    ray_address: str | None
    overwrite: bool


def engine_keywords(args: argparse.Namespace) -> EngineKeywords:
    """What :func:`add_engine_options` (and a command's ``--overwrite``) parsed, as
    ``run_campaign``'s keywords: every campaign command starts it the same way."""
    return EngineKeywords(engine=args.engine, workers=args.workers, ray_address=args.ray_address,
                          overwrite=args.overwrite)


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


def usable_cpus() -> int:
    """The CPUs this process may run on (its affinity mask: a ``taskset`` or a container's
    cpuset), else the machine's count; at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # no affinity call on this system
        return max(1, os.cpu_count() or 1)


def _meminfo_available_bytes() -> int | None:
    try:
        for line in MEMINFO_FILE.read_text().splitlines():
            name, _, value = line.partition(":")
            if name == "MemAvailable":
                return int(value.split()[0]) * 1024  # kB
    except (OSError, ValueError, IndexError):
        pass
    try:  # no /proc (not Linux): the free pages, a lower bound of what can be had
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None


def _cgroup_left_bytes() -> int | None:
    """What a cgroup v2 memory limit leaves this process's group (None: no limit)."""
    try:
        limit = (CGROUP_DIR / "memory.max").read_text().strip()
        if limit == "max":
            return None
        return max(0, int(limit) - int((CGROUP_DIR / "memory.current").read_text().strip()))
    except (OSError, ValueError):
        return None


def available_memory_bytes() -> int | None:
    """Memory that new processes can still get without swapping: /proc/meminfo's MemAvailable
    (or the free pages), less if a cgroup limit leaves less; None when neither is known."""
    found = [value for value in (_meminfo_available_bytes(), _cgroup_left_bytes()) if value is not None]
    return min(found) if found else None


def automatic_workers(per_worker_bytes: float = RUN_WORKER_BYTES) -> tuple[int, str]:
    """How many local workers to start: one per usable CPU, no more than the available memory
    holds at ``per_worker_bytes`` each, at least 1.

    Returns:
        The number and a line saying why (logged).
    """
    cpus = usable_cpus()
    memory = available_memory_bytes()
    if memory is None:
        return cpus, f"{cpus} usable CPU(s); available memory unknown"
    by_memory = int(memory // per_worker_bytes)
    workers = max(1, min(cpus, by_memory))
    return workers, (f"{cpus} usable CPU(s), {memory / 1e9:.1f} GB of memory available at "
                     f"{per_worker_bytes / 1e9:g} GB per worker")


def local_workers(requested: int | None, per_worker_bytes: float = RUN_WORKER_BYTES) -> int:
    """``--workers`` if given, else :func:`automatic_workers` (and a log line saying why)."""
    if requested is not None:
        return requested
    workers, why = automatic_workers(per_worker_bytes)
    log.info("%d worker(s) at a time: %s (--workers N for fewer)", workers, why)
    return workers

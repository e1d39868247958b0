"""Where a campaign's runs execute: local worker processes, or Ray (one machine or a cluster).

Every engine runs :func:`execute` on a :class:`RunTask` and hands back a :class:`RunResult`;
the campaign never has more runs under way than the engine's ``slots``. A run's folder ends up
in the campaign folder byte for byte the same whichever engine ran it: the local engine's
workers write it there themselves (through ``run_experiment``'s staging and rename), Ray's
tasks write it on their own node and send it back as a tar archive that the driver unpacks
through the same staging and rename, so the campaign folder need not be shared between nodes.

This module picks the engine (:func:`make_engine`) and re-exports what the engines share: the
task and its execution (``runs.run_tasks``), the local engine (``runs.local_engine``) and Ray's
(``runs.ray_engine``).
"""

from __future__ import annotations

import importlib.util
from collections.abc import Iterable
from typing import Any

from yafs_safetail.runs.engine_options import ENGINES, local_workers
from yafs_safetail.runs.local_engine import KILL_RUN_ENV, LocalEngine
from yafs_safetail.runs.ray_engine import RAY_MISSING, RAY_TASK_RETRIES, RayEngine, unpack
from yafs_safetail.runs.run_tasks import (
    ONE_CORE_ENV,
    RUN_KINDS,
    RunResult,
    RunTask,
    execute,
    one_line,
)

__all__ = ["ONE_CORE_ENV", "RUN_KINDS", "KILL_RUN_ENV", "RAY_TASK_RETRIES", "RunTask", "RunResult",
           "LocalEngine", "RayEngine", "execute", "one_line", "unpack", "check_engine", "make_engine", "cancel_all"]


def check_engine(engine: str, workers: int | None, ray_address: str | None) -> None:
    """What :func:`make_engine` would refuse, found without starting anything (a campaign checks
    it before it writes a file): a bad ``--workers``, an unknown engine, Ray asked for but not
    installed.

    Raises:
        ValueError: one line naming the option.
    """
    if workers is not None and (isinstance(workers, bool) or workers < 1):
        raise ValueError(f"--workers: expected a positive integer, got {workers!r}")
    if engine == "ray" or ray_address:
        if importlib.util.find_spec("ray") is None:
            raise ValueError(RAY_MISSING)
    elif engine != "local":
        raise ValueError(f"--engine: unknown engine {engine!r}; valid: {', '.join(ENGINES)}")


def make_engine(engine: str, workers: int | None, ray_address: str | None) -> LocalEngine | RayEngine:
    """The engine named on the command line (``--engine``, ``--workers``, ``--ray-address``)."""
    check_engine(engine, workers, ray_address)
    if engine == "ray" or ray_address:
        return RayEngine(workers, ray_address)
    return LocalEngine(local_workers(workers))


def cancel_all(engine: LocalEngine | RayEngine, handles: Iterable[Any]) -> None:
    """Best effort: stop runs that are under way (Ctrl-C, SIGTERM)."""
    if isinstance(engine, RayEngine):
        for handle in handles:
            try:
                engine._ray.cancel(handle, force=True)
            except Exception:  # already finished or gone: nothing to stop
                pass

"""What every engine executes: a run as a task (:class:`RunTask`), what became of it
(:class:`RunResult`), and :func:`execute`, which runs one by its kind (``RUN_KINDS``) and
returns its failure as one line, never raises. Both engines (``runs.local_engine``,
``runs.ray_engine``) start their workers with :func:`init_worker`.
"""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from yafs_safetail.runs.grid import RunSpec, config_run_id, make_config
from yafs_safetail.stopping import raise_terminated

#: Each run of a campaign computes on one core: the campaign's parallelism is its runs, and a
#: run whose TensorFlow and BLAS spread over every core would fight the other workers for
#: them (measured: two such workers were slower than one, docs/campaigns.md). Set in every
#: worker before TensorFlow loads; an explicit value in the environment wins.
ONE_CORE_ENV = {"TF_NUM_INTRAOP_THREADS": "1", "TF_NUM_INTEROP_THREADS": "1", "OMP_NUM_THREADS": "1",
                "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "TF_CPP_MIN_LOG_LEVEL": "2"}


@dataclass(frozen=True)
class RunTask:
    """One run to execute: the spec, its folder, and how to record it."""

    spec: RunSpec
    out_dir: str
    command: str = ""
    overwrite: bool = False


@dataclass(frozen=True)
class RunResult:
    """What became of a run: ``error`` is empty on success, else one line saying why."""

    name: str
    run_id: str
    error: str
    wall_s: float
    archive: bytes | None = None  # the run's folder as a tar archive (Ray only)
    node: str = ""  # the Ray node that ran it (its id's first 8 hex digits); empty locally


def one_line(error: BaseException) -> str:
    """An error as one line: bad input as its own message, anything else with its type."""
    message = " ".join(str(error).split())
    if isinstance(error, ValueError | OSError) and message:
        return message
    return f"{type(error).__name__}: {message}" if message else type(error).__name__


def _run_experiment(task: RunTask) -> None:
    from yafs_safetail.runs import checkpoint
    from yafs_safetail.runs.experiment import run_experiment

    config = make_config(task.spec, Path(task.out_dir), task.command, task.overwrite)
    # A run of this campaign interrupted while training goes on from its checkpoint (same run
    # id: the same configuration and code); any other starts over.
    if checkpoint.matches(Path(task.out_dir).resolve(), config_run_id(config)):
        config = replace(config, resume=True)
    run_experiment(config)


def _run_sweep_point(task: RunTask) -> None:
    from yafs_safetail.runs.sweep_points import run_sweep_point

    run_sweep_point(task.spec, Path(task.out_dir), task.command, task.overwrite)


#: What executes each kind of run (``RunSpec.kind``); each imports its machinery when it runs.
RUN_KINDS: dict[str, Callable[[RunTask], None]] = {
    "experiment": _run_experiment,
    "load_point": _run_sweep_point,
    "failure_point": _run_sweep_point,
}


def execute(task: RunTask) -> RunResult:
    """Run one experiment (or one point of a load or failure sweep); a failure is returned, never raised,
    so the others go on."""
    started = time.perf_counter()
    try:
        runner = RUN_KINDS.get(task.spec.kind)
        if runner is None:
            raise ValueError(f"run {task.spec.name}: unknown kind {task.spec.kind!r}; "
                             f"valid: {', '.join(RUN_KINDS)}")
        runner(task)
        error = ""
    except Exception as exc:  # any run's failure, bug or bad input, is that run's alone
        error = one_line(exc)
    return RunResult(task.spec.name, task.spec.run_id, error, time.perf_counter() - started)


def init_worker() -> None:
    from yafs_safetail.runs.workers import end_with_parent

    # Ctrl-C reaches the whole process group; it is the campaign's to handle (it stops the
    # workers with SIGTERM). SIGTERM unwinds the run, which removes its staging folder.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, raise_terminated)
    for name, value in ONE_CORE_ENV.items():
        os.environ.setdefault(name, value)
    end_with_parent()

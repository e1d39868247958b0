"""The local engine: spawned worker processes on this machine, each watched on its own (a killed
one fails its run alone; a fresh worker takes the next run)."""

from __future__ import annotations

import contextlib
import multiprocessing
import multiprocessing.connection
import os
import signal
import time
from collections.abc import Collection
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Any

from yafs_safetail.runs.run_tasks import RunResult, RunTask, execute, init_worker

#: Fault injection for the tests only (tests/test_faults.py, docs/faults.md): a local worker
#: given the run named here kills itself with SIGKILL, as the out-of-memory killer would, at
#: the worst moment: its results all written, just before they would be renamed into place.
#: Unset (always, outside those tests), it does nothing.
KILL_RUN_ENV = "YAFS_SAFETAIL_TEST_KILL_RUN"


def _kill_before_publishing() -> None:
    from yafs_safetail.runs.output import StagedOutput

    def killed(output: StagedOutput) -> None:
        os.kill(os.getpid(), signal.SIGKILL)

    # This worker dies with the patch; the next worker is a fresh interpreter.
    setattr(StagedOutput, "publish", killed)  # noqa: B010


def _worker_loop(connection: Connection) -> None:
    """A local worker: run each task the campaign sends until it sends None (or goes away)."""
    from yafs_safetail.stopping import Terminated

    init_worker()
    try:
        while True:
            try:
                task = connection.recv()
            except EOFError:  # the campaign went away
                return
            if task is None:
                return
            if os.environ.get(KILL_RUN_ENV) == task.spec.name:
                _kill_before_publishing()
            connection.send(execute(task))
    except Terminated:  # stopped by the campaign (Ctrl-C, SIGTERM): its run has unwound
        return


class _LocalWorker:
    """One spawned worker process and its end of the pipe; one run at a time."""

    def __init__(self, context: Any) -> None:
        self.connection, child = context.Pipe(duplex=True)
        self.process = context.Process(target=_worker_loop, args=(child,),
                                       name="yafs-safetail-campaign-worker")
        self.process.start()
        child.close()  # so that the worker's death reads as end of file here


@dataclass(eq=False)
class _LocalRun:
    """A run under way on a local worker (the campaign's handle for it)."""

    worker: _LocalWorker
    started_s: float


class LocalEngine:
    """``workers`` processes on this machine, each running one run after another.

    Each worker is watched on its own, so one that dies outright (SIGKILL from the
    out-of-memory killer) costs only its own run, reported with the signal; the others'
    runs go on, and a fresh worker takes the next run.
    """

    def __init__(self, workers: int) -> None:
        self.slots = workers
        # "spawn", not fork: the campaign's process may already hold TensorFlow (a grid that
        # loads a user's policy, a test suite), whose threads and locks do not survive fork.
        # A spawned worker is a fresh interpreter; it imports TensorFlow once and then runs
        # run after run, so the import is paid once per worker, not once per run.
        self._context = multiprocessing.get_context("spawn")
        self._idle: list[_LocalWorker] = []
        self._busy: list[_LocalWorker] = []

    def submit(self, task: RunTask) -> _LocalRun:
        self._idle = [worker for worker in self._idle if worker.process.is_alive()]
        worker = self._idle.pop() if self._idle else _LocalWorker(self._context)
        try:
            worker.connection.send(task)
        except OSError:  # an idle worker that died just now: a fresh one takes the run
            worker.process.join()
            worker.connection.close()
            worker = _LocalWorker(self._context)
            worker.connection.send(task)
        self._busy.append(worker)
        return _LocalRun(worker, time.perf_counter())

    def wait(self, pending: Collection[Any], timeout_s: float) -> set[Any]:
        by_event: dict[Any, _LocalRun] = {}
        for run in pending:
            by_event[run.worker.connection] = by_event[run.worker.process.sentinel] = run
        ready = multiprocessing.connection.wait(list(by_event), timeout=timeout_s)
        return {by_event[event] for event in ready}

    def result(self, handle: _LocalRun, task: RunTask) -> RunResult:
        worker = handle.worker
        self._busy.remove(worker)
        try:
            if worker.connection.poll():
                result: RunResult = worker.connection.recv()
                self._idle.append(worker)
                return result
        except (EOFError, OSError):  # the worker died before it could answer
            pass
        from yafs_safetail.runs.workers import how_it_ended

        worker.process.join()
        worker.connection.close()
        return RunResult(task.spec.name, task.spec.run_id,
                         f"its worker process (pid {worker.process.pid}) "
                         f"{how_it_ended(worker.process.exitcode)}; nothing of it was kept, "
                         "the same command again runs it", time.perf_counter() - handle.started_s)

    def close(self, interrupted: bool = False) -> None:
        workers = self._idle + self._busy
        for worker in workers:
            if interrupted:
                # SIGTERM unwinds a worker's run (its staging folder removed).
                worker.process.terminate()
            else:
                with contextlib.suppress(OSError):
                    worker.connection.send(None)
        for worker in workers:
            worker.process.join()
            worker.connection.close()
        self._idle, self._busy = [], []

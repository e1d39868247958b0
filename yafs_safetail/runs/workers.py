"""The baselines' test phase in forked worker processes while the main process trains SafeTail.

A method's simulation depends only on the world and its own seeded generator, so running the
baselines in other processes gives the same rows and files as running everything in one.
Forking (rather than spawning) shares the worlds without pickling them and starts at once; a
worker never touches TensorFlow. :class:`ForkedWorker` is such a process sending one outcome
back; the figures process (``runs.figures_worker``) is one too.
"""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import logging
import multiprocessing
import signal
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

import pandas as pd

from yafs_safetail.edge.world import EdgeWorld
from yafs_safetail.logs import Phase
from yafs_safetail.methods.policy import Policy
from yafs_safetail.methods.registry import UserMethod, make_baseline, method_rng
from yafs_safetail.record import records_frame
from yafs_safetail.sim.runner import simulate

_PR_SET_PDEATHSIG = 1  # linux/prctl.h

#: The signals a worker handles its own way (:func:`become_worker`); blocked across the fork.
_WORKER_SIGNALS = frozenset({signal.SIGTERM, signal.SIGINT})

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class MethodsJob:
    """The test phase of some non-learning methods: everything a worker needs (inherited by fork).

    Attributes:
        names: built-in method names, run in this order.
        user_methods: users' policies (``--method``), run after the built-in ones.
        seed: the run's seed (each method's generator derives from it and the method's name).
        world: the test phase's world.
        step_interval_s: time between requests.
        yafs_dir: where the YAFS CSVs go (None: not written).
        episode_steps: α_s, for the rows' episode numbers.
        progress_label: names the job's one logged phase, every method's requests together
            (None: nothing logged).
        bar: also show a progress bar (only where the job runs in the terminal's own process).
    """

    names: tuple[str, ...]
    user_methods: tuple[UserMethod, ...]
    seed: int
    world: EdgeWorld
    step_interval_s: float
    yafs_dir: Path | None
    episode_steps: int
    progress_label: str | None
    bar: bool = False

    def policies(self) -> list[Policy]:
        n = self.world.n_servers
        reading = self.world.settings.baseline_reading
        made = [make_baseline(name, n, method_rng(self.seed, name), reading) for name in self.names]
        return made + [m.make(n, method_rng(self.seed, m.name)) for m in self.user_methods]

    def run(self) -> tuple[list[pd.DataFrame], float]:
        """Simulate each method; its request rows (in order) and the wall time."""
        started = time.perf_counter()
        policies = self.policies()
        if self.progress_label is None:
            phase: contextlib.AbstractContextManager[Phase | None] = contextlib.nullcontext()
        else:
            phase = Phase(self.progress_label, len(policies) * self.world.n_steps, bar=self.bar, logger=log)
        frames = []
        with phase as progress:
            for policy in policies:
                method_started = time.perf_counter()
                records = simulate(
                    self.world, policy, self.step_interval_s,
                    None if self.yafs_dir is None else self.yafs_dir / f"{policy.name}_test",
                    progress,
                )
                frames.append(records_frame(records, "test", self.episode_steps, self.world.movement))
                log.debug("%s test: %d requests in %.2f s", policy.name, len(records),
                          time.perf_counter() - method_started)
        return frames, time.perf_counter() - started

    @property
    def method_names(self) -> list[str]:
        return [*self.names, *(m.name for m in self.user_methods)]


def end_with_parent() -> None:
    """Ask Linux to send this worker SIGTERM when its parent dies (even by SIGKILL), so a
    killed run leaves no orphan process; elsewhere the parent's own cleanup has to do."""
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
        except (OSError, AttributeError):
            pass


def how_it_ended(exitcode: int | None) -> str:
    """How a worker process that sent no result ended, for a one-line error."""
    if exitcode is not None and exitcode < 0:
        try:
            name = f" ({signal.Signals(-exitcode).name})"
        except ValueError:
            name = ""
        return f"was killed by signal {-exitcode}{name}"
    return f"ended without a result (exit status {exitcode})"


class WorkerDied(ChildProcessError):
    """A baseline worker process that died without a result (killed, e.g. by the
    out-of-memory killer's SIGKILL): one line naming it and the signal."""


def become_worker() -> None:
    """What a forked process does first: it is stopped by SIGTERM (``stop()``) and must die at
    once, not unwind the parent's handlers it inherited through fork; Ctrl-C is the parent's to
    handle; and it ends with its parent."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, _WORKER_SIGNALS)  # one sent meanwhile acts now
    end_with_parent()


def send_outcome(sender: Connection, work: Callable[[], object], worker_name: str) -> None:
    """Do ``work`` and send the parent ``(True, result)``, or ``(False, exception)`` for any
    failure (one that does not pickle becomes a RuntimeError naming ``worker_name``)."""
    outcome: tuple[bool, object]
    try:
        outcome = (True, work())
    except BaseException as error:  # every failure goes back to the parent
        outcome = (False, error)
    try:
        sender.send(outcome)
    except Exception as error:  # e.g. an exception that does not pickle
        sender.send((False, RuntimeError(f"{worker_name}: {type(error).__name__}: {error}")))
    sender.close()


def _worker_main(job: MethodsJob, sender: Connection) -> None:
    become_worker()
    send_outcome(sender, job.run, "baseline worker")


def can_fork() -> bool:
    """Whether this process can fork workers: ``fork`` exists here, and this process is not
    daemonic (e.g. a ``multiprocessing.Pool`` worker, which may not have children)."""
    return "fork" in multiprocessing.get_all_start_methods() and not multiprocessing.current_process().daemon


class ForkedWorker:
    """A forked process running ``target(*args, its end of the pipe)``, which sends one outcome
    back through that end (:func:`send_outcome`); with ``duplex`` it also reads from it."""

    def __init__(self, target: Callable[..., None], args: tuple[Any, ...], name: str,
                 duplex: bool = False) -> None:
        context = multiprocessing.get_context("fork")
        self._channel, child_end = context.Pipe(duplex=duplex)
        self._process = context.Process(target=target, args=(*args, child_end), daemon=True, name=name)
        # Until become_worker() the child has the parent's handlers: a SIGTERM (stop()) in that
        # instant would raise the run's Terminated in the child, which either unwinds the
        # parent's stack there or is swallowed (in an at-fork hook) so that the child never
        # ends. Blocked across the fork, it waits for the child's own handling.
        unblocked = signal.pthread_sigmask(signal.SIG_BLOCK, _WORKER_SIGNALS)
        try:
            self._process.start()
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, unblocked)
        child_end.close()

    def _outcome(self, who: str, then: str) -> Any:
        """Wait for the process's outcome; re-raises its exception.

        Raises:
            WorkerDied: the process ended without one (killed): ``{who} was killed by signal
                ...; {then}``.
        """
        try:
            ok, payload = self._channel.recv()
        except EOFError:
            self._process.join()
            raise WorkerDied(f"{who} {how_it_ended(self._process.exitcode)}; {then}") from None
        self._process.join()
        if not ok:
            raise payload
        return payload

    def stop(self) -> None:
        """End the process if it is still running (the run failed) and free the pipe."""
        if self._process.is_alive():
            self._process.terminate()
            self._process.join()
        self._channel.close()


class MethodsWorker(ForkedWorker):
    """A forked process running a :class:`MethodsJob`."""

    def __init__(self, job: MethodsJob) -> None:
        self.job = job
        super().__init__(_worker_main, (job,), "yafs-safetail-baselines")
        log.debug("worker process %s started: %s", self._process.pid, ", ".join(job.method_names))

    def result(self) -> tuple[list[pd.DataFrame], float]:
        """Wait for the job's result; re-raises its exception."""
        payload = self._outcome(f"the baseline worker (pid {self._process.pid}: {', '.join(self.job.method_names)})",
                                "the run stopped and wrote no results")
        log.debug("worker process %s ended: %s in %.1f s", self._process.pid,
                  ", ".join(self.job.method_names), payload[1])
        return payload


def start_workers(job: MethodsJob, workers: int) -> list[MethodsWorker]:
    """Forks ``workers - 1`` processes (at most one per method), each taking every
    (workers - 1)-th method; none with one worker, where ``fork`` does not exist, or inside a
    daemonic process (e.g. a ``multiprocessing.Pool`` worker, which may not have children)."""
    n_methods = len(job.names) + len(job.user_methods)
    n_processes = min(workers - 1, n_methods)
    if n_processes < 1 or not can_fork():
        return []
    # Bars stay with this process (bars from several processes garble a terminal); each
    # worker's job is its own logged phase, numbered when there are several.
    return [
        MethodsWorker(dataclasses.replace(
            job, names=job.names[i::n_processes], user_methods=job.user_methods[i::n_processes], bar=False,
            progress_label=job.progress_label if job.progress_label is None or n_processes == 1
            else f"{job.progress_label} [part {i + 1}/{n_processes}]"))
        for i in range(n_processes)
    ]

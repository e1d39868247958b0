"""Where a campaign's runs execute: local worker processes, or Ray (one machine or a cluster).

Every engine runs :func:`execute` on a :class:`RunTask` and hands back a :class:`RunResult`;
the campaign never has more runs under way than the engine's ``slots``. A run's folder ends up
in the campaign folder byte for byte the same whichever engine ran it: the local engine's
workers write it there themselves (through ``run_experiment``'s staging and rename), Ray's
tasks write it on their own node and send it back as a tar archive that the driver unpacks
through the same staging and rename, so the campaign folder need not be shared between nodes.
"""

from __future__ import annotations

import contextlib
import io
import multiprocessing
import multiprocessing.connection
import os
import shutil
import signal
import tarfile
import tempfile
import time
from collections.abc import Callable, Collection, Iterable
from dataclasses import dataclass, replace
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

from yafs_safetail.runs.engine_options import ENGINES, local_workers
from yafs_safetail.runs.grid import RunSpec, config_run_id, make_config
from yafs_safetail.runs.output import StagedOutput
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


def _init_worker() -> None:
    from yafs_safetail.runs.workers import end_with_parent

    # Ctrl-C reaches the whole process group; it is the campaign's to handle (it stops the
    # workers with SIGTERM). SIGTERM unwinds the run, which removes its staging folder.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, raise_terminated)
    for name, value in ONE_CORE_ENV.items():
        os.environ.setdefault(name, value)
    end_with_parent()


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

    _init_worker()
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


def _execute_and_pack(task: RunTask) -> RunResult:
    """On a Ray node: run into a private temporary folder and return it as a tar archive."""
    import ray

    from yafs_safetail.stopping import Terminated

    _init_worker()
    # This task's own folder (mkdtemp): the only one the finally below removes.
    scratch = Path(tempfile.mkdtemp(prefix="yafs-safetail-run-"))
    terminated = False
    try:
        folder = scratch / Path(task.spec.name).name
        try:
            done = execute(replace(task, out_dir=str(folder), overwrite=False))
        except Terminated:
            # SIGTERM on a Ray node is the node (or Ray) ending this worker. Raised on, it would
            # reach Ray as the task's own error, which Ray never retries; a worker that dies is
            # retried elsewhere (max_retries). So the run unwinds, the scratch goes, and the
            # process ends as a dead worker would (below).
            terminated = True
            raise
        result = replace(done, node=ray.get_runtime_context().get_node_id()[:8])
        if result.error:
            return result
        buffer = io.BytesIO()
        with tarfile.open(fileobj=buffer, mode="w") as archive:
            for item in sorted(folder.rglob("*")):
                archive.add(item, arcname=str(item.relative_to(folder)), recursive=False)
        return replace(result, archive=buffer.getvalue())
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
        if terminated:
            os._exit(1)


def unpack(result: RunResult, task: RunTask) -> RunResult:
    """Publish a run sent back as an archive into its folder (staged, then renamed)."""
    if result.archive is None:
        return result
    try:
        output = StagedOutput(Path(task.out_dir), task.overwrite)
        with output as staging, tarfile.open(fileobj=io.BytesIO(result.archive)) as archive:
            archive.extractall(staging, filter="data")
            output.publish()
    except (OSError, ValueError, tarfile.TarError) as error:
        return replace(result, error=f"could not write the folder sent back: {one_line(error)}", archive=None)
    return replace(result, archive=None)


#: How many times Ray runs a task again after its worker process or node died.
RAY_TASK_RETRIES = 3


class RayEngine:
    """Ray tasks: a local Ray runtime with ``workers`` CPUs, or the cluster at ``address``."""

    def __init__(self, workers: int | None, address: str | None) -> None:
        try:
            import ray
        except ImportError:
            raise ValueError("--engine ray: Ray is not installed; pip install -e .[ray] "
                             "(or use the local engine)") from None
        self._ray = ray
        self._owns_runtime = not ray.is_initialized()
        if self._owns_runtime:
            env = {"env_vars": {name: os.environ.get(name, value) for name, value in ONE_CORE_ENV.items()}}
            try:
                if address:
                    ray.init(address=address, runtime_env=env, log_to_driver=False)
                else:
                    # Ray starts its workers at niceness 15 by default; on a machine shared
                    # with anything else that starves the runs (measured: Ray two to three
                    # times slower than the local engine), so this runtime's workers run at 0.
                    ray.init(num_cpus=workers or 1, runtime_env=env, log_to_driver=False,
                             include_dashboard=False, _system_config={"worker_niceness": 0})
            except (ConnectionError, RuntimeError) as error:
                raise ValueError(f"--ray-address {address}: cannot connect: {one_line(error)}") from None
        cpus = int(ray.cluster_resources().get("CPU", 1))
        self.slots = min(workers, cpus) if workers else cpus
        # A task whose worker or node died (a raylet lost, the out-of-memory killer) is run
        # again elsewhere: it writes only into its own node's scratch folder and sends the
        # run back whole, so a second attempt is safe. A run's own errors are not retried
        # (execute returns them; Ray's retry_exceptions stays off).
        self._remote = ray.remote(num_cpus=1, max_retries=RAY_TASK_RETRIES)(_execute_and_pack)

    def submit(self, task: RunTask) -> Any:
        return self._remote.remote(task)

    def wait(self, pending: Collection[Any], timeout_s: float) -> set[Any]:
        done, _ = self._ray.wait(list(pending), num_returns=1, timeout=timeout_s)
        return set(done)

    def result(self, handle: Any, task: RunTask) -> RunResult:
        try:
            result: RunResult = self._ray.get(handle)
        except Exception as error:  # a task or node lost: that run's failure alone
            return RunResult(task.spec.name, task.spec.run_id, f"Ray task failed: {one_line(error)}", 0.0)
        return unpack(result, task)

    def close(self, interrupted: bool = False) -> None:
        if self._owns_runtime:
            self._ray.shutdown()


def make_engine(engine: str, workers: int | None, ray_address: str | None) -> LocalEngine | RayEngine:
    """The engine named on the command line (``--engine``, ``--workers``, ``--ray-address``)."""
    if workers is not None and (isinstance(workers, bool) or workers < 1):
        raise ValueError(f"--workers: expected a positive integer, got {workers!r}")
    if engine == "ray" or ray_address:
        return RayEngine(workers, ray_address)
    if engine != "local":
        raise ValueError(f"--engine: unknown engine {engine!r}; valid: {', '.join(ENGINES)}")
    return LocalEngine(local_workers(workers))


def cancel_all(engine: LocalEngine | RayEngine, handles: Iterable[Any]) -> None:
    """Best effort: stop runs that are under way (Ctrl-C, SIGTERM)."""
    if isinstance(engine, RayEngine):
        for handle in handles:
            try:
                engine._ray.cancel(handle, force=True)
            except Exception:  # already finished or gone: nothing to stop
                pass

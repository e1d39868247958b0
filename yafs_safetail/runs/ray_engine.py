"""The Ray engine: each run a Ray task (a local Ray runtime or a cluster), written on its own
node and sent back as a tar archive that the driver unpacks through the same staging and rename
as a local run (so the campaign folder need not be shared between nodes)."""

from __future__ import annotations

import io
import os
import shutil
import tarfile
import tempfile
from collections.abc import Collection
from dataclasses import replace
from pathlib import Path
from typing import Any

from yafs_safetail.runs.output import StagedOutput
from yafs_safetail.runs.run_tasks import (
    ONE_CORE_ENV,
    RunResult,
    RunTask,
    execute,
    init_worker,
    one_line,
)


def _execute_and_pack(task: RunTask) -> RunResult:
    """On a Ray node: run into a private temporary folder and return it as a tar archive."""
    import ray

    from yafs_safetail.stopping import Terminated

    init_worker()
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


#: What a campaign says when Ray is asked for and not installed.
RAY_MISSING = "--engine ray: Ray is not installed; pip install -e .[ray] (or use the local engine)"


class RayEngine:
    """Ray tasks: a local Ray runtime with ``workers`` CPUs, or the cluster at ``address``."""

    def __init__(self, workers: int | None, address: str | None) -> None:
        try:
            import ray
        except ImportError:
            raise ValueError(RAY_MISSING) from None
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

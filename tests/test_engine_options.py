"""How many local workers a campaign starts without --workers: the usable CPUs, as far as the
available memory holds a worker each, at least one."""

from __future__ import annotations

from pathlib import Path

import pytest

from yafs_safetail.runs import engine_options
from yafs_safetail.runs.engine_options import (
    CALIBRATION_WORKER_BYTES,
    RUN_WORKER_BYTES,
    automatic_workers,
    local_workers,
)


@pytest.fixture
def machine(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """A machine of ``cpus`` CPUs and ``available_bytes`` of MemAvailable, no cgroup limit
    unless ``cgroup`` = (limit, current) is given."""

    def make(cpus: int, available_bytes: int, cgroup: tuple[str, int] | None = None) -> None:
        meminfo = tmp_path / "meminfo"
        meminfo.write_text(f"MemTotal:       99999999 kB\nMemAvailable:   {available_bytes // 1024} kB\n")
        cgroup_dir = tmp_path / "cgroup"
        cgroup_dir.mkdir(exist_ok=True)
        if cgroup is not None:
            (cgroup_dir / "memory.max").write_text(f"{cgroup[0]}\n")
            (cgroup_dir / "memory.current").write_text(f"{cgroup[1]}\n")
        monkeypatch.setattr(engine_options, "MEMINFO_FILE", meminfo)
        monkeypatch.setattr(engine_options, "CGROUP_DIR", cgroup_dir)
        monkeypatch.setattr(engine_options.os, "sched_getaffinity", lambda pid: set(range(cpus)))

    return make


def test_one_worker_per_cpu_while_memory_holds_one_each(machine) -> None:
    machine(cpus=8, available_bytes=64 * RUN_WORKER_BYTES)
    assert automatic_workers()[0] == 8  # the CPUs bound
    machine(cpus=8, available_bytes=int(3.5 * RUN_WORKER_BYTES))
    workers, why = automatic_workers()
    assert workers == 3 and "8 usable CPU(s)" in why  # memory bounds: three whole workers
    # A calibration worker needs less memory, so more of them fit.
    assert automatic_workers(CALIBRATION_WORKER_BYTES)[0] == 8
    machine(cpus=4, available_bytes=RUN_WORKER_BYTES // 10)
    assert automatic_workers()[0] == 1  # never fewer than one


def test_a_cgroup_limit_counts_and_workers_asks_for_fewer(machine) -> None:
    # The container may use 2.5 workers' worth more, though the machine has plenty free.
    limit = 10 * RUN_WORKER_BYTES
    machine(cpus=16, available_bytes=64 * RUN_WORKER_BYTES,
            cgroup=(str(limit), limit - int(2.5 * RUN_WORKER_BYTES)))
    assert automatic_workers()[0] == 2
    machine(cpus=16, available_bytes=64 * RUN_WORKER_BYTES, cgroup=("max", 0))
    assert automatic_workers()[0] == 16
    assert local_workers(3) == 3 and local_workers(None) == 16


def test_a_local_campaign_starts_as_many_as_this_machine_allows() -> None:
    from yafs_safetail.runs.engines import make_engine

    engine = make_engine("local", None, None)
    try:
        assert engine.slots == automatic_workers()[0] >= 1
    finally:
        engine.close()
    assert make_engine("local", 1, None).slots == 1

"""Campaigns: grid expansion and run ids; failures, resume without recomputation and the same
bytes on every engine (tiny UC1 runs; Ray only when installed)."""

from __future__ import annotations

import io
import json
import shutil
from pathlib import Path

import pytest

from yafs_safetail.logs import RUN_LOG_FILE
from yafs_safetail.runs import campaign
from yafs_safetail.runs.campaign import EARLIER, FAILED, run_campaign
from yafs_safetail.runs.grid import GridError, RunSpec, expand, load_grid, make_config, run_id

TINY = {"steps_scale": 0.013, "figures": False}
REPOSITORY = Path(__file__).resolve().parents[1]
TOPOLOGY = REPOSITORY / "topologies" / "paper_5servers.json"
PLACEMENT = REPOSITORY / "placements" / "paper_5servers.json"


def folder_bytes(folder: Path) -> dict[str, bytes]:
    """Every file of a run folder but run.log, whose times differ from run to run."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name != RUN_LOG_FILE}


def test_grid_expands_first_axis_outermost_with_readable_names_and_ids() -> None:
    specs = expand(TINY, {"use_case": [1, 2], "seed": [0, 1]})
    assert [s.name.rsplit("-", 1)[0] for s in specs] == ["uc1-seed0", "uc1-seed1", "uc2-seed0", "uc2-seed1"]
    assert all(s.name.endswith(s.run_id) and len(s.run_id) == 12 for s in specs)
    assert len({s.run_id for s in specs}) == 4


def test_run_id_follows_what_the_results_depend_on(tmp_path: Path) -> None:
    def one(**settings: object) -> str:
        return expand({**TINY, **settings}, {"seed": [0]})[0].run_id

    base = one()
    assert one(topology=str(TOPOLOGY)) == base  # the default, spelt out
    assert one(steps_scale=0.02) != base and one(redundancy_levels=[1, 2]) != base
    assert one(learning_rate=1e-3) != base and one(learning_rate=1e-3) != one(learning_rate=1e-4)
    edited = tmp_path / "topology.json"
    shutil.copy(TOPOLOGY, edited)
    same_place = one(topology=str(edited), placement=str(PLACEMENT))
    edited.write_text(edited.read_text().replace("\n", "\n\n"))  # same place, other bytes
    assert one(topology=str(edited), placement=str(PLACEMENT)) != same_place


def test_bad_grids_are_one_line_errors(tmp_path: Path) -> None:
    with pytest.raises(GridError, match="base.workers = 2: set by the campaign"):
        expand({"workers": 2}, {"seed": [0]})
    with pytest.raises(GridError, match="two different runs the folder 'same'"):
        expand(TINY, {"seed": [0, 1]}, name="same")
    with pytest.raises(GridError, match="expected a non-empty list"):
        expand(TINY, {"seed": []})
    grid = tmp_path / "grid.toml"
    grid.write_text("[base]\nsteps_scale = 0.013\n[axes]\nseed = [0, 1]\nuse_case = [1]\n")
    assert [s.name.split("-")[0] for s in load_grid(grid)] == ["seed0", "seed1"]
    grid.write_text("[axes]\nseed = [0\n")
    with pytest.raises(GridError, match=r"grid.toml: not valid TOML") as error:
        load_grid(grid)
    assert "\n" not in str(error.value)
    grid.write_text("[axis]\nseed = [0]\n")
    with pytest.raises(GridError, match="axis: unknown entry"):
        load_grid(grid)


def test_engine_options_are_not_recorded_in_the_command() -> None:
    argv = ["--uc", "1", "--workers", "2", "--engine=ray", "--ray-address", "h:1", "--out", "x"]
    assert campaign.engine_free_command(["python", "p.py"], argv) == "python p.py --uc 1 --out x"


def test_each_run_gets_one_process_and_its_run_id(tmp_path: Path) -> None:
    spec = expand(TINY, {"seed": [3]})[0]
    config = make_config(spec, tmp_path / "r")
    assert (config.workers, config.progress, config.run_id, config.seed) == (1, False, spec.run_id, 3)


@pytest.fixture(scope="module")
def uncut(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[RunSpec], campaign.CampaignResult, str]:
    """Two tiny runs and one that fails at its checks, two at a time, without interruption."""
    out = tmp_path_factory.mktemp("campaign") / "uncut"
    specs = expand(TINY, {"seed": [0, 1]})
    # A run that fails at its own checks: made by hand, since a grid naming a missing file is
    # refused whole before anything runs (tests/test_campaign_grid.py).
    settings = {**specs[0].settings, "topology": "/nonexistent/topology.json"}
    broken = [RunSpec(name="seed0-broken", run_id=run_id(settings), settings=settings)]
    stream = io.StringIO()
    result = run_campaign([*specs, *broken], out, workers=2, stream=stream)
    return out, specs, result, stream.getvalue()


def test_a_failed_run_is_reported_and_the_others_finish(uncut) -> None:
    out, specs, result, log = uncut
    assert result.failed == 1
    assert [r.status for r in result.runs] == ["done", "done", FAILED]
    assert "topology file not found" in result.runs[2].error
    for spec in specs:
        assert campaign.recorded_run_id(out / spec.name) == spec.run_id
        # Each run's own log, written in its worker process (where no logging was set up).
        assert "UC1 SafeTail train: done" in (out / spec.name / RUN_LOG_FILE).read_text()
    state = json.loads((out / campaign.STATE_FILE).read_text())
    assert [r["status"] for r in state["runs"]] == ["done", "done", FAILED]
    assert "topology file not found" in state["runs"][2]["error"]
    # Progress lines and the summary table, on the stream and in the log.
    assert "2/3 done (0 earlier), 0 running, 1 failed, 0 to do" in log
    assert "3 runs: 2 computed now, 0 done earlier (not recomputed), 1 failed" in log
    assert "1 failed" in (out / campaign.LOG_FILE).read_text()


def test_a_resumed_campaign_recomputes_nothing_and_gives_the_same_bytes(uncut, tmp_path: Path) -> None:
    reference, specs, _, _ = uncut
    out = tmp_path / "resumed"
    # An interrupted campaign: the first run finished, the second never started.
    shutil.copytree(reference / specs[0].name, out / specs[0].name)
    stamp = (out / specs[0].name / "run.json").stat()
    result = run_campaign(specs, out, stream=io.StringIO())
    assert [r.status for r in result.runs] == [EARLIER, "done"]
    after = (out / specs[0].name / "run.json").stat()
    assert (after.st_ino, after.st_mtime_ns) == (stamp.st_ino, stamp.st_mtime_ns)
    for spec in specs:
        assert folder_bytes(out / spec.name) == folder_bytes(reference / spec.name), spec.name
    # A third time: nothing left to compute.
    again = run_campaign(specs, out, stream=io.StringIO())
    assert [r.status for r in again.runs] == [EARLIER, EARLIER]


def test_a_folder_holding_another_configuration_is_not_replaced_without_overwrite(uncut, tmp_path: Path) -> None:
    reference, specs, _, _ = uncut
    out = tmp_path / "other"
    shutil.copytree(reference / specs[0].name, out / specs[1].name)  # seed 0's run in seed 1's place
    result = run_campaign(specs[1:], out, stream=io.StringIO())
    assert result.failed == 1 and "holds a run of another configuration" in result.runs[0].error
    assert campaign.recorded_run_id(out / specs[1].name) == specs[0].run_id  # untouched


def test_ray_engine_writes_the_same_bytes_as_the_local_engine(uncut, tmp_path: Path) -> None:
    pytest.importorskip("ray", reason="Ray is not installed (pip install -e .[ray]); the local "
                                      "engine is tested without it")
    reference, specs, _, _ = uncut
    out = tmp_path / "ray"
    result = run_campaign(specs, out, engine="ray", workers=2, stream=io.StringIO())
    assert result.failed == 0, [r.error for r in result.runs]
    for spec in specs:
        assert folder_bytes(out / spec.name) == folder_bytes(reference / spec.name), spec.name


def test_a_two_node_ray_cluster_writes_the_same_bytes(uncut, tmp_path: Path) -> None:
    # Two Ray nodes (two raylets) on this machine with one CPU each: with two runs at a time
    # each node must take one, so the folders really travel back from another node.
    pytest.importorskip("ray", reason="Ray is not installed (pip install -e .[ray]); the local "
                                      "engine is tested without it")
    from ray.cluster_utils import Cluster

    reference, specs, _, _ = uncut
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1})
    try:
        cluster.add_node(num_cpus=1)
        cluster.wait_for_nodes()
        out = tmp_path / "ray-cluster"
        result = run_campaign(specs, out, ray_address=cluster.address, workers=2, stream=io.StringIO())
        assert result.failed == 0, [r.error for r in result.runs]
        for spec in specs:
            assert folder_bytes(out / spec.name) == folder_bytes(reference / spec.name), spec.name
        assert len({run.node for run in result.runs}) == 2, [run.node for run in result.runs]
    finally:
        cluster.shutdown()


def test_a_lost_ray_node_s_runs_are_retried_on_the_remaining_node(uncut, tmp_path: Path,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    # The two-node cluster above; once both runs are executing (one on each node: one CPU
    # each), the second node's processes are killed outright, raylet and all.
    pytest.importorskip("ray", reason="Ray is not installed (pip install -e .[ray]); the local "
                                      "engine's killed worker is tested in tests/test_faults.py")
    import tempfile
    import threading
    import time

    from ray.cluster_utils import Cluster

    reference, specs, _, _ = uncut
    # A task makes its scratch folder (yafs-safetail-run-*) once it executes: in a folder of
    # this test's own (short: Ray's sockets stay in /tmp), two of them mean both are running.
    scratch = Path(tempfile.mkdtemp(prefix="ray-node-lost-", dir="/tmp"))
    monkeypatch.setenv("TMPDIR", str(scratch))
    monkeypatch.setenv("RAY_TMPDIR", "/tmp")
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1})
    try:
        doomed = cluster.add_node(num_cpus=1)
        cluster.wait_for_nodes()

        def lose_the_second_node() -> None:
            deadline = time.monotonic() + 300
            while len(list(scratch.glob("yafs-safetail-run-*"))) < len(specs) and time.monotonic() < deadline:
                time.sleep(0.05)
            cluster.remove_node(doomed, allow_graceful=False)

        killer = threading.Thread(target=lose_the_second_node)
        killer.start()
        out = tmp_path / "ray-node-lost"
        result = run_campaign(specs, out, ray_address=cluster.address, workers=2, stream=io.StringIO())
        killer.join()
        assert result.failed == 0, [r.error for r in result.runs]
        # Every run came back from the node that survived, the same bytes as the local engine's.
        assert {run.node for run in result.runs} == {cluster.head_node.node_id[:8]}
        for spec in specs:
            assert folder_bytes(out / spec.name) == folder_bytes(reference / spec.name), spec.name
    finally:
        cluster.shutdown()
        shutil.rmtree(scratch, ignore_errors=True)


def test_a_run_interrupted_while_training_resumes_from_its_checkpoint(uncut, tmp_path: Path,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    import dataclasses

    from yafs_safetail.runs import checkpoint, experiment
    from yafs_safetail.runs.checkpoint import checkpoint_folder

    reference, specs, _, _ = uncut
    out = tmp_path / "interrupted"
    shutil.copytree(reference / specs[0].name, out / specs[0].name)
    # The second run was stopped after its first training checkpoint.
    real_write = checkpoint.write_checkpoint

    def write_then_stop(target, checkpoint):  # type: ignore[no-untyped-def]
        real_write(target, checkpoint)
        raise KeyboardInterrupt

    monkeypatch.setattr(checkpoint, "write_checkpoint", write_then_stop)
    config = dataclasses.replace(make_config(specs[1], out / specs[1].name), checkpoint_every_s=0.0)
    with pytest.raises(KeyboardInterrupt):
        experiment.run_experiment(config)
    monkeypatch.setattr(checkpoint, "write_checkpoint", real_write)
    assert checkpoint_folder((out / specs[1].name).resolve()).is_dir()
    result = run_campaign(specs, out, stream=io.StringIO())
    assert [r.status for r in result.runs] == [EARLIER, "done"]
    assert "resumed from the checkpoint at request" in (out / specs[1].name / RUN_LOG_FILE).read_text()
    for spec in specs:
        assert folder_bytes(out / spec.name) == folder_bytes(reference / spec.name), spec.name
    assert not any(p.name.endswith(".checkpoint") for p in out.iterdir())  # removed once done


@pytest.mark.parametrize(("options", "message"), [
    ({"engine": "ray"}, "--engine ray: Ray is not installed"),
    ({"ray_address": "127.0.0.1:6379"}, "--engine ray: Ray is not installed"),
    ({"engine": "spark"}, "--engine: unknown engine 'spark'"),
    ({"workers": 0}, "--workers: expected a positive integer, got 0"),
])
def test_an_engine_that_cannot_start_is_one_line_before_anything_is_written(tmp_path, monkeypatch, options, message):
    import importlib.util

    from yafs_safetail.runs import engines

    # As on a machine without Ray, whether or not this one has it.
    real_find_spec = importlib.util.find_spec
    monkeypatch.setattr(engines.importlib.util, "find_spec",
                        lambda name, *args: None if name == "ray" else real_find_spec(name, *args))
    specs = expand(TINY, {"seed": [0]})
    with pytest.raises(ValueError, match=message.replace("[", r"\[")):
        run_campaign(specs, tmp_path / "c", **options)
    assert not (tmp_path / "c").exists()

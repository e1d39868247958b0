"""What the machine does to a run, and what the tool promises then (docs/faults.md).

Each test injects one fault: a full disk (a small tmpfs where the machine allows mounting, and an
injected ENOSPC everywhere), and checks the promise: one line naming the folder and the fault,
a non-zero exit, nothing partial left, an earlier results folder untouched byte for byte.
"""

from __future__ import annotations

import errno
import os
from pathlib import Path

import pytest
from test_golden_results import CAMPAIGN_GRID, GOLDEN_FILE, digests

from yafs_safetail.runs.output import OutputError, StagedOutput


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _fake_results_folder(folder: Path) -> None:
    folder.mkdir()
    (folder / "run.json").write_text('{"package_version": "0.1.0"}')
    (folder / "requests.csv").write_text("method\nOracle\n")


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EDQUOT], ids=["ENOSPC", "EDQUOT"])
def test_a_full_disk_while_writing_names_the_folder_and_keeps_the_earlier_run(tmp_path, code):
    target = tmp_path / "run"
    _fake_results_folder(target)
    before = _snapshot(target)
    with pytest.raises(OutputError) as raised:
        with StagedOutput(target, overwrite=True) as staging:
            (staging / "requests.csv").write_text("half")
            raise OSError(code, os.strerror(code))
    message = str(raised.value)
    assert message.startswith(f"--out {target}: no space left on the device")
    assert "earlier results there are untouched" in message and "\n" not in message
    assert _snapshot(target) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]  # no staging, no lock left


def test_a_full_disk_on_a_new_target_leaves_nothing(tmp_path):
    target = tmp_path / "run"
    with pytest.raises(OutputError, match="nothing was left there"):
        with StagedOutput(target) as staging:
            (staging / "requests.csv").write_text("half")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    assert list(tmp_path.iterdir()) == []


def test_other_write_errors_pass_through_unchanged(tmp_path):
    with pytest.raises(PermissionError):
        with StagedOutput(tmp_path / "run"):
            raise PermissionError(errno.EACCES, "denied")


# --------------------------------------------------------------------------------------------
# A checkpoint cut short or corrupted, then --resume


class _Stop(KeyboardInterrupt):
    """Stands for a crash right after the first checkpoint was written."""


@pytest.fixture(scope="module")
def interrupted_run(tmp_path_factory):
    """A real run stopped after its first training checkpoint: (its config, checkpoint path)."""
    import dataclasses

    from yafs_safetail.runs import checkpoint as checkpoint_module
    from yafs_safetail.runs.experiment import ExperimentConfig, run_experiment

    config = ExperimentConfig(use_case=1, out_dir=tmp_path_factory.mktemp("crash") / "run",
                              steps_scale=0.05, redundancy_levels=(1,), figures=False,
                              progress=False, workers=1, checkpoint_every_s=0.0)
    real_write = checkpoint_module.write_checkpoint

    def write_then_crash(target, checkpoint):  # type: ignore[no-untyped-def]
        real_write(target, checkpoint)
        raise _Stop

    checkpoint_module.write_checkpoint = write_then_crash
    try:
        with pytest.raises(_Stop):
            run_experiment(config)
    finally:
        checkpoint_module.write_checkpoint = real_write
    path = checkpoint_module.checkpoint_folder(config.out_dir) / checkpoint_module.CHECKPOINT_FILE
    assert path.is_file() and not config.out_dir.exists()
    return dataclasses.replace(config, resume=True), path


def _cut_short(data: bytes) -> bytes:
    return data[: len(data) // 2]


def _flip_one_byte(data: bytes) -> bytes:
    middle = len(data) // 2 + 7  # inside the pickle, past the header
    return data[:middle] + bytes([data[middle] ^ 0x01]) + data[middle + 1:]


@pytest.mark.parametrize("damage", [_cut_short, _flip_one_byte], ids=["cut short", "one byte flipped"])
def test_a_damaged_checkpoint_is_refused_in_one_line_and_kept(interrupted_run, damage):
    from yafs_safetail.runs.checkpoint import CheckpointError
    from yafs_safetail.runs.experiment import run_experiment

    config, path = interrupted_run
    original = path.read_bytes()
    try:
        path.write_bytes(damage(original))
        damaged = path.read_bytes()
        with pytest.raises(CheckpointError) as raised:
            run_experiment(config)
        message = str(raised.value)
        assert "\n" not in message
        assert message.startswith(f"--resume: {path} is damaged (cut short or corrupted")
        assert "run without --resume" in message
        assert path.read_bytes() == damaged  # the tool does not delete or repair it
        assert not config.out_dir.exists()
    finally:
        path.write_bytes(original)


def test_the_undamaged_checkpoint_resumes(interrupted_run, tmp_path):
    import dataclasses
    import shutil

    from yafs_safetail.runs.checkpoint import checkpoint_folder
    from yafs_safetail.runs.experiment import run_experiment

    config, path = interrupted_run
    copy = dataclasses.replace(config, out_dir=tmp_path / "run")
    shutil.copytree(path.parent, checkpoint_folder(copy.out_dir))
    report = run_experiment(copy)
    assert (report.out_dir / "requests.csv").is_file()


# --------------------------------------------------------------------------------------------
# A real full disk: a small tmpfs (root and a kernel that allows it; skipped elsewhere)


@pytest.fixture
def small_disk(tmp_path):
    import shutil
    import subprocess

    mount_point = tmp_path / "disk"
    mount_point.mkdir()
    if shutil.which("mount") is None or os.geteuid() != 0:
        pytest.skip("mounting a small tmpfs needs root and mount(8); the injected ENOSPC tests "
                    "above cover the same code")
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=400k", "tmpfs", str(mount_point)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        pytest.skip(f"this machine does not allow mounting a tmpfs ({done.stderr.strip()})")
    try:
        yield mount_point
    finally:
        subprocess.run(["umount", str(mount_point)], check=False)


def _run_usecase(*args: str):
    import subprocess
    import sys

    return subprocess.run([sys.executable, "-m", "yafs_safetail.cli", "run", *args],
                          capture_output=True, text=True, timeout=600)


def test_a_run_on_a_full_disk_is_one_line_and_leaves_nothing(small_disk):
    out = small_disk / "run"
    done = _run_usecase("--uc", "1", "--steps-scale", "0.03", "--workers", "1", "--quiet", "--out", str(out))
    assert done.returncode == 2, done.stderr[-2000:]
    lines = done.stderr.strip().splitlines()
    assert lines == [f"error: --out {out}: no space left on the device while writing the "
                     "results; nothing was left there"], done.stderr[-2000:]
    assert list(small_disk.iterdir()) == []


def test_overwrite_on_a_full_disk_keeps_the_earlier_run_byte_for_byte(small_disk):
    out = small_disk / "run"
    _fake_results_folder(out)
    before = _snapshot(out)
    filler = small_disk / "filler.bin"
    with filler.open("wb") as stream:  # leave about 100 KB: less than a run writes
        stream.write(b"\0" * (300 * 1024))
    done = _run_usecase("--uc", "1", "--steps-scale", "0.03", "--workers", "1", "--quiet", "--out", str(out),
                        "--overwrite")
    assert done.returncode == 2, done.stderr[-2000:]
    assert done.stderr.strip().splitlines() == [
        f"error: --out {out}: no space left on the device while writing the results; the "
        "earlier results there are untouched"], done.stderr[-2000:]
    assert _snapshot(out) == before
    assert sorted(p.name for p in small_disk.iterdir()) == ["filler.bin", "run"]


# --------------------------------------------------------------------------------------------
# A campaign worker killed outright (SIGKILL, as the out-of-memory killer does)

#: The golden check's campaign (two runs), so that its golden is the campaign without the kill.
_GRID = CAMPAIGN_GRID


def _grid_in(cwd: Path) -> Path:
    """``cwd/grid.toml``, the campaign's grid (written if it is not there yet)."""
    cwd.mkdir(exist_ok=True)
    grid = cwd / "grid.toml"
    if not grid.is_file():
        grid.write_text(_GRID)
    return grid


def _campaign(cwd: Path, *extra: str, env: dict[str, str] | None = None):
    """``yafs-safetail campaign`` in ``cwd`` with relative paths, so that every run.json
    records the same command whichever folder the campaign ran in."""
    import subprocess
    import sys

    _grid_in(cwd)
    return subprocess.run([sys.executable, "-m", "yafs_safetail.cli", "campaign", "--grid", "grid.toml",
                           "--out", "campaign", "--workers", "2", "--quiet", *extra],
                          cwd=cwd, capture_output=True, text=True, timeout=900,
                          env={**os.environ, **(env or {})})


def test_a_killed_campaign_worker_fails_its_run_alone_and_the_same_command_completes_it(tmp_path):
    import json

    from yafs_safetail.runs.engines import KILL_RUN_ENV
    from yafs_safetail.runs.grid import load_grid

    out = tmp_path / "killed" / "campaign"
    specs = load_grid(_grid_in(tmp_path / "killed"))
    victim = specs[1]

    # The worker running the second run kills itself with SIGKILL just before publishing it.
    killed = _campaign(tmp_path / "killed", env={KILL_RUN_ENV: victim.name})
    assert killed.returncode == 1, killed.stderr[-2000:]
    failed_lines = [line for line in killed.stderr.splitlines() if f"failed {victim.name}" in line]
    assert len(failed_lines) == 1 and "killed by signal 9 (SIGKILL)" in failed_lines[0], killed.stderr[-2000:]
    state = json.loads((out / "campaign.json").read_text())
    assert [run["status"] for run in state["runs"]] == ["done", "failed"]
    assert "its worker process" in state["runs"][1]["error"]
    assert "killed by signal 9 (SIGKILL)" in state["runs"][1]["error"]
    assert not (out / victim.name).exists()
    stamps = {spec.name: (out / spec.name / "run.json").stat().st_mtime_ns for spec in specs if spec != victim}

    # The same command again: the killed run only, then the same files as without the kill.
    again = _campaign(tmp_path / "killed")
    assert again.returncode == 0, again.stderr[-2000:]
    state = json.loads((out / "campaign.json").read_text())
    assert [run["status"] for run in state["runs"]] == ["done earlier", "done"]
    assert stamps == {name: (out / name / "run.json").stat().st_mtime_ns for name in stamps}
    # The files of the same campaign never killed: the golden check's (its normalised digests).
    assert digests(out) == json.loads(GOLDEN_FILE.read_text())["campaign"]
    # Nothing of the killed attempt is left: no temporary folder, no run's lock; only the
    # campaign's own files (its lock file and latency tables included, as after any campaign)
    # and its runs.
    assert sorted(p.name for p in out.iterdir()) == sorted([".campaign.lock", "campaign.json", "campaign.log",
                                                            "latency.csv", "latency.md",
                                                            *(spec.name for spec in specs)])


# --------------------------------------------------------------------------------------------
# run_usecase.py's baseline worker killed outright

#: run_usecase.py with the baseline worker's job replaced by a SIGKILL to itself (the worker is
#: forked, so it inherits the replacement; the main process never runs the job itself).
_KILLED_BASELINE_WORKER = (
    "import os, signal, sys\n"
    "from yafs_safetail.runs import workers\n"
    "workers.MethodsJob.run = lambda self: os.kill(os.getpid(), signal.SIGKILL)\n"
    "from yafs_safetail.cli import run_cli\n"
    "from yafs_safetail.commands import run_usecase\n"
    "sys.exit(run_cli(run_usecase.main, sys.argv[1:]))\n"
)


@pytest.mark.parametrize("earlier", [False, True], ids=["new folder", "earlier run with --overwrite"])
def test_a_killed_baseline_worker_is_one_line_and_leaves_nothing(tmp_path, earlier):
    import subprocess
    import sys

    out = tmp_path / "run"
    before = {}
    if earlier:
        _fake_results_folder(out)
        before = _snapshot(out)
    done = subprocess.run([sys.executable, "-c", _KILLED_BASELINE_WORKER, "--uc", "1", "--steps-scale", "0.013",
                           "--workers", "2", "--quiet", "--out", str(out), *(["--overwrite"] if earlier else [])],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode != 0
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr[-2000:]
    assert lines[0].startswith("error: the baseline worker (pid "), lines[0]
    assert "was killed by signal 9 (SIGKILL); the run stopped and wrote no results" in lines[0]
    if earlier:
        assert _snapshot(out) == before
    # Only SafeTail's training checkpoint (written when its training ended, before the worker
    # was found dead) is left beside --out, as after Ctrl-C: a resume point, not results.
    from yafs_safetail.runs.checkpoint import CHECKPOINT_MARKER, checkpoint_folder

    leftovers = sorted(p.name for p in tmp_path.iterdir())
    assert leftovers == [".run.checkpoint", *(["run"] if earlier else [])], (leftovers, lines[0])
    assert (checkpoint_folder(out) / CHECKPOINT_MARKER).is_file()
    if not earlier:  # the same command with --resume (and no kill) completes the run
        resumed = _run_usecase("--uc", "1", "--steps-scale", "0.013", "--workers", "2", "--quiet",
                               "--out", str(out), "--resume")
        assert resumed.returncode == 0, resumed.stderr[-2000:]
        assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]

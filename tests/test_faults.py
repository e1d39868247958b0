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

"""``--traces DIR``: a run on one's own measured traces (issue 50, item 5).

A copy of the packaged ``traces/`` gives the default run's files; a copy with one corrupted row
stops the run in one line naming the file, the row (as a spreadsheet shows it: the header is
row 1) and the column, exit 2, the earlier results kept.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from in_process import run_usecase_here

from yafs_safetail.defaults import DEFAULT_TRACE_DIR
from yafs_safetail.edge.traces import READ_FILES, same_traces

REPOSITORY = Path(__file__).resolve().parents[1]
TINY = ("--uc", "1", "--seed", "5", "--steps-scale", "0.02")
#: run.json keys a run with --traces writes differently: the command line (it names --traces and
#: its own --out) and the traces folder, recorded only when --traces names one.
PATH_KEYS = ("command", "traces")


def _copy_of_traces(folder: Path) -> Path:
    """The packaged traces copied as a user would (``cp -r traces/ DIR``)."""
    shutil.copytree(DEFAULT_TRACE_DIR, folder, ignore=shutil.ignore_patterns("__pycache__"))
    return folder


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The default run and the same run with --traces pointing at a copy of traces/."""
    root = tmp_path_factory.mktemp("traces_option")
    copy = _copy_of_traces(root / "my traces")
    default = run_usecase_here(*TINY, "--out", root / "default")
    assert default.returncode == 0, default.stderr
    own = run_usecase_here(*TINY, "--traces", copy, "--out", root / "own")
    assert own.returncode == 0, own.stderr
    return root / "default", root / "own", copy


def _files(folder: Path) -> dict[str, bytes]:
    """Every file of a results folder by its path in it, but run.log (which records times)."""
    return {str(path.relative_to(folder)): path.read_bytes() for path in sorted(folder.rglob("*"))
            if path.is_file() and path.name != "run.log"}


def test_a_copy_of_the_packaged_traces_gives_the_default_runs_files(runs):
    default, own, copy = runs
    assert same_traces(copy)
    a, b = _files(default), _files(own)
    assert a.keys() == b.keys()
    assert any(name.startswith("figures/") for name in a)  # the titles too
    for name in a:
        if name != "run.json":
            assert a[name] == b[name], f"{name} differs with --traces pointing at a copy of traces/"
    first, second = json.loads(a["run.json"]), json.loads(b["run.json"])
    assert "traces" not in first  # a run without --traces writes what it always did
    assert second["traces"] == str(copy)
    assert "--traces" in second["command"]
    assert [key for key in {**first, **second} if first.get(key) != second.get(key)] == list(PATH_KEYS)


def _run(*args: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(REPOSITORY / "experiments" / "run_usecase.py"), *map(str, args)],
                          capture_output=True, text=True, cwd=cwd, timeout=120)


def test_a_corrupted_row_is_one_line_naming_it_and_the_earlier_results_stay(runs, tmp_path):
    default, _, _ = runs
    earlier = tmp_path / "earlier"
    shutil.copytree(default, earlier)
    before = _files(earlier)
    mine = _copy_of_traces(tmp_path / "mine")
    lines = (mine / "propagation.csv").read_text().splitlines(keepends=True)
    lines[4] = "2,-0.3\n"  # row 5 as a spreadsheet shows the file (the header is row 1)
    (mine / "propagation.csv").write_text("".join(lines))
    done = _run(*TINY, "--traces", "mine", "--out", earlier, "--overwrite", cwd=tmp_path)
    assert done.returncode == 2
    assert done.stderr == "error: mine/propagation.csv: row 5 (header = row 1), column 'rtt_s': -0.3 must be > 0\n"
    assert done.stdout == ""
    assert _files(earlier) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["earlier", "mine"]


def test_a_missing_folder_or_file_is_one_line_naming_it(tmp_path):
    done = _run(*TINY, "--traces", "~/no-such-traces-folder", "--out", "r", cwd=tmp_path)
    assert done.returncode == 2
    assert done.stderr == f"error: --traces {Path.home() / 'no-such-traces-folder'}: no such folder\n"
    mine = _copy_of_traces(tmp_path / "mine")
    (mine / "load.csv").unlink()
    done = _run(*TINY, "--traces", "mine", "--out", "r", cwd=tmp_path)
    assert (done.returncode, done.stderr) == (2, "error: mine/load.csv: trace file not found\n")
    assert not (tmp_path / "r").exists()


def test_read_files_are_what_a_run_reads():
    assert all((DEFAULT_TRACE_DIR / name).is_file() for name in READ_FILES)
    assert same_traces(DEFAULT_TRACE_DIR)


def test_reproduce_all_takes_the_traces_for_every_run(tmp_path):
    done = subprocess.run([sys.executable, str(REPOSITORY / "experiments" / "reproduce_all.py"), "--uc", "1",
                           "--seeds", "0", "--traces", "nowhere", "--out", "r"],
                          capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and 'traces_dir = "nowhere": no such folder' in done.stderr
    assert not (tmp_path / "r").exists()


def _refuses_a_corrupted_row(script: str, options: tuple[str, ...], copy: Path, out: Path) -> None:
    """``script`` on ``copy`` with one bad row stops in one line naming it, exit 2, nothing at ``out``."""
    lines = (copy / "propagation.csv").read_text().splitlines(keepends=True)
    lines[4] = "2,-0.3\n"
    (copy / "propagation.csv").write_text("".join(lines))
    done = subprocess.run([sys.executable, str(REPOSITORY / "experiments" / script), *options,
                           "--traces", str(copy), "--out", str(out)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 2, done.stderr
    assert done.stderr == (f"error: {copy}/propagation.csv: row 5 (header = row 1), column 'rtt_s': "
                           "-0.3 must be > 0\n")
    assert not out.exists()


#: The smallest load sweep: ten users, two loads, fixed methods only.
SWEEP = ("--users", "10", "--steps-scale", "0.02", "--no-safetail", "--workers", "1", "--seed", "2",
         "--loads", "0.2,0.8", "--methods", "Oracle,Rand-1")


def test_a_load_sweep_takes_the_traces_too(tmp_path):
    import pandas as pd

    copy = _copy_of_traces(tmp_path / "mine")
    rows = {}
    for name, extra in (("default", ()), ("copy", ("--traces", str(copy)))):
        done = subprocess.run([sys.executable, str(REPOSITORY / "experiments" / "load_sweep.py"), *SWEEP, *extra,
                               "--out", str(tmp_path / name)], capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr
        rows[name] = pd.read_csv(tmp_path / name / "sweep.csv")
    pd.testing.assert_frame_equal(rows["default"], rows["copy"])
    run = json.loads((tmp_path / "copy" / "run.json").read_text())
    assert run["traces"] == str(copy) and "traces" not in json.loads((tmp_path / "default" / "run.json").read_text())
    # Another folder is another point: its run id names the files' contents.
    points = json.loads((tmp_path / "copy" / "run.json").read_text())["load_runs"]
    assert points != json.loads((tmp_path / "default" / "run.json").read_text())["load_runs"]
    # A corrupted row stops the sweep before any point runs, in one line, nothing written.
    _refuses_a_corrupted_row("load_sweep.py", SWEEP, copy, tmp_path / "bad")


def test_the_mobility_sweep_takes_the_traces_too(tmp_path):
    import pandas as pd

    copy = _copy_of_traces(tmp_path / "mine")
    sweep = ("--seeds", "4", "--speeds", "walking", "--steps-scale", "0.02", "--no-figures", "--workers", "1", "-q")
    tables = {}
    for name, extra in (("default", ()), ("copy", ("--traces", str(copy)))):
        done = subprocess.run([sys.executable, str(REPOSITORY / "experiments" / "mobility_sweep.py"), *sweep, *extra,
                               "--out", str(tmp_path / name)], capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr
        tables[name] = pd.read_csv(tmp_path / name / "mobility.csv")
    pd.testing.assert_frame_equal(tables["default"], tables["copy"])
    run = json.loads((tmp_path / "copy" / "walking" / "seed4" / "run.json").read_text())
    assert run["traces"] == str(copy)
    # A corrupted row stops the sweep before any run starts, in one line, nothing written.
    _refuses_a_corrupted_row("mobility_sweep.py", sweep, copy, tmp_path / "bad")

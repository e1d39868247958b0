"""yafs-safetail compare: two results folders, B / A with bootstrap intervals."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from in_process import run_in_process
from results_helpers import write_run_folder

from yafs_safetail.edge.scenario import REPOSITORY
from yafs_safetail.results import write_requests_csv
from yafs_safetail.results.compare import compare_runs
from yafs_safetail.results.files import ResultsFileError

COMPARE = REPOSITORY / "experiments" / "compare_runs.py"


@pytest.fixture
def two_runs(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    requests = write_run_folder(a, np.random.default_rng(1))
    slower = requests.copy()
    oracle = slower["method"] == "Oracle"
    slower.loc[oracle, "latency_s"] *= 2.0
    slower.loc[oracle, "deviation_s"] = slower.loc[oracle, "target_s"] - slower.loc[oracle, "latency_s"]
    for part in ("upload_s", "propagation_s", "download_s", "compute_s"):
        slower.loc[oracle, part] *= 2.0
    write_run_folder(b, np.random.default_rng(1))
    write_requests_csv(slower, b)
    return a, b


def test_ratios_and_intervals(two_runs):
    a, b = two_runs
    table = compare_runs(a, b, seed=0)
    assert list(table["method"].unique())[:2] == ["SafeTail", "Oracle"]
    oracle = table[(table["method"] == "Oracle") & (table["figure"] == "p99_s")].iloc[0]
    assert oracle["ratio_b_over_a"] == pytest.approx(2.0)
    assert oracle["ratio_low"] <= 2.0 <= oracle["ratio_high"] and oracle["ratio_low"] > 0
    same = table[table["method"] == "SafeTail"]
    assert (same["ratio_b_over_a"] == 1.0).all() and (same["ratio_low"] <= 1.0).all()
    assert table.equals(compare_runs(a, b, seed=0))  # seeded: the same table every time


def test_a_run_against_itself_is_one_with_a_zero_width_interval(two_runs):
    a, _ = two_runs
    table = compare_runs(a, a, seed=0)
    assert table["paired"].all()
    assert (table["ratio_b_over_a"] == 1.0).all()
    assert (table["ratio_low"] == 1.0).all() and (table["ratio_high"] == 1.0).all()


def test_the_same_requests_are_paired_and_other_seeds_are_not(two_runs, tmp_path):
    a, b = two_runs
    # B's Oracle took exactly twice as long on every request: paired, every resample says 2.
    oracle = compare_runs(a, b, seed=0).query("method == 'Oracle' and figure == 'p99_s'").iloc[0]
    assert oracle["paired"] and oracle["ratio_low"] == pytest.approx(2.0) == oracle["ratio_high"]
    # Another seed's requests are other requests: each run resampled on its own, a wider interval.
    other = tmp_path / "other_seed"
    write_run_folder(other, np.random.default_rng(1), seed=1)
    write_requests_csv(pd.read_csv(b / "requests.csv"), other)
    unpaired = compare_runs(a, other, seed=0).query("method == 'Oracle' and figure == 'p99_s'").iloc[0]
    assert not unpaired["paired"] and unpaired["ratio_b_over_a"] == pytest.approx(2.0)
    assert unpaired["ratio_low"] < 2.0 < unpaired["ratio_high"]


def test_command_writes_a_new_folder_and_refuses_bad_input(two_runs, tmp_path):
    a, b = two_runs
    out = tmp_path / "cmp"
    done = subprocess.run([sys.executable, str(COMPARE), str(a), str(b), "--out", str(out)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert {p.name for p in out.iterdir()} == {"compare.csv", "compare.png"}
    assert len(pd.read_csv(out / "compare.csv")) == 5 * len(pd.read_csv(out / "compare.csv")["method"].unique())
    missing = subprocess.run([sys.executable, str(COMPARE), str(a), str(tmp_path / "nope")],
                             capture_output=True, text=True, timeout=300)
    assert missing.returncode == 2 and "nope: file not found" in missing.stderr and "Traceback" not in missing.stderr
    again = subprocess.run([sys.executable, str(COMPARE), str(a), str(b), "--out", str(a)],
                           capture_output=True, text=True, timeout=300)
    assert again.returncode == 2 and (a / "requests.csv").is_file()  # a results folder is never replaced


def test_no_common_method(tmp_path, two_runs):
    a, _ = two_runs
    other = tmp_path / "other"
    requests = write_run_folder(other, np.random.default_rng(2))
    renamed = requests.assign(method="Mine-" + requests["method"])
    write_requests_csv(renamed, other)
    with pytest.raises(ResultsFileError, match="no method in common"):
        compare_runs(a, other)


def test_quiet_prints_only_the_folder_and_without_out_the_table(two_runs, tmp_path):
    from yafs_safetail.commands.compare_runs import main

    a, b = two_runs
    out = tmp_path / "cmp"
    done = run_in_process(main, a, b, "--out", out, "--quiet")
    assert done.returncode == 0, done.stderr
    assert done.stdout == f"{out}\n" and (out / "compare.csv").is_file()
    # No folder: the table is what the command gives, --quiet or not.
    loud, quiet = run_in_process(main, a, b), run_in_process(main, a, b, "-q")
    assert quiet.stdout == loud.stdout and "p99_s" in quiet.stdout


def _rewrite_run_json(folder, **changes):
    import json

    run = json.loads((folder / "run.json").read_text())
    for key, value in changes.items():
        if isinstance(value, dict):
            run.setdefault(key, {}).update(value)
        else:
            run[key] = value
    (folder / "run.json").write_text(json.dumps(run))


def test_runs_in_different_worlds_get_one_warning_line_and_still_exit_0(two_runs):
    from yafs_safetail.commands.compare_runs import main

    a, b = two_runs
    same = run_in_process(main, a, b)
    assert same.returncode == 0 and same.stderr == ""  # the same world: nothing to say
    _rewrite_run_json(a, topology="topologies/paper_5servers.json", world={"load_peak_users": 2.75})
    _rewrite_run_json(b, topology="/elsewhere/topologies/paper_5servers.json", world={"load_peak_users": 2.75})
    moved = run_in_process(main, a, b)
    assert moved.stderr == ""  # the same file name from another folder: the same topology
    _rewrite_run_json(b, topology="topologies/3servers.json", world={"load_peak_users": 2.0})
    for quiet in ([], ["-q"]):  # a warning: --quiet keeps it
        done = run_in_process(main, a, b, *quiet)
        assert done.returncode == 0
        (line,) = done.stderr.splitlines()
        assert line.startswith(f"warning: {a} and {b} ran in different worlds (")
        assert '"paper_5servers.json" vs "3servers.json"' in line and "world.load_peak_users 2.75 vs 2.0" in line
        assert "p99_s" in done.stdout  # the table all the same


def test_a_run_without_run_json_is_named_in_the_warning(two_runs):
    from yafs_safetail.commands.compare_runs import main

    a, b = two_runs
    (b / "run.json").unlink()
    done = run_in_process(main, a, b)
    assert done.returncode == 0 and "p99_s" in done.stdout
    (line,) = done.stderr.splitlines()
    assert line.startswith("warning: cannot tell whether the two runs share a world: ") and str(b) in line


def test_compare_png_keeps_long_paths_and_its_axis_label_inside_the_figure(two_runs):
    from matplotlib.text import Text

    from yafs_safetail.results.compare import comparison_figure

    a, b = two_runs
    long_b = "/a/very/long/path/" + "nested-folder-with-a-long-name/" * 8 + "run"
    figure = comparison_figure(compare_runs(a, b, seed=0), str(a), long_b)
    renderer = figure.canvas.get_renderer()
    figure.draw(renderer)  # the constrained layout runs here
    box = figure.bbox
    texts = [t for t in figure.findobj(Text) if t.get_visible() and t.get_text()]
    assert any(t.get_text().startswith("B / A") for t in texts)
    for text in texts:
        extent = text.get_window_extent(renderer)
        assert box.x0 - 1 <= extent.x0 and extent.x1 <= box.x1 + 1, text.get_text()
        assert box.y0 - 1 <= extent.y0 and extent.y1 <= box.y1 + 1, text.get_text()
    shown = "".join(t.get_text() for t in texts).replace("\n", "")
    assert long_b in shown  # wrapped, not cut

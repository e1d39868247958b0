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

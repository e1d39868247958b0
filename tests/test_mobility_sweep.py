"""The mobility sweep: every method at every speed, its CSV, table and figure, and one-line errors."""

from __future__ import annotations

import pandas as pd
from in_process import run_in_process

from yafs_safetail.commands import mobility_sweep
from yafs_safetail.results.mobility_sweep import SWEEP_COLUMNS, SWEEP_METRICS

QUICK = ["--steps-scale", "0.02", "--no-figures", "--workers", "1", "--quiet"]


def test_every_method_has_a_row_at_every_speed(tmp_path):
    out = tmp_path / "sweep"
    done = run_in_process(mobility_sweep.main, "--seeds", "3", "--speeds", "rest,driving", *QUICK, "--out", out)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == str(out)
    table = pd.read_csv(out / "mobility.csv")
    assert tuple(table.columns) == SWEEP_COLUMNS
    methods = set(table["method"])
    assert {"SafeTail", "Oracle", "Rand-1", "MinLoad-3", "MinProp-2"} <= methods
    for speed in ("rest", "driving"):
        for method in methods:
            rows = table[(table.speed == speed) & (table.method == method)]
            assert sorted(rows.metric) == sorted(SWEEP_METRICS), (speed, method)
    assert (out / "mobility.png").is_file() and (out / "mobility.md").is_file()
    # The runs are the run command's, each moving at its speed (none at rest).
    rest = pd.read_csv(out / "rest" / "seed3" / "requests.csv")
    driving = pd.read_csv(out / "driving" / "seed3" / "requests.csv")
    assert rest[["user_x_m", "user_y_m"]].drop_duplicates().shape[0] == 1
    assert driving[["user_x_m", "user_y_m"]].drop_duplicates().shape[0] > 100
    # The same requests and loads at every speed: only the links differ.
    for column in ("step", "target_s"):
        assert rest[rest.method == "Rand-1"][column].shape == driving[driving.method == "Rand-1"][column].shape


def test_an_unknown_speed_is_one_line_and_writes_nothing(tmp_path):
    done = run_in_process(mobility_sweep.main, "--speeds", "rest,flying", *QUICK, "--out", tmp_path / "s")
    assert done.returncode == 2
    assert "--speeds" in done.stderr and "flying" in done.stderr and done.stderr.count("\n") == 1
    assert not (tmp_path / "s").exists()


def test_a_topology_without_positions_fails_before_any_run(tmp_path):
    done = run_in_process(mobility_sweep.main, "--topology", "topologies/paper_5servers.json", "--seeds", "1",
                          *QUICK, "--out", tmp_path / "s")
    assert done.returncode == 2 and done.stderr.count("\n") == 1
    assert "needs every edge server's position" in done.stderr
    assert not (tmp_path / "s").exists()


def test_a_policy_that_cannot_choose_stops_the_sweep_before_its_campaign(tmp_path):
    from pathlib import Path

    bad = Path(__file__).resolve().parent / "bad_policies.py"
    done = run_in_process(mobility_sweep.main, "--seeds", "1,2", "--speeds", "rest,walking", *QUICK,
                          "--method", f"{bad}:Empty", "--out", tmp_path / "s")
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert done.stderr.startswith(f"error: --method {bad}:Empty: ") and "returned []" in done.stderr
    assert not (tmp_path / "s").exists()  # no campaign started, not even its folder

"""A user who moves, end to end: run_usecase.py --mobility, its files, its one-line errors, and
the Gymnasium environment's keywords."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from in_process import run_usecase_here

from yafs_safetail.record import MOVEMENT_COLUMNS

ROOT = Path(__file__).resolve().parents[1]
CAMPUS = ["--topology", "topologies/campus_5servers.json"]
QUICK = ["--uc", "1", "--steps-scale", "0.02", "--no-figures", "--quiet", "--workers", "1"]


def test_random_waypoint_runs_and_records_where_the_user_was(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the campus topology is found among the packaged defaults
    done = run_usecase_here(*QUICK, *CAMPUS, "--mobility", "random-waypoint", "--out", tmp_path / "rwp")
    assert done.returncode == 0, done.stderr
    rows = pd.read_csv(tmp_path / "rwp" / "requests.csv")
    assert tuple(rows.columns[-3:]) == MOVEMENT_COLUMNS
    test = rows[(rows.phase == "test") & (rows.method == "Oracle")]
    assert test[["user_x_m", "user_y_m"]].drop_duplicates().shape[0] > len(test) // 2
    assert test["conditions"].nunique() > 1
    run = json.loads((tmp_path / "rwp" / "run.json").read_text())
    assert run["mobility"]["model"] == "random-waypoint" and run["mobility"]["speed_mps"] == [1.0, 1.5]
    assert "--mobility random-waypoint" in run["changed_settings"]


def test_a_route_file_moves_the_user_along_it_and_the_conditions_follow(tmp_path):
    done = run_usecase_here(*QUICK, *CAMPUS, "--mobility", "route", "--route", ROOT / "routes" / "campus_walk.csv",
                            "--out", tmp_path / "walk")
    assert done.returncode == 0, done.stderr
    rows = pd.read_csv(tmp_path / "walk" / "requests.csv", dtype={"conditions": str})
    oracle = rows[(rows.phase == "test") & (rows.method == "Oracle")].sort_values("step")
    # The walk is 600 s, ten requests: request 2 is at the far server, which is then near.
    at_far_server = oracle[oracle.step % 10 == 2].iloc[0]
    assert (at_far_server.user_x_m, at_far_server.user_y_m) == (150.0, 0.0)
    assert at_far_server.conditions.split(";") == ["5", "5", "5", "5", "1"]
    assert oracle[oracle.step % 10 == 0].iloc[0].conditions.split(";") == ["1", "2", "3", "4", "5"]
    assert json.loads((tmp_path / "walk" / "run.json").read_text())["mobility"]["route"].endswith("campus_walk.csv")


def test_without_mobility_the_campus_topology_runs_the_paper_world(tmp_path):
    """Positions alone change nothing: the paper topology and the campus one give the same rows."""
    paper = run_usecase_here(*QUICK, "--out", tmp_path / "paper")
    campus = run_usecase_here(*QUICK, *CAMPUS, "--out", tmp_path / "campus")
    assert paper.returncode == campus.returncode == 0
    assert (tmp_path / "paper" / "requests.csv").read_bytes() == (tmp_path / "campus" / "requests.csv").read_bytes()


@pytest.mark.parametrize("route, message", [
    ("time_s,x_m,y_m\n0,0,0\n5,far,1\n", "bad.csv: point 2: x_m is not a number: 'far'"),
    ("time_s,lat,lon\n0,41.4,2.1\n", "bad.csv: point 1: the route is in degrees (lat, lon) but the topology places"),
])
def test_a_bad_route_is_one_line_and_writes_nothing(tmp_path, route, message):
    (tmp_path / "bad.csv").write_text(route)
    done = subprocess.run([sys.executable, str(ROOT / "experiments" / "run_usecase.py"), *QUICK, *CAMPUS,
                           "--mobility", "route", "--route", "bad.csv", "--out", "out"],
                          cwd=tmp_path, capture_output=True, text=True, check=False)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and message in done.stderr, done.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("options, message", [
    (["--mobility", "route"], "--mobility route: needs --route FILE"),
    (["--route", "routes/campus_walk.csv"], "--route: only with --mobility route"),
    (["--pause-s", "5"], "--pause-s: only with --mobility random-waypoint"),
])
def test_mobility_options_that_do_not_go_together_are_one_line(tmp_path, options, message):
    done = run_usecase_here(*QUICK, *CAMPUS, *options, "--out", tmp_path / "out")
    assert done.returncode == 2 and message in done.stderr
    assert not (tmp_path / "out").exists()


def test_the_gymnasium_environment_takes_the_mobility_keywords():
    import gymnasium

    import yafs_safetail  # noqa: F401  (registers the ids)

    env = gymnasium.make("yafs_safetail/SafeTail-v0", use_case=1, phase="test", steps_scale=0.02,
                         topology=str(ROOT / "topologies" / "campus_5servers.json"),
                         mobility="random-waypoint", speed_mps=(8.0, 14.0), pause_s=0.0)
    observation, _ = env.reset(seed=1)
    locations, conditions = [observation["user_location"]], [observation["server_condition"]]
    for _ in range(30):
        observation, *_ = env.step(env.action_space.sample())
        locations.append(observation["user_location"])
        conditions.append(observation["server_condition"])
    assert len({tuple(np.round(loc, 6)) for loc in locations}) == 31
    assert len({tuple(c.tolist()) for c in conditions}) > 1
    env.close()

"""The training mechanism (issue 33 item 2): watching a policy changes nothing, the windows
cover every training request, and the command writes its table and figure."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from yafs_safetail.contention.run import run_policy
from yafs_safetail.contention.world import ContentionConfig, ContentionWorld
from yafs_safetail.methods.registry import make_baseline
from yafs_safetail.runs.mechanism import MECHANISM_COLUMNS, WatchedPolicy, window_rows

REPOSITORY = Path(__file__).resolve().parents[1]
SMALL = {"use_case": 1, "users": 8, "load": 0.6, "n_requests": 300, "queue": True, "background": False}


def test_a_watched_policy_runs_exactly_as_the_unwatched_one_and_sees_every_choice():
    world = ContentionWorld(ContentionConfig(seed=5, **SMALL))
    plain = run_policy(world, make_baseline("Rand-2", world.n_servers, np.random.default_rng(9)))
    watched = WatchedPolicy(make_baseline("Rand-2", world.n_servers, np.random.default_rng(9)))
    seen = run_policy(world, watched)
    np.testing.assert_array_equal(seen.result.latency_s, plain.result.latency_s)
    np.testing.assert_array_equal(seen.result.n_copies, plain.result.n_copies)
    assert len(watched.active_per_server) == SMALL["n_requests"]
    assert max(watched.active_per_server) > 0  # load 0.6 with queues: some copies wait or run


def test_windows_cover_every_request_once_and_average_within_their_window():
    copies = np.array([1, 1, 2, 2, 3, 3, 4])
    active = np.arange(7, dtype=float)
    latency = np.linspace(1.0, 2.0, 7)
    rows = window_rows("X", 0.5, copies, active, latency, windows=3)
    assert [row["first_request"] for row in rows] == [0, 2, 4]
    assert sum(int(row["requests"]) for row in rows) == 7
    assert rows[0]["mean_copies"] == 1.0 and rows[2]["mean_copies"] == pytest.approx(10 / 3)
    assert rows[1]["mean_active_per_server"] == 2.5
    assert set(rows[0]) == set(MECHANISM_COLUMNS)


def test_more_windows_than_requests_gives_one_request_per_window():
    rows = window_rows("X", 0.1, np.ones(3), np.zeros(3), np.ones(3), windows=10)
    assert [row["requests"] for row in rows] == [1, 1, 1]


def test_the_command_writes_the_table_and_the_figure_and_refuses_a_foreign_folder(tmp_path):
    out = tmp_path / "mechanism"
    done = subprocess.run([sys.executable, str(REPOSITORY / "experiments" / "training_mechanism.py"), "--uc", "1",
                           "--users", "10", "--loads", "0.2,0.8", "--objectives", "target-vector", "--steps-scale",
                           "0.01", "--windows", "4", "--seed", "3", "--out", str(out)],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    table = pd.read_csv(out / "mechanism.csv")
    assert tuple(table.columns) == MECHANISM_COLUMNS
    assert list(table["load"].unique()) == [0.2, 0.8] and set(table["method"]) == {"SafeTail"}
    assert (table.groupby("load")["window"].count() == 4).all()
    assert (out / "mechanism.png").stat().st_size > 0
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    refused = subprocess.run([sys.executable, str(REPOSITORY / "experiments" / "training_mechanism.py"),
                              "--steps-scale", "0.01", "--out", str(foreign)], capture_output=True, text=True,
                             timeout=600)
    assert refused.returncode != 0 and "Traceback" not in refused.stderr
    assert refused.stderr.strip().splitlines()[-1].startswith("error: --out")
    assert (foreign / "notes.txt").read_text() == "mine"

"""The three YAFS-style examples run end to end (smoke tests with small budgets)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def run_example(name, tmp_path, *args):
    completed = subprocess.run(
        [sys.executable, str(EXAMPLES / name / "main.py"), "--results", str(tmp_path), *args],
        cwd=tmp_path, capture_output=True, text=True, timeout=120,
    )
    assert completed.returncode == 0, completed.stderr
    return completed.stdout


def test_tutorial_01_port(tmp_path):
    out = run_example("yafs_tutorial_01", tmp_path, "--until", "300")
    rows = (tmp_path / "sim_trace.csv").read_text().splitlines()
    # A user co-located with a replica is served without any hop; the others take 1.00002.
    assert rows[1] == "3,COMP_M,2,2_01,M.USER.APP.2,2,7,3,3,None,0.3,100,100.3,100.0,100.0"
    assert "1,COMP_M,0,0_01,M.USER.APP.0,0,4,1,0,None,0.3,101.00002,101.30002,100.0,101.00002" in rows
    assert "Number of requests handled by deployed services: 10" in out


def test_tutorial_main2_port(tmp_path):
    out = run_example("yafs_tutorial_main2", tmp_path)
    rows = (tmp_path / "sim_trace.csv").read_text().splitlines()
    assert len(rows) == 1 + 9 * 3  # each of 9 requests: one service, two broadcast sink copies
    assert rows[3].endswith(",112.00600000000001,112.00600000000001,110.00500000000001,112.00600000000001")
    # YAFS3's report: loop 0 is the mean M.A response plus the mean M.B response.
    assert "0 - ['M.A', 'M.B'] :" in out


def test_basic_example_with_redundant_dispatch(tmp_path):
    out = run_example("yafs_basic", tmp_path, "--until", "10")
    assert "unanswered: 0" in out
    answered = int(out.split("requests answered: ")[1].split(",")[0])
    assert answered > 5
    links = (tmp_path / "sim_trace_link.csv").read_text().splitlines()
    assert len(links) - 1 >= answered * 2 * 4  # two copies, two hops up and two down each

"""Every benchmark still starts: its imports resolve and it answers --help (a benchmark is run on
demand, so nothing else would notice that a restructure broke it)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

REPOSITORY = Path(__file__).resolve().parents[1]
BENCHMARKS = sorted((REPOSITORY / "benchmarks").glob("bench_*.py"))


def test_there_are_benchmarks():
    assert len(BENCHMARKS) >= 8


@pytest.mark.parametrize("script", BENCHMARKS, ids=lambda p: p.name)
def test_benchmark_answers_help(script):
    done = subprocess.run([sys.executable, str(script), "--help"], capture_output=True, text=True,
                          cwd=REPOSITORY, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "usage:" in done.stdout


def test_fidelity_benchmark_small_budget(tmp_path):
    done = subprocess.run(
        [sys.executable, str(REPOSITORY / "benchmarks" / "bench_fidelity.py"), "--seeds", "0,1",
         "--steps-scale", "0.03", "--out", str(tmp_path / "fid")],
        capture_output=True, text=True, cwd=REPOSITORY, timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]
    lines = done.stdout.strip().splitlines()
    assert any(line.startswith("ratios_within_20=") and line.endswith("/23") for line in lines)
    assert any(line.startswith("claims_hold=") and line.endswith("/9") for line in lines)
    assert lines[-1].startswith("goals_met=") and "uc1_time:no" in lines[-1]  # not the full budget
    assert (tmp_path / "fid" / "fidelity.csv").is_file()

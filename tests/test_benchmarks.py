"""Every benchmark still starts: its imports resolve and it answers --help (a benchmark is run on
demand, so nothing else would notice that a restructure broke it)."""

from __future__ import annotations

import importlib.util
import json
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


@pytest.mark.slow  # about 50 s: reproduce_all's own small run and the scorecard's tests cover its parts
def test_fidelity_benchmark_small_budget(tmp_path):
    done = subprocess.run(
        [sys.executable, str(REPOSITORY / "benchmarks" / "bench_fidelity.py"), "--seeds", "0",
         "--steps-scale", "0.03", "--out", str(tmp_path / "fid")],
        capture_output=True, text=True, cwd=REPOSITORY, timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]
    lines = done.stdout.strip().splitlines()
    assert any(line.startswith("ratios_within_20=") and line.endswith("/23") for line in lines)
    assert any(line.startswith("claims_hold=") and line.endswith("/11") for line in lines)
    verdict = next(line for line in lines if line.startswith("goals_met="))
    assert [goal.split(":")[0] for goal in verdict.removeprefix("goals_met=").split(",")] == [
        "ratios", "reachable_claims", "access", "fallback", "uc1_tails", "x1_p95_not_fallback",
        "uc1_tails_x123", "access_vs_method", "zero_share"]
    assert any(line.startswith("uc1_run_s_at_scale_0.03=") for line in lines)  # not the full budget
    for name in ("reachable_claims_hold=", "safetail_fallback_max=", "uc1_tails_below_x1_seeds=",
                 "x1_p95_at_fallback_seeds="):
        assert any(line.startswith(name) for line in lines), name
    assert next(line for line in lines if line.startswith("uc1_tails_below_x1_seeds=")).endswith("/1")
    assert any(line.startswith("any_policy_ratios_at_most=") and line.endswith("/23") for line in lines)
    assert any(line.startswith("any_policy_claims_at_most=") for line in lines)
    assert (tmp_path / "fid" / "fidelity.csv").is_file()
    assert (tmp_path / "fid" / "feasibility.csv").is_file()
    for name in ("uc1_tails_below_x123_seeds=", "method_optimum_uc3=", "zero_share_gap_uc2=",
                 "access_gap_uc1=", "access_goal_uc2=", "not_reachable_by_method="):
        assert any(line.startswith(name) for line in lines), name
    # The same goals again from the folder alone, nothing rerun (the timed run aside), and the
    # scorecard written as the JSON the README renders.
    again = subprocess.run(
        [sys.executable, str(REPOSITORY / "benchmarks" / "bench_fidelity.py"), "--from", str(tmp_path / "fid"),
         "--write", str(tmp_path / "scorecard.json")],
        capture_output=True, text=True, cwd=REPOSITORY, timeout=300)
    assert again.returncode == 0, again.stderr[-2000:]
    assert again.stdout.splitlines() == [line for line in done.stdout.splitlines()
                                         if not line.startswith(("report:", "uc1_run_s_at_scale_"))]
    card = json.loads((tmp_path / "scorecard.json").read_text(encoding="utf-8"))
    assert card["seeds"] == [0] and card["steps_scale"] == 0.03 and len(card["commit"]) == 40
    spec = importlib.util.spec_from_file_location("readme_tables", REPOSITORY / "tables" / "readme_tables.py")
    assert spec and spec.loader
    readme_tables = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(readme_tables)
    assert "Seeds 0, preset `paper` at --steps-scale 0.03" in readme_tables.scorecard_block(card)


def test_core_benchmark_against_a_yafs3_checkout_small_budget(tmp_path):
    # No YAFS3 checkout ships with the project, so the comparison runs against a stand-in: this
    # core's own package under the name ``yafs`` and one tutorial-sized script. It checks the
    # comparison machinery (alternating runs, import porting, CSV check, --split's columns),
    # not YAFS3's speed.
    import shutil

    fake = tmp_path / "yafs3"
    shutil.copytree(REPOSITORY / "yafs_safetail" / "yafs", fake / "src" / "yafs",
                    ignore=shutil.ignore_patterns("__pycache__"))
    for path in (fake / "src" / "yafs").rglob("*.py"):
        path.write_text(path.read_text().replace("yafs_safetail.yafs", "yafs"))
    script = fake / "tutorial_scenarios" / "01_basicExample" / "main.py"
    script.parent.mkdir(parents=True)
    script.write_text(
        "import sys\n"
        f"sys.path.insert(0, {str(REPOSITORY / 'tests')!r})\n"
        "from yafs import core\n"
        "from yafs_examples.yafs3_common import library\n"
        "from yafs_examples.yafs3_scenarios import basic\n"
        "lib = library(core.__name__.rpartition('.')[0])\n"
        "class Routing(lib.path_routing.DeviceSpeedAwareRouting):  # the script's own code, timed by --split\n"
        "    pass\n"
        "lib.path_routing.DeviceSpeedAwareRouting = Routing\n"
        "basic(lib, 'results')\n")
    done = subprocess.run([sys.executable, str(REPOSITORY / "benchmarks" / "bench_core.py"), "--yafs3", str(fake),
                           "--repeats", "1", "--split", "--scripts", "01_basic"],
                          capture_output=True, text=True, cwd=REPOSITORY, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    header = next(line for line in done.stdout.splitlines() if line.startswith("script"))
    assert "ceiling" in header
    row = next(line for line in done.stdout.splitlines() if line.startswith("tutorial_scenarios/01"))
    assert row.endswith("2/2 identical"), row
    # script, YAFS3 s, ours s, ratio, pair median, core YAFS3, core ours, core ratio, ceiling, CSVs
    columns = row.split()
    assert len(columns) == 11 and all(c.endswith("x") for c in (columns[3], columns[4], columns[7], columns[8]))
    assert float(columns[8][:-1]) > 0


@pytest.mark.slow  # about a minute; the benchmark's own small-budget run stays in the suite
def test_fidelity_benchmark_with_failed_runs_ends_without_a_traceback(tmp_path):
    # Too few training requests for use case 2 (refused before TensorFlow): the reproduction
    # fails, and the benchmark says so and stops instead of reading a report never written.
    done = subprocess.run(
        [sys.executable, str(REPOSITORY / "benchmarks" / "bench_fidelity.py"), "--seeds", "0",
         "--steps-scale", "0.013", "--out", str(tmp_path / "fid")],
        capture_output=True, text=True, cwd=REPOSITORY, timeout=900)
    assert done.returncode == 1
    assert "Traceback" not in done.stderr
    assert "run(s) failed" in done.stderr and "fewer than κ = 128" in done.stderr
    assert not (tmp_path / "fid" / "fidelity.csv").exists()


def test_first_answer_benchmark_against_a_revision(tmp_path):
    done = subprocess.run(
        [sys.executable, str(REPOSITORY / "benchmarks" / "bench_first_answer.py"), "--runs", "1",
         "--only", "help,error", "--against-rev", "HEAD"],
        capture_output=True, text=True, cwd=REPOSITORY, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    figures = dict(line.split("=") for line in done.stdout.strip().splitlines())
    assert set(figures) == {"help_s", "help_reference_s", "help_ratio", "error_s",
                            "error_reference_s", "error_ratio"}
    assert all(float(value) > 0 for value in figures.values())
    worktrees = subprocess.run(["git", "-C", str(REPOSITORY), "worktree", "list"],
                               capture_output=True, text=True, check=True).stdout
    assert "bench_first_answer_" not in worktrees  # its own worktree is gone
    bad = subprocess.run(
        [sys.executable, str(REPOSITORY / "benchmarks" / "bench_first_answer.py"), "--only", "fast"],
        capture_output=True, text=True, cwd=REPOSITORY, timeout=60)
    assert bad.returncode == 2 and "--only" in bad.stderr


@pytest.mark.slow  # two TensorFlow processes; its network code is the runs' own, tested there
def test_training_round_benchmark_small_budget():
    done = subprocess.run(
        [sys.executable, str(REPOSITORY / "benchmarks" / "bench_training_round.py"), "--rounds", "2"],
        capture_output=True, text=True, cwd=REPOSITORY, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    figures = dict(part.split("=") for line in done.stdout.splitlines() for part in line.split())
    assert set(figures) == {"first_round_s", "first_round_xla_s", "round_ms", "round_xla_ms", "same_weights"}
    assert all(float(figures[name]) > 0 for name in figures if name != "same_weights")
    assert figures["same_weights"] in ("yes", "no")

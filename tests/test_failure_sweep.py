"""The failure sweep (issue 31): every method's success rate, p99 and energy per request as each
server's probability of being down rises, on the load sweep's machinery."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from yafs_safetail.contention.world import ContentionConfig, ContentionError
from yafs_safetail.edge.failures import DEFAULT_MTTR_S
from yafs_safetail.results.sweep_report import failure_checks
from yafs_safetail.runs.sweep_config import (
    DEFAULT_FAILURE_LOAD,
    FAILURE_POINT,
    FailureSweepConfig,
    SweepConfig,
)
from yafs_safetail.runs.sweep_points import point_specs

REPOSITORY = Path(__file__).resolve().parents[1]
FAILURE_SWEEP = REPOSITORY / "experiments" / "failure_sweep.py"
LOAD_SWEEP = REPOSITORY / "experiments" / "load_sweep.py"
#: The issue's required columns of failure_sweep.csv.
REQUIRED = ("method", "failure_level", "success_rate", "p99_s", "energy_j_per_request")


def test_failure_sweep_small_budget(tmp_path):
    out = tmp_path / "failures"
    command = [sys.executable, str(FAILURE_SWEEP), "--uc", "1", "--users", "10", "--failure-levels", "0.2,0",
               "--steps-scale", "0.02", "--objectives", "target-vector", "--methods", "Oracle,Rand-1,MinLoad-2,Tied",
               # Short outages: the 400 requests span a few minutes, and each server should fail in them.
               "--failure-mttr-s", "5", "--seed", "3", "--out", str(out)]
    done = subprocess.run(command, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    frame = pd.read_csv(out / "failure_sweep.csv")
    for column in REQUIRED:
        assert column in frame.columns, column
    # One row per method and level, levels rising (given falling), SafeTail first.
    assert frame["failure_level"].tolist() == [0.0] * 5 + [0.2] * 5
    assert list(frame[frame["failure_level"] == 0.2]["method"]) == ["SafeTail", "Oracle", "Rand-1", "MinLoad-2", "Tied"]
    assert (frame["load"] == DEFAULT_FAILURE_LOAD).all() and (frame["n_requests"] == 380).all()
    # Without failures nothing is lost and servers queue: every request is answered.
    assert (frame[frame["failure_level"] == 0]["success_rate"] == 1.0).all()
    lossy = frame[frame["failure_level"] == 0.2].set_index("method")
    assert lossy.at["Rand-1", "success_rate"] < 1.0 and lossy.at["Rand-1", "share_all_lost"] > 0
    assert (frame["energy_j_per_request"] > 0).all()
    report = (out / "FAILURE_SWEEP.md").read_text()
    assert "| SafeTail energy per request < Oracle's at level 0.2 |" in report
    assert "| Oracle and x >= 2 succeed more often than every x = 1 at level 0.2 |" in report
    assert "| failure_level | SafeTail | Oracle | Rand-1 | MinLoad-2 | Tied |" in done.stdout
    run = json.loads((out / "run.json").read_text())
    assert run["kind"] == "failure_sweep" and run["failure_levels"] == [0.0, 0.2]
    assert run["mttr_s"] == 5.0 and run["timeout_s"] is None and set(run["level_runs"]) == {
        "level-0", "level-0.2"}
    for name in ("failure_sweep.png", "level-0/sweep.csv", "level-0.2/run.json", "campaign.json"):
        assert (out / name).is_file(), name
    assert json.loads((out / "level-0.2" / "run.json").read_text())["kind"] == FAILURE_POINT
    first = (out / "failure_sweep.csv").read_bytes()
    # Each level is a campaign run: rerunning resumes and recomputes nothing.
    again = subprocess.run(command, capture_output=True, text=True, timeout=900)
    assert again.returncode == 0, again.stderr
    assert "2 runs: 0 computed now, 2 done earlier" in again.stderr
    assert (out / "failure_sweep.csv").read_bytes() == first
    # (Same bytes with --workers 2: the load sweep's test checks it on the same code path.)


def test_failure_sweep_bad_input_is_one_line(tmp_path):
    out = tmp_path / "f"
    cases = {
        ("--failure-levels", "0,1.2"): "--failure-levels: expected distinct probabilities in [0, 1)",
        ("--failure-levels", "0.1,0.1"): "--failure-levels: expected distinct probabilities in [0, 1)",
        ("--load", "0"): "--load: expected a load in (0, 10)",
        ("--failure-mttr-s", "-5"): "--failure-mttr-s: expected a positive number",
        ("--timeout-s", "nan"): "--timeout-s: expected a positive number",
        ("--methods", "Best-3"): "unknown baseline 'Best-3'",
        ("--steps-scale", "0.001"): "20 test requests per failure level",
    }
    for args, message in cases.items():
        done = subprocess.run([sys.executable, str(FAILURE_SWEEP), *args, "--out", str(out)],
                              capture_output=True, text=True, timeout=120)
        assert done.returncode == 2, (args, done.stderr)
        assert message in done.stderr and "Traceback" not in done.stderr, (args, done.stderr)
        assert len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert not out.exists()


def test_failure_sweep_never_writes_into_another_sweep(tmp_path):
    # A load sweep's (interrupted) folder is not a failure sweep's, and the other way round.
    folder = tmp_path / "sweep"
    folder.mkdir()
    (folder / "campaign.json").write_text("{}")
    (folder / "load-0.5").mkdir()
    done = subprocess.run([sys.executable, str(FAILURE_SWEEP), "--out", str(folder)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "is not a failure sweep's folder" in done.stderr
    (folder / "load-0.5").rmdir()
    (folder / "level-0.1").mkdir()
    done = subprocess.run([sys.executable, str(LOAD_SWEEP), "--out", str(folder)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "is not a load sweep's folder" in done.stderr
    assert sorted(p.name for p in folder.iterdir()) == ["campaign.json", "level-0.1"]


def test_each_level_is_a_point_of_its_own():
    config = FailureSweepConfig(base=ContentionConfig(users=10), failure_levels=(0.3, 0.0, 0.1), mttr_s=30.0,
                                timeout_s=4.0)
    assert config.points == (0.0, 0.1, 0.3)
    specs = point_specs(config)
    assert [spec.name for spec in specs] == ["level-0", "level-0.1", "level-0.3"]
    assert {spec.kind for spec in specs} == {FAILURE_POINT} and len({spec.run_id for spec in specs}) == 3
    # A point's settings give back the one-level sweep (what a campaign worker runs).
    again = FailureSweepConfig.from_point_settings(specs[2].settings)
    assert (again.points, again.load, again.mttr_s, again.timeout_s) == ((0.3,), DEFAULT_FAILURE_LOAD, 30.0, 4.0)
    assert again.base == config.base and again.safetails == config.safetails
    assert again.test_requests == config.test_requests and again.methods == config.methods
    failures = config.failures(0.3)
    assert failures.unavailability == pytest.approx(0.3) and failures.mttr_s == 30.0 and failures.timeout_s == 4.0
    assert not config.failures(0.0).enabled
    assert FailureSweepConfig(base=ContentionConfig()).failures(0.1).mttr_s == DEFAULT_MTTR_S
    world = config.point_world(0.1)
    assert world.load == DEFAULT_FAILURE_LOAD and world.failures.unavailability == pytest.approx(0.1)
    # The load sweep's points are unchanged by the failure axis (their run ids hash the same fields).
    load_sweep = SweepConfig(base=ContentionConfig(users=10), loads=(0.5,))
    assert "failure_level" not in point_specs(load_sweep)[0].settings
    with pytest.raises(ContentionError, match="failure_levels: expected distinct probabilities in"):
        FailureSweepConfig(base=ContentionConfig(), failure_levels=(0.5, 1.0))


def test_failure_checks_are_computed_from_the_rows():
    rows = []
    table = {  # method: success rate at levels 0 and 0.2, energy per request at both
        "SafeTail": (1.0, 0.97, 1.0, 1.2), "Oracle": (1.0, 0.999, 3.0, 3.1), "Rand-1": (1.0, 0.80, 0.6, 0.7),
        "MinLoad-1": (1.0, 0.81, 0.6, 0.7), "MinLoad-2": (1.0, 0.96, 1.2, 1.3), "MinProp-3": (1.0, 0.79, 1.8, 1.9),
        "Tied": (1.0, 0.5, 1.0, 1.0),
    }
    for method, (ok0, ok2, energy0, energy2) in table.items():
        for level, ok, energy in ((0.0, ok0, energy0), (0.2, ok2, energy2)):
            rows.append({"failure_level": level, "method": method, "success_rate": ok, "p99_s": 1.0,
                         "energy_j_per_request": energy})
    checks = {claim: (holds, measured) for claim, holds, measured in failure_checks(pd.DataFrame(rows))}
    # Level 0 has nothing lost, so it is not a point of the success-rate goal; Tied counts in neither group.
    holds, measured = checks["Oracle and x >= 2 succeed more often than every x = 1 at level 0.2"]
    assert not holds and measured == "lowest MinProp-3 0.7900 vs highest x = 1 MinLoad-1 0.8100"
    assert [claim for claim in checks if "succeed" in claim] == [
        "Oracle and x >= 2 succeed more often than every x = 1 at level 0.2"]
    assert checks["SafeTail energy per request < Oracle's at level 0"] == (True, "1 J vs 3 J (0.33x)")
    assert checks["SafeTail energy per request < Oracle's at level 0.2"][0]
    assert len(checks) == 3

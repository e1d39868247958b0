"""calibrate: the learner-free objective, its reading of the worlds, and the script end to end
on a tiny grid."""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from yafs_safetail.edge.calibration import (
    CALIBRATED_PARAMETERS,
    CALIBRATION_FILE,
    CalibrationError,
    seed_set,
    world_settings,
)
from yafs_safetail.results.paper import PAPER_RATIOS
from yafs_safetail.runs import calibrate, world_fit
from yafs_safetail.runs.workers import MethodsJob

REPOSITORY = Path(__file__).resolve().parents[1]
SCRIPT = REPOSITORY / "experiments" / "calibrate.py"
TINY_GRID = {"load_start": ("per_server",), "load_peak_users": (3.0, 4.5),
             "bandwidth_share_exponent": (0.0, 2.0), "fallback_compute_multiple": (8.0,)}


def test_implied_cells_are_the_published_ratios_combined():
    implied = world_fit.implied_over_oracle()
    assert len(implied) == 12
    # facts.md: Rand-1 median = 1.72 (SafeTail over Rand-1) x 1.08 (Oracle over SafeTail).
    assert implied[("Rand-1", 50)] == pytest.approx(1.72 * 1.08)
    assert implied[("MinProp-1", 99)] == pytest.approx(1.89 / 0.79)
    consumed = world_fit.consumed_numbers()
    assert len(consumed) == 16 and {r.use_case for r in consumed} == {1}
    held_out = [r for r in PAPER_RATIOS if r not in consumed]
    assert len(held_out) == 7 and {r.use_case for r in held_out} == {2, 3}


def test_objective_is_zero_at_the_implied_cells_and_symmetric_in_log():
    exact = {world_fit.cell_key(m, p): v for (m, p), v in world_fit.implied_over_oracle().items()}
    value, within, means = world_fit.fit_score([exact, exact])
    assert value == 0.0 and within == 1.0 and means == pytest.approx(exact)
    double = {k: 2 * v for k, v in exact.items()}
    half = {k: v / 2 for k, v in exact.items()}
    assert world_fit.fit_score([double])[0] == pytest.approx(math.log(2))
    assert world_fit.fit_score([half])[0] == pytest.approx(math.log(2))
    assert world_fit.fit_score([double])[1] == 0.0


@pytest.mark.parametrize("candidate", [
    # servers at their limit for part of the time: refusals and fallbacks on the x = 1 baselines
    {"load_start": "per_server", "load_peak_users": 4.5, "bandwidth_share_exponent": 1.0,
     "fallback_compute_multiple": 8.0},
    {"load_start": "shared", "load_peak_users": 3.0, "bandwidth_share_exponent": 2.0,
     "fallback_compute_multiple": 4.0},
])
@pytest.mark.parametrize("reading", ["paper-text", "original-code"])
def test_latencies_read_from_the_world_equal_the_simulation(candidate, reading):
    use_case, inputs, scenario = world_fit._scenario(str(world_fit.DEFAULT_TOPOLOGY),
                                                     str(world_fit.DEFAULT_PLACEMENT))
    settings = dataclasses.replace(world_fit.settings_for(candidate), baseline_reading=reading)
    world = world_fit.build_world(scenario, use_case, inputs, 400, seed=5, phase="test",
                                  settings=settings)
    read = world_fit.method_latencies_s(world, world_fit.seed_choices(5, world.n_servers, 400))
    names = ("Oracle", *world_fit.X1_BASELINES)
    job = MethodsJob(names=names, user_methods=(), seed=5, world=world, step_interval_s=60.0,
                     yafs_dir=None, episode_steps=256, progress_label=None)
    frames, _ = job.run()
    for name, frame in zip(names, frames, strict=True):
        # The simulation adds the hops' delays to a clock; the table sums them directly.
        np.testing.assert_allclose(frame["latency_s"].to_numpy(), read[name], rtol=0, atol=1e-9)
    if candidate["load_peak_users"] > 4:
        assert (read["Rand-1"] == world.fallback_latency_s).any()  # the refusal path is exercised


def test_candidates_take_the_knee_rule_nu():
    settings = world_fit.settings_for(calibrate.grid_candidates()[0])
    assert settings.nu is None  # each use case's own ν (the knee rule)
    assert world_settings("calibrated").nu is None


def test_the_result_does_not_depend_on_the_workers(tmp_path):
    one = calibrate.calibrate(calibrate.CalibrationConfig(
        seeds=(1000,), grid=TINY_GRID, workers=1, out_dir=tmp_path / "one"), log=lambda _: None)
    two = calibrate.calibrate(calibrate.CalibrationConfig(
        seeds=(1000,), grid=TINY_GRID, workers=2, out_dir=tmp_path / "two"), log=lambda _: None)
    assert one["parameters"] == two["parameters"]
    assert (tmp_path / "one" / "evaluations.csv").read_bytes() == (tmp_path / "two" / "evaluations.csv").read_bytes()
    evaluations = pd.read_csv(tmp_path / "one" / "evaluations.csv")
    assert len(evaluations) == 4
    best = evaluations["objective"].idxmin()
    assert one["parameters"]["load_peak_users"] == evaluations.loc[best, "load_peak_users"]
    assert one["provenance"]["objective_value"] == pytest.approx(evaluations["objective"].min(), abs=1e-6)
    assert one["provenance"]["runner_up_objective"] >= one["provenance"]["objective_value"]


def test_script_on_one_seed_writes_results_and_leaves_the_package_alone(tmp_path):
    shipped = CALIBRATION_FILE.read_bytes()
    out = tmp_path / "cal"
    grid = tmp_path / "grid.json"
    grid.write_text(json.dumps(TINY_GRID))
    done = subprocess.run([sys.executable, str(SCRIPT), "--seeds", "1000", "--grid", str(grid),
                           "--out", str(out)],
                          capture_output=True, text=True, cwd=REPOSITORY, timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]
    assert CALIBRATION_FILE.read_bytes() == shipped  # no --apply: the package is untouched
    document = json.loads((out / "calibration.json").read_text())
    assert set(document["parameters"]) == set(CALIBRATED_PARAMETERS)
    assert document["provenance"]["seeds"] == [1000]
    assert document["provenance"]["evaluations"] == 4
    assert document["provenance"]["grid"] == {k: list(v) for k, v in TINY_GRID.items()}


def test_bad_arguments_are_one_line_errors(tmp_path):
    grid = tmp_path / "grid.json"
    grid.write_text(json.dumps({**TINY_GRID, "load_peak_users": [3.0, 9.0]}))
    missing = tmp_path / "missing.json"
    missing.write_text(json.dumps({"load_start": ["shared"]}))
    for args in (("--seeds", "5,5"), ("--workers", "0"), ("--seeds", "x"), ("--grid", str(grid)),
                 ("--grid", str(missing)), ("--grid", str(tmp_path / "none.json"))):
        done = subprocess.run([sys.executable, str(SCRIPT), *args, "--out", str(tmp_path / "x")],
                              capture_output=True, text=True, cwd=REPOSITORY, timeout=300)
        assert done.returncode == 2, args
        assert done.stderr.startswith("error:") and done.stderr.count("\n") == 1, done.stderr


def test_seed_sets_are_disjoint_and_bad_files_are_one_line(tmp_path):
    # Every set that only reports: each must be new to what it reports on.
    held_out = [set(seed_set(name)) for name in ("held_out", "fresh_held_out", "refit_held_out",
                                                 "uc3_scale_held_out", "mobility_report",
                                                 "target_held_out", "method_held_out")]
    assert sum(map(len, held_out)) == len(set().union(*held_out))  # no seed in two held-out sets
    assert not set().union(*held_out) & (set(seed_set("world_calibration"))
                                         | set(seed_set("learner_calibration")))
    bad = tmp_path / "sets.json"
    bad.write_text(json.dumps({"held_out": [1, "2"]}))
    with pytest.raises(CalibrationError, match="held_out: expected a list"):
        seed_set("held_out", bad)
    with pytest.raises(CalibrationError, match="unknown seed set"):
        seed_set("train", bad)

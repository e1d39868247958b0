"""calibrate: the objective on the calibration subset, and the script end to end on a tiny budget."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from yafs_safetail.edge.calibration import CALIBRATED_PARAMETERS, CALIBRATION_FILE
from yafs_safetail.results.paper import CALIBRATION_RATIOS
from yafs_safetail.runs.calibrate import objective, ratio_key

REPOSITORY = Path(__file__).resolve().parents[1]
SCRIPT = REPOSITORY / "experiments" / "calibrate.py"


def test_the_subset_is_use_case_one_against_the_x1_baselines():
    assert len(CALIBRATION_RATIOS) == 12
    assert {r.reference for r in CALIBRATION_RATIOS} == {"Rand-1", "MinLoad-1", "MinProp-1"}
    assert {r.use_case for r in CALIBRATION_RATIOS} == {1}


def test_objective_is_zero_at_the_paper_and_symmetric_in_log():
    exact = {ratio_key(r): r.speedup for r in CALIBRATION_RATIOS}
    value, within, means = objective([exact, exact])
    assert value == 0.0 and within == 1.0 and means == pytest.approx(exact)
    double = {k: 2 * v for k, v in exact.items()}
    half = {k: v / 2 for k, v in exact.items()}
    assert objective([double])[0] == pytest.approx(math.log(2))
    assert objective([half])[0] == pytest.approx(objective([double])[0])
    assert objective([double])[1] == 0.0


def test_script_on_a_tiny_budget_writes_results_and_leaves_the_package_alone(tmp_path):
    shipped = CALIBRATION_FILE.read_bytes()
    out = tmp_path / "cal"
    done = subprocess.run(
        [sys.executable, str(SCRIPT), "--steps-scale", "0.02", "--max-evaluations", "8",
         "--seeds", "1000", "--nu", "2,3", "--out", str(out)],
        capture_output=True, text=True, cwd=REPOSITORY, timeout=900,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert CALIBRATION_FILE.read_bytes() == shipped  # no --apply: the package is untouched
    document = json.loads((out / "calibration.json").read_text())
    assert set(document["parameters"]) == set(CALIBRATED_PARAMETERS)
    assert document["provenance"]["seeds"] == [1000]
    assert document["provenance"]["evaluations"] == 8
    evaluations = pd.read_csv(out / "evaluations.csv")
    assert len(evaluations) == 8
    assert set(evaluations["nu"]) == {2, 3}  # --nu bounds the search
    assert "nu in 2,3" in document["provenance"]["search"]
    assert evaluations["objective"].min() == pytest.approx(document["provenance"]["objective_value"],
                                                           abs=1e-6)


def test_bad_arguments_are_one_line_errors(tmp_path):
    for args in (("--seeds", "5,5"), ("--max-evaluations", "3"), ("--preset", "x"),
                 ("--nu", "0,2"), ("--nu", "2,2")):
        done = subprocess.run([sys.executable, str(SCRIPT), *args, "--out", str(tmp_path / "x")],
                              capture_output=True, text=True, cwd=REPOSITORY, timeout=300)
        assert done.returncode == 2, args
        assert done.stderr.startswith("error:") and done.stderr.count("\n") == 1, done.stderr

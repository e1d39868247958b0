"""reproduce_all.py end to end on a tiny budget: run folders, REPORT.md, speedups.csv, bad input."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pandas as pd

REPOSITORY = Path(__file__).resolve().parents[1]
SCRIPT = REPOSITORY / "experiments" / "reproduce_all.py"


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True,
                          cwd=REPOSITORY, timeout=900)


def test_two_seeds_one_use_case_make_a_report(tmp_path: Path) -> None:
    out = tmp_path / "rep"
    done = _run("--uc", "1", "--seeds", "0,1", "--steps-scale", "0.013", "--no-figures",
                "--out", str(out))
    assert done.returncode == 0, done.stderr[-2000:]
    for seed in (0, 1):
        assert (out / "uc1-paper" / f"seed{seed}" / "summary.csv").is_file()
    report = (out / "REPORT.md").read_text()
    assert "## Use case 1" in report and "preset `paper`" in report
    assert "Oracle over SafeTail" in report and "SafeTail over Rand-1" in report
    assert "| 0 |" in report and "| 1 |" in report  # one diagnostics row per seed
    assert "### Why our ratios may differ" in report
    # The scorecard: every use-case-1 number of the paper, calibration and held-out apart.
    assert "## Fidelity scorecard — preset `paper`" in report
    assert "the scorecard is meant for five or more" in report
    card = pd.read_csv(out / "fidelity.csv")
    ratios = card[card["kind"] == "ratio"]
    assert len(ratios) == 16 and set(ratios["use_case"]) == {1}
    assert (ratios["subset"] == "calibration").sum() == 12
    assert ratios["ours"].gt(0).all() and ratios["n_seeds"].eq(2).all()
    assert (card["kind"] == "claim").sum() == 3
    assert (out / "fidelity-paper.png").is_file() and (out / "fidelity-paper.pdf").is_file()
    speedups = pd.read_csv(out / "speedups.csv")
    assert set(speedups["preset"]) == {"paper"}
    stated = speedups[speedups["paper"].notna()]
    assert len(stated) > 0 and stated["n_seeds"].eq(2).all()


def test_unknown_use_case_and_preset_and_repeated_seeds_are_one_line_errors(tmp_path: Path) -> None:
    for args in (("--uc", "4"), ("--preset", "fast"), ("--seeds", "0,1,0")):
        done = _run(*args, "--out", str(tmp_path / "x"))
        assert done.returncode == 2
        assert done.stderr.startswith("error:") and done.stderr.count("\n") == 1
        assert "Traceback" not in done.stderr

"""The learning-rate rule (docs/calibration.md, rule 3): the choice on hand-made rewards, and the
script end to end on a tiny budget."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
from in_process import run_in_process

from yafs_safetail.methods.safetail.presets import PAPER_LEARNING_RATES, get_preset
from yafs_safetail.runs.learning_rate import RATE_GRID, choose

REPOSITORY = Path(__file__).resolve().parents[1]
SCRIPT = REPOSITORY / "experiments" / "choose_learning_rate.py"


def rewards(table: dict[tuple[int, float], list[float]]) -> pd.DataFrame:
    return pd.DataFrame([{"use_case": uc, "rate": rate, "seed": seed, "reward": value}
                         for (uc, rate), values in table.items() for seed, value in enumerate(values)])


def test_the_highest_mean_reward_wins_and_ties_go_to_the_smaller_rate():
    chosen = choose(rewards({
        (1, 1e-4): [-0.2, -0.1], (1, 1e-3): [-0.05, -0.15], (1, 3e-3): [-0.3, 0.0],  # means -.15 -.1 -.15
        (2, 1e-5): [-0.1, -0.1], (2, 1e-3): [-0.1, -0.1],  # a tie
    }))
    assert chosen == {1: 1e-3, 2: 1e-5}


def test_the_zero_share_criterion_takes_the_largest_share_of_zero_rewards():
    table = rewards({(3, 1e-5): [-0.001, -0.001], (3, 1e-3): [-0.01, -0.01]})
    table["zero_share"] = [0.5, 0.6, 0.9, 0.8]
    assert choose(table) == {3: 1e-5} and choose(table, "zero_share") == {3: 1e-3}


def test_the_shipped_rates_are_from_the_grid_and_used_by_paper_only():
    for use_case, rate in PAPER_LEARNING_RATES.items():
        assert rate in RATE_GRID
        assert get_preset("paper", use_case).learning_rate == rate
        assert get_preset("paper-literal", use_case).learning_rate in (1e-7, 1e-6)  # Table I


def test_script_on_a_tiny_budget_scores_every_rate(tmp_path):
    out = tmp_path / "lr"
    from yafs_safetail.commands import choose_learning_rate

    # In this process (tests/in_process.py: TensorFlow imported once); bad input below runs
    # the script itself.
    done = run_in_process(choose_learning_rate.main, "--uc", "1", "--seeds", "1000", "--rates", "1e-3,1e-5",
                          "--steps-scale", "0.02", "--out", out, "--quiet")
    assert done.returncode == 0, done.stderr[-2000:]
    table = pd.read_csv(out / "learning_rates.csv")
    assert sorted(table["rate"]) == [1e-5, 1e-3] and table["reward"].notna().all()
    assert table["zero_share"].between(0, 1).all() and table["access_rate"].between(0.19, 1.0).all()
    document = json.loads((out / "learning_rates.json").read_text())
    assert document["learning_rates"] == {"1": choose(table)[1]}
    assert document["provenance"]["seeds"] == [1000]
    assert document["provenance"]["rates"] == [1e-5, 1e-3]


def test_bad_arguments_are_one_line_errors(tmp_path):
    for args in (("--uc", "4"), ("--seeds", "1,1"), ("--criterion", "median"), ("--steps-scale", "0"), ("--workers", "x"),
                 ("--rates", "1e-3,0"), ("--rates", "1e-3,1e-3")):
        done = subprocess.run([sys.executable, str(SCRIPT), *args, "--out", str(tmp_path / "x")],
                              capture_output=True, text=True, cwd=REPOSITORY, timeout=300)
        assert done.returncode == 2, args
        assert done.stderr.startswith("error:") and done.stderr.count("\n") == 1, done.stderr

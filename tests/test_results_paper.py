"""The comparison with the paper, statistics over seeds, and the reports (yafs_safetail.results.paper, .stats, .report)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from results_helpers import make_requests, write_run_folder

from yafs_safetail import results
from yafs_safetail.results import (
    ResultsFileError,
)
from yafs_safetail.results import paper as paper_results


def _toy_summary(latencies: dict[str, tuple[float, float, float, float]]) -> pd.DataFrame:
    rows = []
    for method, (p50, p90, p95, p99) in latencies.items():
        rows.append({"method": method, "p50_s": p50, "p90_s": p90, "p95_s": p95, "p99_s": p99,
                     "mean_target_s": 0.6, "mean_n_selected": 2.0, "median_n_selected": 2.0,
                     "min_n_selected": 1, "max_n_selected": 3,
                     "min_window_n_selected": 1.4, "max_window_n_selected": 2.6})
    return pd.DataFrame(rows)


def test_speedup_directions_and_paper_values():
    summary = _toy_summary({
        "SafeTail": (0.54, 0.6, 0.7, 0.8),
        "Oracle": (0.5, 0.5, 0.5, 0.5),
        "Rand-1": (1.08, 1.2, 1.4, 2.4),
    })
    table = results.speedup_table(summary, use_case=1)
    oracle = table[table["method"] == "Oracle"].set_index("percentile")
    assert oracle.loc[50, "ours"] == pytest.approx(0.54 / 0.5)  # SafeTail / Oracle
    assert oracle.loc[50, "paper"] == pytest.approx(1.08)
    # The paper states p90 as SafeTail 0.93x vs Oracle: converted to Oracle over SafeTail.
    assert oracle.loc[90, "paper"] == pytest.approx(1 / 0.93)
    rand = table[table["reference"] == "Rand-1"].set_index("percentile")
    assert rand.loc[99, "ours"] == pytest.approx(2.4 / 0.8)  # baseline / SafeTail
    assert rand.loc[50, "paper"] == pytest.approx(1.72)
    assert "Rand-1" in rand.loc[50, "stated"]
    # Use case 2 states nothing for Rand-1 and Oracle.
    uc2 = results.speedup_table(summary, use_case=2)
    assert uc2["paper"].isna().all()


def test_paper_data_is_consistent():
    assert paper_results.paper_speedup(3, "Oracle", "SafeTail", 50) == pytest.approx(1.5)
    assert paper_results.paper_speedup(3, "SafeTail", "Oracle", 50) == pytest.approx(1 / 1.5)
    assert paper_results.paper_speedup(2, "SafeTail", "MinLoad-3", 90) == pytest.approx(0.90)
    assert paper_results.paper_speedup(2, "SafeTail", "MinLoad-3", 50) is None
    for ratio in paper_results.PAPER_RATIOS:
        assert ratio.use_case in (1, 2, 3) and ratio.percentile in (50, 90, 95, 99)
        assert ratio.speedup > 0 and ratio.stated
    assert {c.use_case for c in paper_results.PAPER_CLAIMS} == {1, 2, 3}


def test_claims_are_checked():
    good = _toy_summary({
        "SafeTail": (0.3, 0.4, 0.5, 0.55),
        "Oracle": (0.2, 0.3, 0.4, 0.5),
        "Rand-2": (0.4, 0.5, 0.6, 0.7),
    })
    claims = results.check_claims(good, 1).set_index("key")["holds"]
    assert claims["below_target_all"] is True
    assert claims["beats_x23_all"] is True
    assert claims["servers_1_to_3"] is True
    bad = good.copy()
    bad.loc[0, "p99_s"] = 0.9
    bad.loc[0, "max_window_n_selected"] = 3.2
    claims = results.check_claims(bad, 1).set_index("key")["holds"]
    assert claims["below_target_all"] is False
    assert claims["beats_x23_all"] is False
    assert claims["servers_1_to_3"] is False
    # A summary without β windows (written before them) falls back to single requests.
    no_windows = good.copy()
    no_windows[["min_window_n_selected", "max_window_n_selected"]] = math.nan
    no_windows.loc[0, "max_n_selected"] = 5
    assert results.check_claims(no_windows, 1).set_index("key")["holds"]["servers_1_to_3"] is False
    uc3 = results.check_claims(_toy_summary({"SafeTail": (0.3, 0.4, 0.5, 0.6)}), 3)
    assert uc3.set_index("key")["holds"]["baseline_better_p50_p90"] is None


# ---------------------------------------------------------------------------- markdown

def test_summary_markdown_contents(tmp_path):
    write_run_folder(tmp_path, np.random.default_rng(7))
    text = (tmp_path / "summary.md").read_text()
    assert text.startswith("# SafeTail results: use case 1 (object detection (YOLOv5)), "
                           "preset `paper`, seed 0")
    summary = results.read_summary_csv(tmp_path)
    safetail = summary.iloc[0]
    assert f"| SafeTail | {safetail['p50_s']:.3f} | {safetail['p90_s']:.3f} |" in text
    oracle = summary.iloc[1]
    assert f"| Oracle over SafeTail | {safetail['p50_s'] / oracle['p50_s']:.2f} | 1.08 |" in text
    rand1 = summary[summary["method"] == "Rand-1"].iloc[0]
    assert f"| SafeTail over Rand-1 | {rand1['p50_s'] / safetail['p50_s']:.2f} | 1.72 |" in text
    assert "| SafeTail over Rand-2 |" in text and "MinProp-3" in text
    assert "ours" in text and "paper" in text
    assert "## The paper's qualitative statements" in text


def test_markdown_without_run_or_safetail():
    requests = make_requests(np.random.default_rng(8), methods=("Oracle", "Rand-1"))
    text = results.summary_markdown(results.summarize(requests))
    assert "use case, preset and seed unknown" in text
    assert "Not available" in text


# ---------------------------------------------------------------------------- β averages

def test_beta_averages_blocks_and_episode_numbers():
    requests = make_requests(np.random.default_rng(9), n_train=50, n_test=30,
                             methods=("SafeTail", "Oracle"))
    beta = 20
    curve = results.access_rate_by_episode(requests, beta)
    assert list(curve["phase"]) == ["train"] * 3 + ["test"] * 2
    assert list(curve["n_steps"]) == [20, 20, 10, 20, 10]
    np.testing.assert_allclose(curve["avg_episode"], [1, 2, 2.5, 3.5, 4])
    train = requests.query("method == 'SafeTail' and phase == 'train'").sort_values("step")
    assert curve["value"].iloc[1] == pytest.approx(train["access_rate"].iloc[20:40].mean())
    assert results.train_test_boundary(requests, beta) == pytest.approx(2.5)
    deviation = results.latency_deviation_by_episode(requests, beta)
    test = requests.query("method == 'SafeTail' and phase == 'test'").sort_values("step")
    assert deviation["value"].iloc[3] == pytest.approx(test["deviation_s"].iloc[:20].mean())
    reward = results.abs_reward_by_episode(requests, beta)
    assert (reward["value"] > 0).all()
    assert reward["value"].iloc[0] == pytest.approx(train["reward"].iloc[:20].abs().mean())


def test_beta_averages_follow_step_order_not_file_order():
    requests = make_requests(np.random.default_rng(10), n_train=40, n_test=0,
                             methods=("SafeTail",))
    shuffled = requests.sample(frac=1.0, random_state=np.random.default_rng(11).integers(1 << 30))
    a = results.beta_averages(requests, 10, "latency_s")
    b = results.beta_averages(shuffled, 10, "latency_s")
    np.testing.assert_allclose(a["value"], b["value"])


# ---------------------------------------------------------------------------- across seeds

def test_geometric_interval_is_a_log_scale_t_interval():
    centre, low, high = results.geometric_interval([1.0, 2.0, 4.0])
    assert centre == pytest.approx(2.0)
    # log values ln(1), ln(2), ln(4): sd = ln 2, t(0.975, 2) = 4.3027 (tables).
    assert math.log(high / centre) == pytest.approx(4.3027 * math.log(2) / math.sqrt(3), abs=1e-3)
    assert low == pytest.approx(centre * centre / high)
    assert math.isnan(results.geometric_interval([1.0])[1])
    # Three seeds far apart: a t-interval of the plain mean would go below 0, this one cannot.
    _, low, _ = results.geometric_interval([0.1, 3.0, 9.0])
    assert low > 0


@given(st.lists(st.floats(0.0, 1.0, allow_nan=False), min_size=2, max_size=8))
@settings(max_examples=40, deadline=None)
def test_bootstrap_interval_stays_in_the_range_of_the_values(values):
    mean, low, high = results.bootstrap_interval(values)
    assert min(values) - 1e-12 <= low <= mean + 1e-12
    assert mean - 1e-12 <= high <= max(values) + 1e-12
    assert results.bootstrap_interval(values) == (mean, low, high)  # seeded


def test_aggregate_across_seeds(tmp_path):
    folders = []
    for seed in range(3):
        folder = tmp_path / f"seed{seed}"
        write_run_folder(folder, np.random.default_rng(100 + seed), seed=seed)
        folders.append(folder)
    stats = results.aggregate_summaries(folders)
    row = stats[(stats["method"] == "SafeTail") & (stats["metric"] == "p90_s")].iloc[0]
    values = [results.read_summary_csv(f).iloc[0]["p90_s"] for f in folders]
    assert row["mean"] == pytest.approx(np.mean(values))
    assert row["n_seeds"] == 3 and row["ci_low"] < row["mean"] < row["ci_high"]
    table = results.aggregate_markdown(stats)
    assert f"| SafeTail | 3 | {np.mean([results.read_summary_csv(f).iloc[0]['p50_s'] for f in folders]):.3f} [" in table
    speedups = results.aggregate_speedups(folders)
    oracle50 = speedups[(speedups["method"] == "Oracle") & (speedups["percentile"] == 50)].iloc[0]
    per_seed = [results.speedup(results.read_summary_csv(f), "Oracle", "SafeTail", 50)
                for f in folders]
    assert oracle50["mean"] == pytest.approx(np.exp(np.mean(np.log(per_seed))))
    assert oracle50["paper"] == pytest.approx(1.08)
    assert oracle50["note"]
    text = results.comparison_markdown(speedups, only_stated=True)
    assert "| 1 | Oracle over SafeTail | median |" in text
    assert "differs?" in text
    assert "Rand-2" not in text  # the paper states no Rand-2 number for use case 1


def test_aggregate_rejects_mixed_use_cases(tmp_path):
    write_run_folder(tmp_path / "a", np.random.default_rng(12), use_case=1)
    write_run_folder(tmp_path / "b", np.random.default_rng(13), use_case=3)
    with pytest.raises(ResultsFileError, match="use_case"):
        results.aggregate_summaries([tmp_path / "a", tmp_path / "b"])
    with pytest.raises(ResultsFileError, match="not found"):
        results.aggregate_speedups([tmp_path / "missing"])


@pytest.mark.parametrize(
    ("mean", "low", "high", "paper", "start"),
    [
        (1.1, 1.0, 1.2, 1.08, "consistent"),
        (1.5, 1.4, 1.6, 1.08, "differs in size"),
        (0.8, 0.7, 0.9, 1.08, "differs in direction"),
        (1.07, math.nan, math.nan, 1.08, "close: within 5%"),
        (1.0, 0.9, 1.1, math.nan, "paper states no number"),
    ],
)
def test_difference_notes(mean, low, high, paper, start):
    assert results.paper._difference_note(mean, low, high, paper, "A", "B").startswith(start)

"""REPORT.md's comparisons of two methods over seeds are paired by seed: every method of a seed
meets the same test requests (common random numbers), so each seed gives one ratio and the
interval is taken over those ratios, never from two methods' separate intervals. A method
against itself gives 1 with a zero-width interval, however much the seeds differ."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from results_helpers import make_requests, make_run

from yafs_safetail import results
from yafs_safetail.results import fidelity, reproduction, seed_tables
from yafs_safetail.results.over_seeds import metrics_over_seeds, speedups_over_seeds

#: SafeTail's latency level per seed: seeds far apart, as in a world that differs per seed.
LEVELS = (1.0, 3.0, 9.0)
SAFETAIL_S = {50: 0.2, 90: 0.5, 95: 0.6, 99: 0.9}


def summary(level: float, others: dict[str, float]) -> pd.DataFrame:
    """One seed's summary: SafeTail at ``level`` times ``SAFETAIL_S``, each other method at
    SafeTail's latency divided by its speed-up over SafeTail (``others``)."""
    rows = [{"method": method, **{f"p{p}_s": level * v / faster for p, v in SAFETAIL_S.items()},
             "mean_target_s": 10.0, "mean_n_selected": 1.5, "median_n_selected": 1.0,
             "min_n_selected": 1, "max_n_selected": 5, "min_window_n_selected": 1.2,
             "max_window_n_selected": 2.0, "mean_access_rate": 0.3}
            for method, faster in {"SafeTail": 1.0, **others}.items()]
    return pd.DataFrame(rows)


def test_a_method_against_its_twin_is_one_with_a_zero_width_interval() -> None:
    summaries = [summary(level, {"Twin": 1.0}) for level in LEVELS]
    ratios = speedups_over_seeds(summaries, ["Twin"], ["SafeTail"])
    assert len(ratios) == 4 and ratios["n_seeds"].eq(3).all()
    assert ratios["mean"].eq(1.0).all()
    assert ratios["ci_low"].eq(1.0).all() and ratios["ci_high"].eq(1.0).all()
    row = seed_tables.speedup_table(ratios).iloc[0].tolist()
    assert row == ["Twin", "SafeTail", "3", *["1.00 [1.00, 1.00]"] * 4]
    # Unpaired, the two methods' own intervals over seeds are wide and overlap fully.
    levels = metrics_over_seeds(summaries, ["p99_s"])
    assert (levels["ci_high"] / levels["ci_low"] > 2).all()


def test_the_interval_is_over_the_seeds_ratios_whatever_the_seeds_levels() -> None:
    speedups = (1.1, 1.2, 1.35)
    near = [summary(1.0, {"Mine": s}) for s in speedups]
    apart = [summary(level, {"Mine": s}) for level, s in zip(LEVELS, speedups, strict=True)]
    expected = results.geometric_interval(speedups)
    for summaries in (near, apart):
        ratios = speedups_over_seeds(summaries, ["Mine"], ["SafeTail"])
        for column, value in zip(("mean", "ci_low", "ci_high"), expected, strict=True):
            np.testing.assert_allclose(ratios[column], value, rtol=1e-12)
    # Paired by seed: a seed that did not run the reference gives no ratio, and its other
    # method's latency is not used either.
    apart[1] = apart[1][apart[1]["method"] != "SafeTail"]
    ratios = speedups_over_seeds(apart, ["Mine"], ["SafeTail"])
    assert ratios["n_seeds"].eq(2).all()
    kept = results.geometric_interval([speedups[0], speedups[2]])
    np.testing.assert_allclose(ratios[["mean", "ci_low", "ci_high"]].iloc[0], kept, rtol=1e-12)


def test_the_scorecard_ratio_of_a_method_equal_to_safetail_is_one_without_width() -> None:
    # The paper's "Oracle over SafeTail" with an Oracle as fast as SafeTail in every seed.
    card = fidelity.scorecard({1: [summary(level, {"Oracle": 1.0}) for level in LEVELS]})
    oracle = card[card["key"].str.startswith("Oracle over SafeTail")]  # the paper's median
    assert len(oracle) == 1 and oracle["n_seeds"].eq(3).all()
    assert oracle["ours"].eq(1.0).all()
    assert oracle["ci_low"].eq(1.0).all() and oracle["ci_high"].eq(1.0).all()


def _seed_folders(root: Path) -> list[Path]:
    """Three run folders whose Oracle and user policy "Twin" got SafeTail's latency on every
    test request (and SafeTail's seeds far apart)."""
    folders = []
    for seed, level in enumerate(LEVELS):
        requests = make_requests(np.random.default_rng(50 + seed))
        requests = requests[requests["method"] != "Oracle"].copy()
        for column in ("latency_s", "upload_s", "propagation_s", "download_s", "compute_s"):
            requests[column] *= level
        requests["deviation_s"] = requests["target_s"] - requests["latency_s"]
        test = requests[(requests["method"] == "SafeTail") & (requests["phase"] == "test")]
        twins = [test.assign(method=name, reward=math.nan) for name in ("Oracle", "Twin")]
        folder = root / f"seed{seed}"
        folder.mkdir()
        run = make_run(seed=seed)
        run.methods.append("Twin")
        results.write_requests_csv(pd.concat([requests, *twins], ignore_index=True), folder)
        results.write_run_json(folder, run)
        results.write_summary(folder)
        folders.append(folder)
    return folders


def test_report_tables_of_twins_are_one_with_a_zero_width_interval(tmp_path: Path) -> None:
    folders = _seed_folders(tmp_path)
    # Your methods' speed-ups (REPORT.md, its LaTeX and methods.csv).
    lines, tables, rows = reproduction._users_methods(1, "paper", folders)
    text = "\n".join(lines)
    assert "| Twin | SafeTail | 3 | 1.00 [1.00, 1.00] | 1.00 [1.00, 1.00] | 1.00 [1.00, 1.00] | 1.00 [1.00, 1.00] |" in text
    assert "1.00 [1.00, 1.00]" in tables["methods-ratios-uc1-paper"]
    over = rows[rows["metric"].str.startswith("speedup_over_SafeTail_p")]
    assert len(over) == 4 and over["mean"].eq(1.0).all()
    assert over["ci_low"].eq(1.0).all() and over["ci_high"].eq(1.0).all()
    # Oracle got the same latencies too: Twin over Oracle is 1 as well.
    assert rows[rows["metric"] == "speedup_over_Oracle_p99"]["ci_high"].eq(1.0).all()
    # The paper's ratios (speedups.csv and "Our ratios beside the paper's").
    aggregated = results.aggregate_speedups(folders)
    oracle = aggregated[(aggregated["method"] == "Oracle") & (aggregated["reference"] == "SafeTail")]
    assert len(oracle) == 4 and oracle["mean"].eq(1.0).all()
    assert oracle["ci_low"].eq(1.0).all() and oracle["ci_high"].eq(1.0).all()
    assert "| 1 | Oracle over SafeTail | p99 | 1.00 [1.00, 1.00] | 3 |" in results.comparison_markdown(aggregated)
    # While each method's own latency interval over the seeds is wide.
    stats = results.aggregate_summaries(folders)
    p99 = stats[(stats["metric"] == "p99_s") & stats["method"].isin(["SafeTail", "Oracle"])]
    assert (p99["ci_high"] / p99["ci_low"] > 2).all()
    assert not any(math.isnan(v) for v in p99["ci_low"])


@pytest.mark.parametrize("n_seeds", [1, 2])
def test_a_twin_with_few_seeds(n_seeds: int) -> None:
    ratios = speedups_over_seeds([summary(level, {"Twin": 1.0}) for level in LEVELS[:n_seeds]],
                                 ["Twin"], ["SafeTail"])
    assert ratios["mean"].eq(1.0).all()
    if n_seeds == 1:  # one seed: no interval
        assert ratios["ci_low"].isna().all()
    else:
        assert ratios["ci_low"].eq(1.0).all() and ratios["ci_high"].eq(1.0).all()

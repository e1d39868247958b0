"""The comparison with the paper, statistics over seeds, and the reports (yafs_safetail.results.paper, .stats, .report)."""

from __future__ import annotations

import math
import re

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from results_helpers import make_requests, make_run, write_run_folder

from yafs_safetail import results
from yafs_safetail.results import (
    ResultsFileError,
)
from yafs_safetail.results import claims as claim_checks
from yafs_safetail.results import paper as paper_results
from yafs_safetail.runs.experiment import REPOSITORY


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


def _holds(summary: pd.DataFrame, use_case: int) -> pd.Series:
    return results.check_claims(summary, use_case).set_index("key")["holds"]


def _with_servers(summary: pd.DataFrame, mean: float, median: float, fewest: int, most: int,
                  windows: tuple[float, float]) -> pd.DataFrame:
    """``summary`` with SafeTail's servers per request set (its first row)."""
    out = summary.copy()
    out.loc[0, ["mean_n_selected", "median_n_selected", "min_n_selected", "max_n_selected",
                "min_window_n_selected", "max_window_n_selected"]] = [mean, median, fewest, most,
                                                                      *windows]
    return out


TOY = {"SafeTail": (0.3, 0.4, 0.5, 0.55), "Oracle": (0.2, 0.3, 0.4, 0.5),
       "Rand-2": (0.4, 0.5, 0.6, 0.7)}


def test_a_policy_that_never_varies_holds_no_claim_about_varying():
    # One server every time: every β-window mean is 1, inside [1, 3], and the median is 1, at
    # most 2. Read on the bounds alone both claims would hold; the paper says the count varies.
    one = _with_servers(_toy_summary(TOY), 1.0, 1.0, 1, 1, (1.0, 1.0))
    assert _holds(one, 1)["servers_1_to_3"] is False
    assert _holds(one, 3)["mostly_1_to_2_servers"] is False
    # Two servers every time: inside the bounds too, and does not vary either.
    two = _with_servers(_toy_summary(TOY), 2.0, 2.0, 2, 2, (2.0, 2.0))
    assert _holds(two, 1)["servers_1_to_3"] is False
    assert _holds(two, 3)["mostly_1_to_2_servers"] is False
    # Varying within the bounds holds; a window above 3 does not.
    varied = _with_servers(_toy_summary(TOY), 1.3, 1.0, 1, 3, (1.0, 1.8))
    assert _holds(varied, 1)["servers_1_to_3"] is True
    assert _holds(varied, 3)["mostly_1_to_2_servers"] is True
    beyond = _with_servers(_toy_summary(TOY), 1.3, 1.0, 1, 5, (1.0, 3.2))
    assert _holds(beyond, 1)["servers_1_to_3"] is False
    # A summary without β windows (written before them) reads single requests the same way.
    for fewest, most, holds in ((1, 1, False), (1, 3, True), (1, 5, False)):
        old = _with_servers(_toy_summary(TOY), 1.5, 1.0, fewest, most, (math.nan, math.nan))
        assert _holds(old, 1)["servers_1_to_3"] is holds, (fewest, most)


def test_uc2_two_to_three_servers_on_average_needs_some_request_on_one_server():
    # "An average of 2 to 3 edge servers and, in some cases, just 1": a policy sending 2 or 3
    # every time has its mean in [2, 3] but never sends one server.
    never_one = _with_servers(_toy_summary(TOY), 2.5, 2.0, 2, 3, (2.2, 2.8))
    assert _holds(never_one, 2)["mean_servers_2_to_3"] is False
    sometimes_one = _with_servers(_toy_summary(TOY), 2.5, 2.0, 1, 3, (2.2, 2.8))
    assert _holds(sometimes_one, 2)["mean_servers_2_to_3"] is True
    below = _with_servers(_toy_summary(TOY), 1.8, 2.0, 1, 3, (1.5, 2.1))
    assert _holds(below, 2)["mean_servers_2_to_3"] is False


NINE = [f"{family}-{x}" for family in ("Rand", "MinLoad", "MinProp") for x in (1, 2, 3)]


def _uc3(safetail_s: float, baselines_s: list[float]) -> pd.DataFrame:
    """SafeTail and the nine baselines, each at the same latency at every percentile."""
    latencies = {"SafeTail": (safetail_s,) * 4, "Oracle": (0.1,) * 4}
    latencies.update({name: (value,) * 4 for name, value in zip(NINE, baselines_s, strict=True)})
    return _toy_summary(latencies)


def test_uc3_the_baselines_mean_more_than_half_of_them_on_both_sides():
    # SafeTail faster than five of the nine: "SafeTail performed better" holds (the earlier
    # reading, faster than every baseline, said no), and "the baseline methods outperformed
    # SafeTail" does not (the earlier reading, some baseline faster, said yes).
    five_slower = _uc3(1.0, [0.5, 0.6, 0.7, 0.8, 1.1, 1.2, 1.3, 1.4, 1.5])
    assert _holds(five_slower, 3)["safetail_better_p95_p99"] is True
    assert _holds(five_slower, 3)["baseline_better_p50_p90"] is False
    # Five of the nine faster: the other way round.
    five_faster = _uc3(1.0, [0.5, 0.6, 0.7, 0.8, 0.9, 1.2, 1.3, 1.4, 1.5])
    assert _holds(five_faster, 3)["safetail_better_p95_p99"] is False
    assert _holds(five_faster, 3)["baseline_better_p50_p90"] is True
    # Each percentile on its own: a majority at p95 but not at p99 is not enough.
    split = five_slower.copy()
    split.loc[split["method"] == "SafeTail", "p99_s"] = 1.45
    assert _holds(split, 3)["safetail_better_p95_p99"] is False
    # An even count: half is not more than half; a tie counts on neither side.
    six = _toy_summary({"SafeTail": (1.0,) * 4, **{n: (v,) * 4 for n, v in zip(
        NINE[:6], [0.5, 0.6, 1.0, 1.2, 1.3, 1.4], strict=True)}})
    assert _holds(six, 3)["safetail_better_p95_p99"] is False
    assert _holds(six, 3)["baseline_better_p50_p90"] is False
    # A baseline without a latency was not run: it counts on neither side.
    absent = _uc3(1.0, [0.5, 0.6, 0.7, 1.1, 1.2, math.nan, math.nan, math.nan, math.nan])
    assert _holds(absent, 3)["safetail_better_p95_p99"] is False
    assert _holds(absent, 3)["baseline_better_p50_p90"] is True


@given(st.lists(st.floats(0.05, 1.95).filter(lambda v: abs(v - 1.0) > 1e-6), min_size=1,
                max_size=9))
@settings(max_examples=60, deadline=None)
def test_uc3_readings_mirror_each_other(baselines_s):
    # One quantifier on both sides: reflecting every baseline's latency about SafeTail's
    # (faster becomes slower by as much) swaps the two verdicts. The earlier pair ("some
    # baseline faster" against "faster than every baseline") fails this as soon as SafeTail
    # sits between two baselines.
    padded = baselines_s + [math.nan] * (9 - len(baselines_s))
    mirrored = [2.0 - v for v in padded]
    assert (_holds(_uc3(1.0, padded), 3)["baseline_better_p50_p90"]
            is _holds(_uc3(1.0, mirrored), 3)["safetail_better_p95_p99"])


def test_the_statements_checked_only_since_issue_28():
    # UC3: "in the median and p90 cases ... better than the target latency" (target 0.6 s).
    summary = _toy_summary({"SafeTail": (0.5, 0.59, 0.7, 0.9), "Oracle": (0.2, 0.3, 0.4, 0.5),
                            "MinProp-3": (0.45, 0.65, 0.75, 0.95)})
    assert _holds(summary, 3)["below_target_p50_p90"] is True
    late = summary.copy()
    late.loc[0, "p90_s"] = 0.61
    assert _holds(late, 3)["below_target_p50_p90"] is False
    # UC2: "SafeTail outperformed MinProp-3 in other cases" than the median, where MinProp-3
    # was faster (0.45 against 0.5 here).
    assert _holds(summary, 2)["beats_minprop3_tails"] is True
    caught = summary.copy()
    caught.loc[caught["method"] == "MinProp-3", "p95_s"] = 0.69
    assert _holds(caught, 2)["beats_minprop3_tails"] is False
    without = summary[summary["method"] != "MinProp-3"]
    assert _holds(without, 2)["beats_minprop3_tails"] is None


def test_every_claim_has_a_check_and_a_unique_key():
    everything = _toy_summary({"SafeTail": (0.3, 0.4, 0.5, 0.55), "Oracle": (0.2, 0.3, 0.4, 0.5),
                               **{n: (0.4, 0.5, 0.6, 0.7) for n in NINE}})
    for use_case in (1, 2, 3):
        claims = results.check_claims(everything, use_case)
        assert claims["key"].is_unique
        assert all(h in (True, False) for h in claims["holds"]), use_case
    with pytest.raises(KeyError, match="no check"):
        claim_checks._claim_holds("not_a_claim", everything)


# ---------------------------------------------------------------------------- the paper's setting

def test_setting_differences_name_what_is_not_the_papers():
    run = make_run()
    run.extra.update({"placement": "placements/paper_5servers.json",
                      "world": {"name": "calibrated", "target_latency_s": None}})
    assert results.setting_differences(run) == []
    landed = make_run()
    landed.preset = "paper-literal"
    landed.extra["world"] = {"name": "landed", "target_latency_s": None}
    assert results.setting_differences(landed) == []  # a preset's world is the paper's reading
    absolute = make_run()
    absolute.topology = str(REPOSITORY / "topologies" / "paper_5servers.json")
    assert results.setting_differences(absolute) == []
    other = make_run()
    other.topology = "topologies/3servers.json"
    other.extra["placement"] = "placements/3servers.json"
    assert results.setting_differences(other) == [
        "topology topologies/3servers.json (the paper's: topologies/paper_5servers.json)",
        "placement placements/3servers.json (the paper's: placements/paper_5servers.json)"]
    changed = make_run()
    changed.extra.update({"world": {"name": "calibrated", "target_latency_s": 0.75},
                          "world_overrides": {"target_latency_s": 0.75, "load_peak_users": 0.0}})
    assert results.setting_differences(changed) == ["--load-peak-users 0.0",
                                                    "--target-latency-s 0.75"]
    # A fixed τ is seen in the world itself, also in a run.json from before the overrides key.
    older = make_run()
    older.extra["world"] = {"name": "calibrated", "target_latency_s": 0.75}
    assert results.setting_differences(older) == [
        "a fixed target latency of 0.75 s (the paper's τ is Eq. 4's, per request)"]
    custom = make_run()
    custom.extra["world"] = {"name": "my-world", "target_latency_s": None}
    assert results.setting_differences(custom)[0].startswith("world 'my-world'")


def test_summary_outside_the_papers_setting_is_not_scored(tmp_path):
    requests = make_requests(np.random.default_rng(7), n_test=1000,
                             methods=("SafeTail", "Oracle", "Rand-1"))
    paper_run = make_run()
    (tmp_path / "paper").mkdir()
    results.write_results(tmp_path / "paper", requests, paper_run)
    text = (tmp_path / "paper" / "summary.md").read_text()
    assert "**Closeness to the paper (this run):" in text and "not scored" not in text
    assert "| Oracle over SafeTail |" in text and "| 1.08 |" in text
    other_run = make_run()
    other_run.extra["world_overrides"] = {"load_peak_users": 0.0}
    (tmp_path / "other").mkdir()
    results.write_results(tmp_path / "other", requests, other_run)
    text = (tmp_path / "other" / "summary.md").read_text()
    assert "**Closeness to the paper: not scored.**" in text and "--load-peak-users 0.0" in text
    assert "Closeness to the paper (this run)" not in text
    assert "| 1.08 |" not in text and "1.72" not in text  # no paper column filled
    assert "for information, not a score" in text
    # The latencies and ratios themselves are the same.
    assert (tmp_path / "other" / "summary.csv").read_bytes() == (
        tmp_path / "paper" / "summary.csv").read_bytes()


def test_summary_warns_when_percentiles_rest_on_too_few_requests(tmp_path):
    methods = ("SafeTail", "Oracle", "Rand-1")
    (tmp_path / "few").mkdir()
    results.write_results(tmp_path / "few", make_requests(np.random.default_rng(7), n_test=150,
                                                          methods=methods), make_run())
    text = (tmp_path / "few" / "summary.md").read_text()
    # 150 requests: 15 beyond p90, 7.5 beyond p95, 1.5 beyond p99.
    assert "**Too few test requests for p95, p99:**" in text and "150 per method" in text
    (tmp_path / "enough").mkdir()
    results.write_results(tmp_path / "enough", make_requests(np.random.default_rng(7), n_test=1000,
                                                             methods=methods), make_run())
    assert "Too few test requests" not in (tmp_path / "enough" / "summary.md").read_text()


# ---------------------------------------------------------------------------- markdown

def assert_cites_only_what_a_reader_has(text: str) -> None:
    """The paper's numbers are cited to the paper and to docs of the project, never to a file
    the project does not ship."""
    assert "facts.md" not in text
    assert "Section V of the paper; see docs/results.md" in text
    cited = re.findall(r"\b[\w./-]+\.md\b", text)
    assert cited and all((REPOSITORY / name).is_file() for name in cited), cited


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
    assert_cites_only_what_a_reader_has(text)


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
    assert_cites_only_what_a_reader_has(text)


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

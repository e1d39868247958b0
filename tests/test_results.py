"""Tests for the results folder contract (yafs_safetail.results, yafs_safetail.results.paper)."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from yafs_safetail import results
from yafs_safetail.results import (
    REQUESTS_COLUMNS,
    SUMMARY_COLUMNS,
    ResultsFileError,
    RunMetadata,
)
from yafs_safetail.results import paper as paper_results

N_SERVERS = 5
BASELINES = [f"{fam}-{x}" for fam in ("Rand", "MinLoad", "MinProp") for x in (1, 2, 3)]


def make_requests(
    rng: np.random.Generator,
    n_train: int = 120,
    n_test: int = 80,
    methods: tuple[str, ...] = ("SafeTail", "Oracle", *BASELINES),
) -> pd.DataFrame:
    """A synthetic requests table in contract form, with common random numbers per request."""
    per_server_s = rng.lognormal(mean=-0.7, sigma=0.4, size=(n_train + n_test, N_SERVERS))
    target_s = np.full(n_train + n_test, 0.55)
    rows = []
    for method in methods:
        family, level = results.parse_method(method)
        phases = [("train", 0, n_train), ("test", n_train, n_test)] if method == "SafeTail" \
            else [("test", n_train, n_test)]
        for phase, start, count in phases:
            for step in range(count):
                request = start + step
                if method == "Oracle":
                    chosen = np.arange(N_SERVERS)
                elif method == "SafeTail":
                    chosen = np.sort(rng.choice(N_SERVERS, size=rng.integers(1, 4), replace=False))
                else:
                    assert level is not None
                    chosen = np.sort(rng.choice(N_SERVERS, size=level, replace=False))
                latency = float(per_server_s[request, chosen].min())
                target = float(target_s[request])
                reward = -0.003 * math.exp(min(latency - target, 5)) if method == "SafeTail" \
                    else math.nan
                fallback = int(rng.random() < 0.01)
                parts = rng.dirichlet(np.ones(4)) * latency
                if fallback:
                    parts = np.full(4, math.nan)
                rows.append({
                    "method": method, "phase": phase, "episode": step // 256, "step": step,
                    "request_id": request, "latency_s": latency, "target_s": target,
                    "deviation_s": target - latency, "n_selected": len(chosen),
                    "access_rate": len(chosen) / N_SERVERS,
                    "servers": ";".join(str(i) for i in chosen), "reward": reward,
                    "refused": int(rng.integers(0, 2)), "fallback": fallback,
                    "upload_s": parts[0], "propagation_s": parts[1], "download_s": parts[2],
                    "compute_s": parts[3],
                })
    return pd.DataFrame(rows, columns=list(REQUESTS_COLUMNS))


def make_run(use_case: int = 1, seed: int = 0, beta: int = 20) -> RunMetadata:
    return RunMetadata(
        use_case=use_case, use_case_name="object detection (YOLOv5)", preset="paper", seed=seed,
        n_servers=N_SERVERS, beta=beta, train_steps=120, test_steps=80,
        topology="topologies/edge5.json", methods=["SafeTail", "Oracle", *BASELINES],
        package_version="0.1.0", command="python experiments/run_usecase.py --uc 1",
    )


def write_run_folder(path, rng: np.random.Generator, use_case: int = 1, seed: int = 0):
    path.mkdir(parents=True, exist_ok=True)
    requests = make_requests(rng)
    results.write_requests_csv(requests, path)
    results.write_run_json(path, make_run(use_case, seed))
    results.write_summary(path)  # reads both files back
    return requests


# ---------------------------------------------------------------------------- method names

def test_parse_method_and_report_order():
    assert results.parse_method("MinLoad-12") == ("MinLoad", 12)
    assert results.parse_method("SafeTail") == ("SafeTail", None)
    assert results.parse_method("Rand-x") == ("Rand-x", None)
    shuffled = ["MinProp-1", "Rand-2", "Oracle", "Other", "MinLoad-1", "Rand-1", "SafeTail"]
    assert results.sort_methods(shuffled) == [
        "SafeTail", "Oracle", "Rand-1", "Rand-2", "MinLoad-1", "MinProp-1", "Other"]
    assert results.baselines_of(shuffled, "Rand") == ["Rand-1", "Rand-2"]


# ---------------------------------------------------------------------------- requests.csv

def test_requests_round_trip(tmp_path):
    requests = make_requests(np.random.default_rng(1))
    results.write_requests_csv(requests, tmp_path)
    header = (tmp_path / "requests.csv").read_text().splitlines()[0]
    assert header == ",".join(REQUESTS_COLUMNS)
    back = results.read_requests_csv(tmp_path)
    assert list(back.columns) == list(REQUESTS_COLUMNS)
    assert back["servers"].iloc[0] == requests["servers"].iloc[0]
    assert back["step"].dtype == np.int64
    np.testing.assert_array_equal(back["latency_s"], requests["latency_s"])  # lossless
    assert back["upload_s"].isna().sum() == requests["upload_s"].isna().sum()


def test_single_server_column_stays_text(tmp_path):
    requests = make_requests(np.random.default_rng(2), methods=("Rand-1",))
    results.write_requests_csv(requests, tmp_path)
    back = results.read_requests_csv(tmp_path / "requests.csv")
    assert back["servers"].map(type).eq(str).all()
    assert set(back["servers"]) <= {"0", "1", "2", "3", "4"}


def test_write_requests_rejects_missing_column(tmp_path):
    requests = make_requests(np.random.default_rng(3)).drop(columns=["reward"])
    with pytest.raises(ValueError, match="reward"):
        results.write_requests_csv(requests, tmp_path)
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    ("mutate", "needle"),
    [
        (lambda f: f.drop(columns=["target_s"]), "missing column(s) target_s"),
        (lambda f: f.assign(phase=["warmup"] + list(f["phase"][1:])), "column phase, line 2"),
        (lambda f: f.assign(latency_s=["fast"] + list(f["latency_s"][1:])),
         "column latency_s, line 2"),
        (lambda f: f.assign(step=[1.5] + list(f["step"][1:])), "column step, line 2"),
        (lambda f: f.assign(fallback=[0, 3] + list(f["fallback"][2:])), "column fallback, line 3"),
        (lambda f: f.assign(method=[np.nan] + list(f["method"][1:])), "column method, line 2"),
        (lambda f: f.assign(deviation_s=-f["deviation_s"]), "column deviation_s, line 2"),
        (lambda f: f.assign(servers=["0;1;2;3"] * len(f)), "column servers, line 2"),
        (lambda f: f.assign(access_rate=f["access_rate"] * 10), "column access_rate, line 2"),
    ],
)
def test_read_requests_names_file_and_field(tmp_path, mutate, needle):
    frame = mutate(make_requests(np.random.default_rng(4), n_train=3, n_test=3,
                                 methods=("SafeTail",)))
    frame.to_csv(tmp_path / "requests.csv", index=False)
    with pytest.raises(ResultsFileError) as info:
        results.read_requests_csv(tmp_path)
    message = str(info.value)
    assert "requests.csv" in message and needle in message and "\n" not in message


def test_read_requests_missing_and_garbled(tmp_path):
    with pytest.raises(ResultsFileError, match="requests.csv: file not found"):
        results.read_requests_csv(tmp_path)
    (tmp_path / "requests.csv").write_bytes(b"")
    with pytest.raises(ResultsFileError, match="empty"):
        results.read_requests_csv(tmp_path)
    (tmp_path / "requests.csv").write_bytes(b"\xff\xfe\x00garbage\x00\n\x01,\x02\n")
    with pytest.raises(ResultsFileError, match="requests.csv"):
        results.read_requests_csv(tmp_path)


# ---------------------------------------------------------------------------- run.json

def test_run_json_round_trip_and_errors(tmp_path):
    run = make_run()
    run.extra["steps_scale"] = 0.1
    results.write_run_json(tmp_path, run)
    assert results.read_run_json(tmp_path) == run
    data = json.loads((tmp_path / "run.json").read_text())
    assert set(results.RUN_JSON_KEYS) <= set(data)
    del data["beta"]
    (tmp_path / "run.json").write_text(json.dumps(data))
    with pytest.raises(ResultsFileError, match=r"run.json: missing key\(s\) beta"):
        results.read_run_json(tmp_path)
    data["beta"] = "200"
    (tmp_path / "run.json").write_text(json.dumps(data))
    with pytest.raises(ResultsFileError, match="key beta: expected an integer"):
        results.read_run_json(tmp_path)
    (tmp_path / "run.json").write_text("{not json")
    with pytest.raises(ResultsFileError, match="run.json: not valid JSON"):
        results.read_run_json(tmp_path)


# ---------------------------------------------------------------------------- summary

def test_summary_matches_numpy():
    requests = make_requests(np.random.default_rng(5))
    summary = results.summarize(requests, preset="tuned")
    assert list(summary.columns) == list(SUMMARY_COLUMNS)
    assert list(summary["method"]) == ["SafeTail", "Oracle", *BASELINES]
    assert (summary["preset"] == "tuned").all()
    for method in ("SafeTail", "Rand-2"):
        test = requests[(requests["method"] == method) & (requests["phase"] == "test")]
        row = summary[summary["method"] == method].iloc[0]
        expected = np.percentile(test["latency_s"], [50, 90, 95, 99])
        np.testing.assert_allclose(row[["p50_s", "p90_s", "p95_s", "p99_s"]].astype(float),
                                   expected, rtol=0, atol=0)
        assert row["n_requests"] == len(test) == 80
        assert row["mean_access_rate"] == pytest.approx(test["access_rate"].mean())
        assert row["fallback_rate"] == pytest.approx(test["fallback"].mean())
        assert row["target_met_rate"] == pytest.approx((test["latency_s"] <= test["target_s"]).mean())
    safetail = summary.iloc[0]
    expected_abs = requests.query("method == 'SafeTail' and phase == 'test'")["reward"].abs().mean()
    assert safetail["mean_abs_reward"] == pytest.approx(expected_abs)
    assert math.isnan(summary[summary["method"] == "Oracle"]["mean_abs_reward"].iloc[0])
    # Common random numbers: Oracle is a lower bound at every percentile.
    for p in (50, 90, 95, 99):
        assert (summary[f"p{p}_s"] >= summary[summary["method"] == "Oracle"][f"p{p}_s"].iloc[0]).all()


def test_summary_files_are_deterministic(tmp_path):
    first, second = tmp_path / "a", tmp_path / "b"
    write_run_folder(first, np.random.default_rng(6))
    write_run_folder(second, np.random.default_rng(6))
    for name in ("requests.csv", "summary.csv", "summary.md", "run.json"):
        assert (first / name).read_bytes() == (second / name).read_bytes(), name
    # Rewriting in place gives the same bytes and leaves no temporary files behind.
    before = (first / "summary.csv").read_bytes()
    results.write_summary(first)
    assert (first / "summary.csv").read_bytes() == before
    assert sorted(p.name for p in first.iterdir()) == [
        "requests.csv", "run.json", "summary.csv", "summary.md"]
    back = results.read_summary_csv(first)
    assert list(back["method"])[:2] == ["SafeTail", "Oracle"]
    # Writing from the in-memory tables gives the same bytes as going through the files.
    third = tmp_path / "c"
    third.mkdir()
    summary = results.write_results(third, make_requests(np.random.default_rng(6)), make_run())
    assert list(summary["method"]) == list(back["method"])
    for name in ("requests.csv", "summary.csv", "summary.md", "run.json"):
        assert (third / name).read_bytes() == (first / name).read_bytes(), name


# ---------------------------------------------------------------------------- ratios

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

"""Tests for the results folder contract (yafs_safetail.results, yafs_safetail.results.paper)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from results_helpers import BASELINES, make_requests, make_run, write_run_folder

from yafs_safetail import results
from yafs_safetail.results import (
    REQUESTS_COLUMNS,
    SUMMARY_COLUMNS,
    ResultsFileError,
)


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


@pytest.mark.parametrize(("n_requests", "thin"), [
    (19, (50, 90, 95, 99)), (20, (90, 95, 99)), (99, (90, 95, 99)), (100, (95, 99)),
    (199, (95, 99)), (200, (99,)), (999, (99,)), (1000, ()), (40000, ()),
])
def test_thin_percentiles_have_fewer_than_ten_requests_beyond_them(n_requests, thin):
    # n·(1 − q) < 10: 1,000 requests leave exactly 10 beyond p99, 999 leave 9.99.
    assert results.thin_percentiles(n_requests) == thin


def test_summary_names_its_thin_percentiles_and_reads_them_back(tmp_path):
    write_run_folder(tmp_path, np.random.default_rng(4))  # 80 test requests per method
    summary = results.read_summary_csv(tmp_path)
    assert (summary["thin_percentiles"] == "p90;p95;p99").all()
    enough = results.summarize(make_requests(np.random.default_rng(4), n_train=0, n_test=1000,
                                             methods=("Oracle",)))
    assert list(enough["thin_percentiles"]) == [""]
    enough.to_csv(tmp_path / "summary.csv", index=False)
    assert list(results.read_summary_csv(tmp_path)["thin_percentiles"]) == [""]
    # A summary.csv from before the column: derived from n_requests.
    summary.drop(columns="thin_percentiles").to_csv(tmp_path / "summary.csv", index=False)
    assert (results.read_summary_csv(tmp_path)["thin_percentiles"] == "p90;p95;p99").all()


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

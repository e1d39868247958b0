"""``yafs-safetail score``: one policy in every world, beside SafeTail, with intervals paired by
request; the suite a campaign (resumable, the same files again), bad input one line."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from in_process import run_in_process

from yafs_safetail.commands import score_policy
from yafs_safetail.methods.baselines import LeastLoadedTwo
from yafs_safetail.results.score_report import block_length, paired_ratio, score_table
from yafs_safetail.runs.score_suite import PROFILES, SCENARIOS, suite_specs
from yafs_safetail.runs.sweep_points import PER_REQUEST, point_specs

REPOSITORY = Path(__file__).resolve().parents[1]
NEAREST_FREE = f"{REPOSITORY / 'examples' / 'custom_policy' / 'nearest_free.py'}:NearestFree"
BAD_POLICIES = REPOSITORY / "tests" / "bad_policies.py"
#: The smallest suite that still has both worlds: the paper's use case 1 and one contention point.
SMALL = ("--scenarios", "uc1,load-low", "--seeds", "3", "--workers", "2", "-q")


# ------------------------------------------------------------------ the paired interval


def test_a_policy_against_itself_is_one_with_a_zero_width_interval():
    rng = np.random.default_rng(0)
    latencies = [rng.lognormal(size=500), rng.lognormal(size=300)]
    for figure in ("p50_s", "p99_s", "energy_j"):
        assert paired_ratio(latencies, latencies, figure, np.random.default_rng(1), 200) == (1.0, 1.0, 1.0)


def test_a_policy_half_as_slow_on_every_request_is_half_with_no_doubt():
    rng = np.random.default_rng(0)
    theirs = [rng.lognormal(size=400)]
    ratio, low, high = paired_ratio([theirs[0] / 2], theirs, "p99_s", np.random.default_rng(1), 200)
    assert ratio == pytest.approx(0.5) and low == pytest.approx(0.5) and high == pytest.approx(0.5)


def test_the_paired_interval_is_narrower_than_the_unpaired_one_on_shared_draws():
    # Both methods' latencies follow the same per-request draw (common random numbers), as in a
    # run: pairing removes that shared variation, resampling each method apart does not.
    rng = np.random.default_rng(3)
    shared = rng.lognormal(sigma=1.0, size=4000)
    mine, theirs = shared * rng.lognormal(sigma=0.05, size=4000), shared * 1.1
    _, low, high = paired_ratio([mine], [theirs], "p50_s", np.random.default_rng(4), 300)
    boot = np.random.default_rng(5)
    unpaired = [np.median(mine[boot.integers(0, 4000, 4000)]) / np.median(theirs[boot.integers(0, 4000, 4000)])
                for _ in range(300)]
    unpaired_low, unpaired_high = np.percentile(unpaired, [2.5, 97.5])
    assert low < 1 / 1.1 < high
    assert high - low < (unpaired_high - unpaired_low) / 3


def test_blocks_keep_each_seeds_requests_apart_and_grow_with_the_run():
    assert block_length(1) == 1 and block_length(400) == 20 and block_length(20_000) == 141
    with pytest.raises(ValueError, match="different numbers of requests"):
        paired_ratio([np.ones(3)], [np.ones(4)], "p50_s", np.random.default_rng(0))
    # One seed's requests all below another's: a resample that mixed seeds would move the figure.
    low_seed, high_seed = np.linspace(1, 2, 100), np.linspace(10, 20, 50)
    ratio, low, high = paired_ratio([low_seed, high_seed], [low_seed, high_seed * 2], "energy_j",
                                    np.random.default_rng(0), 200)
    kept_apart = (low_seed.mean() * 100 + high_seed.mean() * 50) / (low_seed.mean() * 100 + high_seed.mean() * 100)
    assert ratio == pytest.approx(kept_apart) and low < ratio < high and high - low < 0.05


def _requests(method: str, latency: np.ndarray, servers: float) -> pd.DataFrame:
    n = len(latency)
    return pd.DataFrame({"method": method, "request": np.arange(n), "latency_s": latency,
                         "servers": servers, "energy_j": servers * 10.0})


def test_the_table_sets_the_policy_beside_safetail_oracle_the_best_fixed_and_the_least_loaded():
    rng = np.random.default_rng(0)
    base = rng.lognormal(size=300)
    seed = pd.concat([_requests("SafeTail", base * 1.2, 1.5), _requests("Oracle", base, 5),
                      _requests("Rand-1", base * 3, 1), _requests("MinLoad-2", base * 1.5, 2),
                      _requests("Mine", base * 1.1, 1.2), _requests("LeastLoaded-2", base * 1.3, 2)])
    table = score_table({"uc1": [seed]}, "Mine", "LeastLoaded-2", seed=1)
    assert table["role"].tolist() == ["your policy", "SafeTail", "Oracle", "best fixed", "least-loaded"]
    rows = table.set_index("role")
    assert rows.loc["best fixed", "method"] == "MinLoad-2"  # the fixed method with the lowest p99
    assert rows.loc["SafeTail", "ratio_p99_s"] == pytest.approx(1.1 / 1.2)
    assert rows.loc["your policy", "servers"] == pytest.approx(1.2)
    # Requests that do not pair are refused, never compared.
    shuffled = seed.copy()
    shuffled.loc[shuffled["method"] == "Oracle", "request"] += 1
    with pytest.raises(ValueError, match="Oracle and Mine met different requests"):
        score_table({"uc1": [shuffled]}, "Mine", "LeastLoaded-2")


# ------------------------------------------------------------------ the suite


def test_the_suite_covers_every_scenario_with_the_policy_and_the_least_loaded_beside_it():
    specs = suite_specs(NEAREST_FREE, PROFILES["full"])
    assert [spec.name for spec in specs] == [f"{s.name}/seed{seed}" for s in SCENARIOS for seed in (0, 1, 2)]
    kinds = {spec.name.split("/")[0]: spec.kind for spec in specs}
    assert kinds == {"uc1": "experiment", "uc2": "experiment", "uc3": "experiment", "load-low": "load_point",
                     "load-mid": "load_point", "load-high": "load_point", "failures": "failure_point",
                     "walking": "experiment"}
    for spec in specs:
        methods = spec.settings["methods" if spec.kind == "experiment" else "user_methods"]
        assert methods[0] == NEAREST_FREE and methods[1].startswith("LeastLoaded-2=")
        assert spec.kind == "experiment" or spec.settings[PER_REQUEST] is True
    walking = [spec for spec in specs if spec.name.startswith("walking")][0].settings
    assert walking["mobility"] == "random-waypoint" and walking["topology"].endswith("campus_5servers.json")
    assert len({spec.run_id for spec in specs}) == len(specs)


def test_a_point_that_keeps_its_requests_gives_the_figures_of_its_table(tmp_path):
    from yafs_safetail.runs.score_suite import _sweep_config
    from yafs_safetail.runs.sweep_points import run_sweep_point

    load_low = [s for s in SCENARIOS if s.name == "load-low"][0]
    config = _sweep_config(load_low, [NEAREST_FREE], PROFILES["quick"], 0)
    config = type(config)(**{**config.__dict__, "safetail": False, "methods": ("Oracle", "Rand-1"),
                             "test_requests_per_load": 600})
    (spec,) = point_specs(config)
    plain = run_sweep_point(spec, tmp_path / "plain")
    assert not (plain / "requests.csv").exists()  # only a point that asks keeps its requests
    kept_spec = type(spec)(name=spec.name, run_id="kept", settings={**spec.settings, PER_REQUEST: True},
                           kind=spec.kind)
    kept = run_sweep_point(kept_spec, tmp_path / "kept")
    assert (kept / "sweep.csv").read_bytes() == (plain / "sweep.csv").read_bytes()
    rows = pd.read_csv(kept / "requests.csv")
    table = pd.read_csv(kept / "sweep.csv").set_index("method")
    for method, part in rows.groupby("method"):
        assert len(part) == table.loc[method, "n_requests"]
        assert np.percentile(part["latency_s"], 99) == pytest.approx(table.loc[method, "p99_s"], rel=1e-5)
        assert part["n_copies"].mean() == pytest.approx(table.loc[method, "mean_n_selected"], rel=1e-5)


def test_least_loaded_two_sends_each_request_to_the_two_idlest_servers_of_all():
    from types import SimpleNamespace

    policy = LeastLoadedTwo(5, np.random.default_rng(0))
    observation = SimpleNamespace(server_active_users=np.array([4, 0, 3, 1, 9]))
    assert sorted(policy.choose(observation)) == [1, 3] and policy.name == "LeastLoaded-2"


# ------------------------------------------------------------------ the command


def test_the_quick_suite_writes_its_report_and_a_second_call_recomputes_nothing(tmp_path):
    done = run_in_process(score_policy.main, "--method", NEAREST_FREE, *SMALL, "--out", tmp_path / "s")
    assert done.returncode == 0, done.stderr
    out = tmp_path / "s"
    report = (out / "REPORT.md").read_text()
    assert report.startswith("# NearestFree scored in 2 scenarios (profile quick)")
    assert "Against SafeTail's p99, NearestFree is" in report and "![your p99" in report
    for heading in ("### uc1: the paper's world, use case 1", "### load-low: many users"):
        assert heading in report
    table = pd.read_csv(out / "score.csv")
    assert set(table["scenario"]) == {"uc1", "load-low"}
    mine = table[table["role"] == "your policy"]
    assert (mine["ratio_p99_s"] == 1).all() and (mine["ratio_p99_s_low"] == 1).all()
    roles = table[table["scenario"] == "load-low"]["method"].tolist()
    assert roles[:3] == ["NearestFree", "SafeTail", "SafeTail-CA"] and "LeastLoaded-2" in roles
    assert (table["ratio_p99_s_low"] <= table["ratio_p99_s"]).all()
    assert (table["ratio_p99_s"] <= table["ratio_p99_s_high"]).all()
    settings = json.loads((out / "score.json").read_text())
    assert settings["kind"] == "score_policy" and settings["seeds"] == [3] and settings["name"] == "quick"
    assert (out / "score.png").stat().st_size > 0
    first = {name: (out / name).read_bytes() for name in ("REPORT.md", "score.csv")}
    again = run_in_process(score_policy.main, "--method", NEAREST_FREE, *SMALL, "--out", out)
    assert again.returncode == 0, again.stderr
    state = json.loads((out / "campaign.json").read_text())
    assert {run["status"] for run in state["runs"]} == {"done earlier"}
    assert first == {name: (out / name).read_bytes() for name in first}


def test_a_killed_suite_resumes_without_redoing_finished_runs(tmp_path):
    from yafs_safetail.runs.engines import KILL_RUN_ENV

    command = [sys.executable, str(REPOSITORY / "experiments" / "score_policy.py"), "--method", NEAREST_FREE,
               *SMALL, "--out", str(tmp_path / "s")]
    killed = subprocess.run(command, capture_output=True, text=True, timeout=600,
                            env={**os.environ, KILL_RUN_ENV: "load-low/seed3"})
    assert killed.returncode == 1, killed.stderr[-2000:]
    assert not (tmp_path / "s" / "REPORT.md").exists()  # no report from a part of the suite
    finished = (tmp_path / "s" / "uc1" / "seed3" / "run.json").stat().st_mtime_ns
    again = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr[-2000:]
    state = {run["name"]: run["status"] for run in json.loads((tmp_path / "s" / "campaign.json").read_text())["runs"]}
    assert state == {"uc1/seed3": "done earlier", "load-low/seed3": "done"}
    assert (tmp_path / "s" / "uc1" / "seed3" / "run.json").stat().st_mtime_ns == finished
    assert (tmp_path / "s" / "REPORT.md").is_file()


@pytest.mark.parametrize(("extra", "message"), [
    (("--method", f"{BAD_POLICIES}:Empty"), "returned []: no server"),
    (("--method", f"{REPOSITORY}/no_such_file.py:Mine"), "no_such_file.py"),
    (("--method", NEAREST_FREE, "--method", NEAREST_FREE), "--method: expected your one policy, got 2"),
    (("--method", NEAREST_FREE, "--scenarios", "uc1,moon"), "moon"),
    (("--method", NEAREST_FREE, "--profile", "huge"), "huge"),
])
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, extra, message):
    done = run_in_process(score_policy.main, *extra, "--scenarios", "uc1", "--out", tmp_path / "s") \
        if "--scenarios" not in extra else run_in_process(score_policy.main, *extra, "--out", tmp_path / "s")
    assert done.returncode == 2, (done.returncode, done.stderr)
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], done.stderr
    assert not (tmp_path / "s").exists()


def test_a_folder_with_someone_elses_report_is_left_alone(tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "REPORT.md").write_text("my notes\n")
    done = run_in_process(score_policy.main, "--method", NEAREST_FREE, "--scenarios", "uc1", "--out", out)
    assert done.returncode != 0 and "not a scoring suite's" in done.stderr
    assert sorted(p.name for p in out.iterdir()) == ["REPORT.md"]
    assert (out / "REPORT.md").read_text() == "my notes\n"

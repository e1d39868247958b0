"""The method's own optimum (issue 48): the "most zeros" policy, fitted learner-free, measured on
the very requests a run's test phase sees, beside SafeTail's figures from the run's folder; and
``investigations/learner_vs_optimum.py``, which prints the comparison."""

from __future__ import annotations

import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from in_process import run_in_process, run_usecase_here

from yafs_safetail.results.files import read_requests_csv
from yafs_safetail.results.reproduction import RUN_FOLDER
from yafs_safetail.runs import method_optimum as mo
from yafs_safetail.runs import most_zeros as mz
from yafs_safetail.settings.experiment import ExperimentConfig

REPOSITORY = Path(__file__).resolve().parents[1]
#: A fit small enough for a test: one world-calibration seed, two episodes of 256 requests.
FIT = {"fit_seeds": [1000], "fit_steps": 512}


def _script(name: str):
    spec = importlib.util.spec_from_file_location(name, REPOSITORY / "investigations" / f"{name}.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _table(reward: np.ndarray, loads: np.ndarray, inputs: np.ndarray) -> mz.RequestTable:
    n = len(reward)
    return mz.RequestTable(reward=reward, loads=loads,
                           features={"input": inputs, "uplink": np.ones(n), "downlink": np.ones(n)},
                           target_s=np.ones(n), max_load=4)


def test_eq5_pays_zero_only_to_one_server_in_time_or_to_all_servers_late():
    # Two requests, three servers' worth of subsets: k = 1, 2, 3 servers.
    n_selected = np.array([1, 2, 3])
    latency_s = np.array([[0.5, 0.5, 0.5], [2.0, 2.0, 2.0]])
    rewards = mz.eq5_rewards(latency_s, np.array([1.0, 1.0]), n_selected, 3, delta=0.003)
    assert rewards[0, 0] == 0.0 and rewards[1, 2] == 0.0
    assert (rewards[0, 1:] < 0).all() and (rewards[1, :2] < 0).all()


def test_eq5_rewards_score_every_case_as_the_reward_function():
    # eq5_policies.py's table, moved here: every (request, subset) as the learner's reward.
    from yafs_safetail.methods.safetail.reward import reward

    rng = np.random.default_rng(3)
    latency_s = rng.uniform(0.5, 3.0, (40, 31))
    target_s = rng.uniform(1.0, 2.0, 40)
    latency_s[0, 4] = target_s[0]  # case 1: exactly on target
    n_selected = np.array([bin(a + 1).count("1") for a in range(31)])
    ours = mz.eq5_rewards(latency_s, target_s, n_selected, 5, 0.003)
    expected = [[reward(latency_s[i, a], target_s[i], n_selected[a], 5, 0.003) for a in range(31)] for i in range(40)]
    np.testing.assert_allclose(ours, expected, rtol=1e-12, atol=0)


def test_most_zeros_picks_each_key_s_most_rewarded_subset_and_backs_off_to_coarser_keys():
    # Two servers, three actions: 0 = {0}, 1 = {1}, 2 = {0, 1}. Under loads (0, 0) the action
    # that earns 0 depends on the input size; loads (1, 0) come with small inputs only.
    loads = np.array([[0, 0]] * 8 + [[1, 0]] * 3)
    inputs = np.array([1.0, 2.0, 5.0, 6.0, 9.0, 10.0, 11.0, 12.0, 1.5, 2.5, 0.5])
    zero_at = [0, 0, 1, 1, 1, 1, 1, 1, 2, 2, 2]
    reward = np.full((len(zero_at), 3), -1.0)
    reward[np.arange(len(zero_at)), zero_at] = 0.0
    fit = mz.fit_most_zeros(_table(reward, loads, inputs), "loads+input")
    assert mz.apply_most_zeros(fit, _table(reward, loads, inputs)).tolist() == zero_at
    assert fit.fallback_action == 1  # the most zeros over every fit request
    asked = _table(np.zeros((3, 3)), np.array([[1, 0], [0, 1], [0, 0]]), np.array([100.0, 1.0, 1.0]))
    # (1, 0) with a large input: unseen, so the loads alone answer; (0, 1): never seen at all.
    assert mz.apply_most_zeros(fit, asked).tolist() == [2, 1, 0]


def test_a_finer_key_earns_at_least_the_coarser_key_s_zeros_on_its_own_fit_requests():
    config = ExperimentConfig(use_case=1)
    table = mz.fit_world_table(config, 1000, 512)
    shares = []
    for key in mz.KEYS:
        actions = mz.apply_most_zeros(mz.fit_most_zeros(table, key), table)
        shares.append(float(np.mean(table.reward[np.arange(len(actions)), actions] == 0.0)))
    best_fixed = float((table.reward == 0.0).mean(axis=0).max())
    assert shares == sorted(shares) and shares[0] >= best_fixed
    assert shares[-1] > best_fixed  # keying on the loads earns more zeros than any one subset


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory) -> Path:
    """A small UC1 run where a reproduction puts it (``OUT/uc1-paper/seed0``)."""
    out = tmp_path_factory.mktemp("reproduction")
    folder = out / RUN_FOLDER.format(use_case=1, preset="paper", seed=0)
    done = run_usecase_here("--uc", "1", "--steps-scale", "0.02", "--no-figures", "--quiet", "--out", folder)
    assert done.returncode == 0, done.stderr[-2000:]
    return folder


def test_the_policy_is_measured_on_the_requests_of_the_run_s_test_phase(run_folder):
    world, delta, beta = mz.run_test_world(mo.run_config(run_folder))
    requests = read_requests_csv(run_folder)
    test = requests[(requests["method"] == "SafeTail") & (requests["phase"] == "test")].sort_values("step")
    assert world.n_steps == len(test)
    assert np.array_equal(world.target_s, test["target_s"].to_numpy(float))
    (row,) = mo.compare(mo.run_folders(run_folder.parents[1]), **FIT)
    assert row.use_case == 1 and row.seeds == (0,)
    assert row.safetail_zero_share == pytest.approx(float((test["reward"] == 0.0).mean()))
    assert row.safetail_access_rate == pytest.approx(float(test["access_rate"].mean()))
    # The optimum's figures are the fitted policy's on that same world.
    policy = mz.fit_for(mo.run_config(run_folder), mz.DEFAULT_KEY, **FIT)
    table = mz.request_table(world, delta)
    figures = mo.seed_figures(0, mz.apply_most_zeros(policy, table), table, beta)
    assert row.optimum.seeds == (figures,)
    assert figures.access_rate == pytest.approx(figures.mean_servers / world.n_servers)
    assert len(figures.window_means) == -(-world.n_steps // beta)


def test_a_run_whose_requests_are_not_the_redrawn_world_s_is_refused(run_folder, tmp_path):
    copy = tmp_path / RUN_FOLDER.format(use_case=1, preset="paper", seed=0)
    shutil.copytree(run_folder, copy)
    requests = pd.read_csv(copy / "requests.csv")
    first = requests.index[(requests["method"] == "SafeTail") & (requests["phase"] == "test")][0]
    requests.loc[first, "reward"] -= 0.5
    requests.to_csv(copy / "requests.csv", index=False)
    with pytest.raises(mo.MethodOptimumError, match=r"requests\.csv: column reward"):
        mo.compare(mo.run_folders(tmp_path), **FIT)


def test_safetail_s_side_counts_its_own_test_rewards_of_exactly_zero(run_folder, tmp_path):
    copy = tmp_path / "run"
    shutil.copytree(run_folder, copy)
    requests = pd.read_csv(copy / "requests.csv")
    safetail = requests["method"] == "SafeTail"
    test = safetail & (requests["phase"] == "test")
    rows = requests.index[test]
    requests.loc[rows, "reward"] = -0.01
    requests.loc[rows[:20], "reward"] = 0.0
    requests.loc[safetail & (requests["phase"] == "train"), "reward"] = 0.0  # not the test's
    requests.loc[rows, "n_selected"] = 2
    requests.loc[rows, "servers"] = "0;1"
    requests.loc[rows, "access_rate"] = 0.4
    requests.to_csv(copy / "requests.csv", index=False)
    side = mo.safetail_side(copy)
    assert side.zero_share == pytest.approx(20 / len(rows))
    assert side.mean_servers == 2 and side.access_rate == pytest.approx(0.4) and side.seed == 0


def test_the_goals_compare_with_the_policy_s_figures():
    figures = mo.SeedFigures(0, zero_share=0.90, mean_servers=1.3, access_rate=0.26, median_servers=1,
                             min_servers=1, max_servers=5, window_means=(1.0, 2.0), mean_target_s=1.0)
    optimum = mo.Optimum(1, mz.DEFAULT_KEY, (1000,), (figures,))
    close = mo.Comparison(1, (mo.SafeTailFigures(0, 0.86, 1.5, 0.30),), optimum)
    assert close.zero_share_met and close.access_met
    far = mo.Comparison(1, (mo.SafeTailFigures(0, 0.84, 1.6, 0.32),), optimum)
    assert not far.zero_share_met and not far.access_met
    assert optimum.reaches("servers_1_to_3")  # windows 1.0-2.0: in [1, 3] and varying
    flat = mo.Optimum(1, mz.DEFAULT_KEY, (1000,), (mo.SeedFigures(
        0, 0.9, 1.0, 0.2, 1, 1, 1, (1.0, 1.0), 1.0),))
    assert not flat.reaches("servers_1_to_3") and "1.00–1.00" in flat.claim_figure("servers_1_to_3")


def test_the_command_prints_the_comparison_of_a_reproduction_folder(run_folder):
    done = run_in_process(_script("learner_vs_optimum").main, "--runs", run_folder.parents[1],
                          "--fit-seeds", "1000", "--fit-steps", "512")
    assert done.returncode == 0, done.stderr
    row = next(line for line in done.stdout.splitlines() if line.startswith("| UC1 |"))
    (expected,) = mo.compare(mo.run_folders(run_folder.parents[1]), **FIT)
    cells = [cell.strip() for cell in row.strip("|").split("|")]
    assert cells[2:5] == [f"{expected.safetail_zero_share:.3f}", f"{expected.optimum.zero_share:.3f}",
                          f"{expected.zero_share_gap:+.3f}"]
    assert cells[6:9] == [f"{expected.safetail_access_rate:.3f}", f"{expected.optimum.access_rate:.3f}",
                          f"{expected.access_gap:+.3f}"]
    assert any(line.startswith("UC1 most zeros") and "servers_1_to_3" in line for line in done.stdout.splitlines())


def test_the_command_measures_the_policy_alone_on_seeds():
    done = run_in_process(_script("learner_vs_optimum").main, "--seeds", "0,1", "--uc", "2",
                          "--steps-scale", "0.02", "--fit-seeds", "1000", "--fit-steps", "512")
    assert done.returncode == 0, done.stderr
    (line,) = done.stdout.splitlines()
    optimum = mo.optimum_for_seeds(2, [0, 1], steps_scale=0.02, **FIT)
    assert line.startswith("UC2 most zeros") and f"access {optimum.access_rate:.3f}" in line
    assert "mean_servers_2_to_3 holds in" in line


@pytest.mark.parametrize("make, expected", [
    (lambda root: None, "no run folder uc<N>-paper/seed<S>"),
    (lambda root: (root / "uc1-paper" / "seed0").mkdir(parents=True), "run.json"),
])
def test_a_bad_folder_is_one_line_and_exit_2(tmp_path, make, expected):
    make(tmp_path)
    done = subprocess.run([sys.executable, str(REPOSITORY / "investigations" / "learner_vs_optimum.py"),
                           "--runs", str(tmp_path)], capture_output=True, text=True, cwd=REPOSITORY,
                          timeout=120)
    assert done.returncode == 2
    assert "Traceback" not in done.stderr and len(done.stderr.strip().splitlines()) == 1
    assert done.stderr.startswith("error: ") and expected in done.stderr and str(tmp_path) in done.stderr

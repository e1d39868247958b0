"""The value learner in the single-user world (``--objective value``): what it regresses with the
D15 prices, its options, and a small run (docs/deviations.md D13, D15)."""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from in_process import run_usecase_here

from yafs_safetail import results
from yafs_safetail.edge.observation import Observation
from yafs_safetail.methods.safetail.presets import get_preset
from yafs_safetail.methods.safetail.reward import copy_price, latency_score, priced_latency_score
from yafs_safetail.record import RequestRecord
from yafs_safetail.settings.experiment import ExperimentConfig
from yafs_safetail.worlds.recipe import learner_config

ROOT = Path(__file__).resolve().parents[1]
N_SERVERS = 5


def _observation(step: int, active_users: tuple[int, ...]) -> Observation:
    n = N_SERVERS
    return Observation(
        server_uplink_bps=np.full(n, 20e6), server_downlink_bps=np.full(n, 20e6),
        server_memory_util=np.full(n, 0.05), server_cpu_util=np.full(n, 0.5),
        server_active_users=np.array(active_users), server_median_propagation_s=np.full(n, 0.1),
        input_bytes=80e3, est_output_bytes=2e3, gamma=np.array([]), user_location=np.array([0.0, 0.0]),
        user_uplink_bps=20e6, user_downlink_bps=20e6, server_max_load=np.full(n, 4), step=step)


def _record(step: int, servers: tuple[int, ...], latency_s: float, target_s: float, end_reason: str,
            server_energy_j: float, radio_energy_j: float) -> RequestRecord:
    return RequestRecord(
        method="SafeTail", step=step, request_id=step, time_emit_s=float(step), latency_s=latency_s,
        target_s=target_s, servers=servers, n_servers=N_SERVERS, refused=0, fallback=end_reason != "reply",
        winner=servers[0], upload_s=0.1, propagation_s=0.1, download_s=0.1, compute_s=0.5,
        end_reason=end_reason, server_energy_j=server_energy_j, radio_energy_j=radio_energy_j)


def test_the_priced_value_score_is_the_latency_term_less_the_prices():
    for latency_s, target_s, energy_j, replied in ((0.8, 1.9, 7.2, True), (14.4, 1.9, 21.5, False),
                                                   (2.5, 1.2, 0.0, True)):
        term = -math.log(latency_s / target_s)
        assert priced_latency_score(latency_s, target_s, energy_j, replied) == latency_score(latency_s, target_s)
        assert priced_latency_score(latency_s, target_s, energy_j, replied, 0.05, 1.0) == pytest.approx(
            term - 0.05 * energy_j - 1.0 * (not replied))
    with pytest.raises(ValueError, match="prices must be >= 0"):
        priced_latency_score(1.0, 1.0, 5.0, True, -0.01, 0.0)


def test_the_value_network_regresses_the_priced_score_of_hand_made_records():
    """What the policy hands the learner is the latency term less price × energy less the
    penalty; the record's reward is that less the copies' price known at dispatch."""
    from yafs_safetail.methods.safetail.learner import SafeTailLearner
    from yafs_safetail.methods.safetail.policy import SafeTailPolicy
    from yafs_safetail.methods.safetail.spaces import StateScales, state_dim

    price_per_j, penalty = 0.02, 1.5
    config = dataclasses.replace(get_preset("paper", 1), objective="value", energy_price_per_j=price_per_j,
                                 failure_penalty=penalty)
    learner = SafeTailLearner(N_SERVERS, state_dim(N_SERVERS, 0, 2), config, seed=0)
    policy = SafeTailPolicy(N_SERVERS, np.random.default_rng(0), learner=learner,
                            scales=StateScales.for_use_case(1), training=True, reward_name="latency-cost")
    learned: list[float] = []
    stored = learner.observe
    learner.observe = lambda state, action, reward: learned.append(reward) or stored(state, action, reward)
    cases = [(0.7, 1.9, "reply", 6.0, 0.9), (14.4, 1.9, "all_lost", 20.0, 1.1), (2.4, 1.6, "reply", 13.0, 0.4)]
    for step, (latency_s, target_s, end_reason, server_j, radio_j) in enumerate(cases):
        active_users = (step, 0, 2, 1, 3)
        servers = policy.choose(_observation(step, active_users))
        done = policy.feedback(_record(step, servers, latency_s, target_s, end_reason, server_j, radio_j))
        expected = (-math.log(latency_s / target_s) - price_per_j * (server_j + radio_j)
                    - penalty * (end_reason != "reply"))
        assert learned[-1] == pytest.approx(expected)
        assert done.reward == pytest.approx(expected - copy_price(sum(active_users[i] for i in servers)))
    assert len(learned) == len(cases)


def test_the_learner_option_sets_the_objective_and_its_networks():
    _, default = learner_config(ExperimentConfig())
    # paper's default is §III's target vector (the spec owner's decision of 2026-11-28).
    assert (default.objective, default.n_networks) == ("target-vector", 1)
    _, value = learner_config(ExperimentConfig(objective="value", n_networks=2, energy_price_per_j=0.01))
    assert (value.objective, value.n_networks, value.energy_price_per_j) == ("value", 2, 0.01)
    assert dataclasses.replace(value, objective="target-vector", n_networks=1, energy_price_per_j=0.0) == default


def _run_usecase(*args: str, out: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(ROOT / "experiments/run_usecase.py"), *args, "--out", str(out)],
                          capture_output=True, text=True, timeout=900, cwd=ROOT, check=False)


@pytest.mark.parametrize(("args", "expected"), [
    (("--energy-price-per-j", "-0.01"), "--energy-price-per-j: expected a non-negative number"),
    (("--objective", "q-table"), "--objective: invalid choice: 'q-table'"),
    (("--value-networks", "0"), "--value-networks: expected a positive integer"),
    (("--value-networks", "3"), "--value-networks 3: only the value learner averages networks"),
])
def test_a_bad_learner_option_is_one_line(tmp_path, args, expected):
    done = _run_usecase("--uc", "1", "--steps-scale", "0.03", "--no-figures", *args, out=tmp_path / "out")
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0], done.stderr
    assert not (tmp_path / "out").exists()


def test_run_usecase_with_the_value_learner_and_a_price(tmp_path):
    out = tmp_path / "out"
    done = run_usecase_here("--uc", "1", "--seed", "3", "--steps-scale", "0.03", "--failure-probability", "0.3",
                            "--objective", "value", "--energy-price-per-j", "0.05", "--no-figures", "--quiet", "--out", out)
    assert done.returncode == 0, done.stderr[-2000:]
    for name in ("requests.csv", "summary.csv", "summary.md", "run.json", "policy.keras"):
        assert (out / name).is_file(), name
    learner = json.loads((out / "run.json").read_text())["learner"]
    assert (learner["objective"], learner["n_networks"], learner["energy_price_per_j"]) == ("value", 1, 0.05)
    assert "failure_penalty" not in learner  # a price left at 0 is not written
    # Evaluated again from its file, it makes the same greedy choices with the same reward: a
    # saved value network is read with the value learner's own reward, not Eq. 5.
    again = tmp_path / "again"
    done = run_usecase_here("--uc", "1", "--seed", "3", "--steps-scale", "0.03", "--failure-probability", "0.3",
                            "--policy", str(out / "policy.keras"), "--no-figures", "--quiet", "--out", again)
    assert done.returncode == 0, done.stderr[-2000:]
    trained, loaded = (results.read_requests_csv(folder) for folder in (out, again))
    columns = ["step", "servers", "reward"]
    trained = trained[(trained["method"] == "SafeTail") & (trained["phase"] == "test")][columns]
    loaded = loaded[(loaded["method"] == "SafeTail") & (loaded["phase"] == "test")][columns]
    assert len(loaded) > 0
    assert trained.reset_index(drop=True).equals(loaded.reset_index(drop=True))


def test_the_run_id_hashes_the_learner_only_when_set():
    from unittest import mock

    from yafs_safetail.runs import grid

    with mock.patch.object(grid, "code_version", lambda: "0.0.0+git.test"), \
            mock.patch.object(grid, "_digest", lambda path: "digest"):
        default = grid.config_run_id(ExperimentConfig())
        assert default == "a89f6bb8a559"  # tests/test_config.py's pinned id of the defaults
        value = grid.config_run_id(ExperimentConfig(objective="value"))
        assert value != default
        assert grid.config_run_id(ExperimentConfig(objective="value", n_networks=3)) not in (default, value)

"""The ``q-target`` objective: the original code's Q-style training targets (docs/calibration.md
rule 7, docs/deviations.md D18)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from test_policy_learner import DIM, N, best_of, learn_toy_bandit, states, tiny_config

from yafs_safetail.methods.safetail import SafeTailLearner
from yafs_safetail.methods.safetail.presets import Q_TARGET_DISCOUNT, get_preset

ROOT = Path(__file__).resolve().parents[1]


def q_config(**changes: object) -> Any:
    return tiny_config(objective="q-target", **changes)


@pytest.mark.parametrize("use_case", [1, 2, 3])
def test_every_preset_trains_on_the_target_vector(use_case: int) -> None:
    # The spec owner's decision of 2026-11-28 (issue 48): the paper's text specifies the method,
    # so paper takes §III's target vector; rule 7's Q-style targets only when asked by name.
    assert get_preset("paper", use_case).objective == "target-vector"
    assert get_preset("paper-literal", use_case).objective == "target-vector"
    assert get_preset("tuned", use_case).objective == "target-vector"


def test_targets_are_the_outputs_with_the_taken_entry_bootstrapped_from_the_next_state() -> None:
    learner = SafeTailLearner(N, DIM, q_config(), seed=1)
    x = states(5, seed=2)
    actions, rewards = [4, 30, 0, 7, 12], [-0.01, 0.0, -0.2, -0.003, -0.05]
    for state, action, reward in zip(x, actions, rewards, strict=True):
        learner.observe(state, action, reward)
    targets = learner.objective.round_targets(learner._replay(5), learner.predict_probabilities)
    outputs = learner.predict_probabilities(x)
    for row in range(5):
        expected = outputs[row].copy()
        # The newest tuple's next request has not come: its entry is R alone, and no round draws it.
        bootstrap = Q_TARGET_DISCOUNT * outputs[row + 1].max() if row < 4 else 0.0
        expected[actions[row]] = rewards[row] + bootstrap
        np.testing.assert_allclose(targets[row], expected, rtol=1e-5, atol=1e-7)
    assert learner._has_next[:5].tolist() == [True, True, True, True, False]


@pytest.mark.parametrize("sampling", ["recent", "uniform"])
def test_a_round_never_draws_a_tuple_whose_next_state_is_unknown(sampling: str) -> None:
    config = q_config(replay_sampling=sampling, updates_per_round=40, kappa=16, batch_size=8,
                      replay_capacity=16, epochs_per_round=3)
    learner = SafeTailLearner(N, DIM, config, seed=3)
    drawn: list[np.ndarray] = []

    def capture(round_states: np.ndarray, targets: np.ndarray, batches: np.ndarray) -> float:
        drawn.append(batches)
        return 0.0

    learner._round_updates = capture
    if sampling == "recent":
        original = learner.model.train_on_batch

        def train_on_batch(batch_states: np.ndarray, targets: np.ndarray) -> float:
            rows = [int(np.flatnonzero((learner._states[:16] == s).all(axis=1))[0]) for s in batch_states]
            drawn.append(np.array(rows))
            return float(original(batch_states, targets))

        learner.model.train_on_batch = train_on_batch
    x = states(48, seed=4)
    for i in range(48):
        learner.observe(x[i], i % 31, -0.01)
        if (i + 1) % 16 == 0:
            newest = i % 16
            rows = np.concatenate([np.ravel(b) for b in drawn])
            assert newest not in rows and len(set(rows.tolist())) == 15
            drawn.clear()


def test_observe_rejects_a_positive_reward_and_a_bad_action() -> None:
    learner = SafeTailLearner(N, DIM, q_config(), seed=1)
    x = states(1)[0]
    with pytest.raises(ValueError, match="<= 0"):
        learner.observe(x, 3, 0.1)
    with pytest.raises(ValueError, match="out of range"):
        learner.observe(x, 31, -0.1)


def test_q_targets_learn_which_action_meets_the_target() -> None:
    # Eq. 5's shape: 0 for the action that pays in this state, a penalty for every other.
    config = q_config(replay_sampling="uniform", updates_per_round=32, kappa=64, batch_size=32,
                      replay_capacity=1024, hidden_widths=(32, 32), learning_rate=3e-3,
                      epsilon_decay=0.0, epsilon_min=1.0)  # pure exploration
    learner = SafeTailLearner(3, DIM, config, seed=5)  # 7 actions
    before, after, _ = learn_toy_bandit(learner, lambda x, a: 0.0 if a == best_of(x) else -0.2)
    # Every taken action's entry is pulled below its own output (0.95 of the next state's best),
    # the paying one least, so the argmax turns to it more slowly than a classifier's would.
    assert before < 0.3 and after > 0.75, (before, after)


def test_same_seed_same_weights_and_a_checkpoint_resumes_exactly(tmp_path: Path) -> None:
    x = states(80, seed=9)

    def trained() -> SafeTailLearner:
        learner = SafeTailLearner(N, DIM, q_config(), seed=8)
        for i in range(40):
            learner.observe(x[i], learner.act(x[i], explore=True), -0.01 * (i % 4))
        return learner

    first, second = trained(), trained()
    assert first.n_training_rounds == 2
    for a, b in zip(first.model.get_weights(), second.model.get_weights(), strict=True):
        np.testing.assert_array_equal(a, b)
    twin = SafeTailLearner(N, DIM, q_config(), seed=8)
    twin.restore_training_state(first.training_state())
    for i in range(40, 80):
        first.observe(x[i], 3, -0.02)
        twin.observe(x[i], 3, -0.02)
    np.testing.assert_array_equal(twin._forward.logits(x), first._forward.logits(x))
    # A checkpoint of another objective's learner is refused, in both directions.
    with pytest.raises(ValueError, match="another network"):
        SafeTailLearner(N, DIM, tiny_config(), seed=8).restore_training_state(first.training_state())
    other = SafeTailLearner(N, DIM, tiny_config(), seed=8).training_state()
    with pytest.raises(ValueError, match="another network"):
        SafeTailLearner(N, DIM, q_config(), seed=8).restore_training_state(other)
    loaded = SafeTailLearner.load(first.save(tmp_path / "q.keras"))
    assert loaded.config.objective == "q-target"
    np.testing.assert_array_equal(loaded._forward.logits(x), first._forward.logits(x))


def test_a_run_names_the_objective_it_trained_with(tmp_path: Path) -> None:
    out = tmp_path / "run"
    done = subprocess.run([sys.executable, str(ROOT / "experiments/run_usecase.py"), "--uc", "1",
                           "--steps-scale", "0.05", "--objective", "q-target", "--no-figures", "--quiet",
                           "--out", str(out)], capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    run = json.loads((out / "run.json").read_text())
    assert (run["learner"]["objective"], run["preset"]) == ("q-target", "paper")
    assert json.loads((out / "policy.keras.json").read_text())["config"]["objective"] == "q-target"

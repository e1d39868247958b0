"""Presets, the FNN, the NumPy fast path, the learner's schedule, determinism and persistence."""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from yafs_safetail.methods.safetail import SafeTailLearner, target_vector
from yafs_safetail.methods.safetail.network import NumpyForward
from yafs_safetail.methods.safetail.persistence import PolicyFileError
from yafs_safetail.methods.safetail.presets import (
    PAPER_LEARNING_RATES,
    LearnerConfig,
    get_preset,
)

N = 5
DIM = 36


def tiny_config(**changes: object) -> LearnerConfig:
    """A small network and κ so that rounds are cheap."""
    base = dataclasses.replace(
        get_preset("tuned", 1),
        kappa=16,
        replay_capacity=64,
        batch_size=8,
        hidden_widths=(16, 16, 16, 8, 8),
        epsilon_decay=0.1,
        train_steps=64,
    )
    return dataclasses.replace(base, **changes)


def states(n_rows: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(0.0, 2.0, (n_rows, DIM)).astype(np.float32)


# --- presets ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("use_case", "lr", "delta", "episodes", "beta"),
    [(1, 1e-7, 0.003, 50, 200), (2, 1e-6, 0.0015, 30, 120), (3, 1e-7, 0.003, 50, 200)],
)
def test_paper_literal_preset_is_table_one(
    use_case: int, lr: float, delta: float, episodes: int, beta: int
) -> None:
    c = get_preset("paper-literal", use_case)
    assert (c.learning_rate, c.delta, c.n_episodes, c.beta) == (lr, delta, episodes, beta)
    assert (c.epsilon_start, c.epsilon_decay, c.epsilon_min) == (1.0, 3.3e-6, 0.01)
    assert (c.episode_steps, c.kappa) == (256, 128)
    assert (c.train_steps, c.test_steps) == (50 * beta, 20 * beta)
    assert len(c.hidden_widths) == 5
    assert (c.replay_capacity, c.epochs_per_round) == (128, 1)


@pytest.mark.parametrize("use_case", [1, 2, 3])
def test_tuned_exploration_ends_within_budget(use_case: int) -> None:
    paper, tuned = get_preset("paper-literal", use_case), get_preset("tuned", use_case)
    rounds_to_min = (tuned.epsilon_start - tuned.epsilon_min) / tuned.epsilon_decay
    assert rounds_to_min <= 0.5 * tuned.n_training_rounds + 1e-9
    # Only the documented fields differ.
    differing = {
        f.name for f in dataclasses.fields(LearnerConfig)
        if getattr(paper, f.name) != getattr(tuned, f.name)
    }
    assert differing == {
        "name", "learning_rate", "epsilon_decay", "replay_capacity", "epochs_per_round",
        "batch_size",
    }


@pytest.mark.parametrize("use_case", [1, 2, 3])
def test_paper_preset_compresses_the_original_schedule_into_the_budget(use_case: int) -> None:
    literal, paper = get_preset("paper-literal", use_case), get_preset("paper", use_case)
    # Table I's δ, κ, ε bounds, episode settings and the network stay.
    for name in ("delta", "kappa", "epsilon_start", "epsilon_min", "episode_steps", "n_episodes",
                 "beta", "train_steps", "test_steps", "hidden_widths"):
        assert getattr(paper, name) == getattr(literal, name), name
    # ε decays per step and reaches ε_min exactly at the end of training, as the original runs.
    assert paper.epsilon_per_step
    assert paper.epsilon_start - paper.train_steps * paper.epsilon_decay == pytest.approx(0.01)
    # The learning rate is the one rule 3 of docs/calibration.md chose, whatever the budget.
    assert paper.learning_rate == PAPER_LEARNING_RATES[use_case] != literal.learning_rate
    assert (paper.replay_capacity, paper.replay_sampling, paper.batch_size) == (2500, "uniform", 32)
    # A smaller budget still ends exploration at ε_min, at the same rate.
    small = get_preset("paper", use_case, train_steps=1280)
    assert small.epsilon_start - 1280 * small.epsilon_decay == pytest.approx(0.01)
    assert small.learning_rate == paper.learning_rate


def test_epsilon_per_step_counts_stored_tuples() -> None:
    config = dataclasses.replace(get_preset("paper", 1, train_steps=1280))
    learner = SafeTailLearner(N, DIM, config, seed=2)
    state = np.zeros(DIM, dtype=np.float32)
    for _ in range(100):
        learner.observe(state, 0, 0.0)
    assert learner.n_training_rounds == 0
    assert learner.epsilon == pytest.approx(1.0 - 100 * config.epsilon_decay)


def test_uniform_replay_rounds_are_deterministic_and_move_the_weights() -> None:
    config = get_preset("paper", 1, train_steps=512)

    def train() -> list[np.ndarray]:
        learner = SafeTailLearner(N, DIM, config, seed=9)
        rng = np.random.default_rng(1)
        before = [w.copy() for w in learner.model.get_weights()]
        for _ in range(256):
            state = rng.random(DIM).astype(np.float32)
            learner.observe(state, int(rng.integers(learner.n_actions)), -float(rng.random()) * 0.01)
        assert learner.n_training_rounds == 2 and learner.last_round_loss is not None
        after = learner.model.get_weights()
        assert any(not np.array_equal(a, b) for a, b in zip(before, after, strict=True))
        return after

    for first, second in zip(train(), train(), strict=True):
        np.testing.assert_array_equal(first, second)


def test_unknown_preset_and_use_case() -> None:
    with pytest.raises(ValueError, match="unknown preset 'fast'; valid presets: paper, paper-literal, tuned"):
        get_preset("fast", 1)
    with pytest.raises(ValueError, match="unknown use case 4; valid use cases: 1, 2, 3"):
        get_preset("paper", 4)


def test_config_validation_and_roundtrip() -> None:
    c = get_preset("tuned", 2)
    assert LearnerConfig.from_dict(json.loads(json.dumps(c.to_dict()))) == c
    with pytest.raises(ValueError, match="LearnerConfig.kappa must be a positive integer"):
        dataclasses.replace(c, kappa=0)
    with pytest.raises(ValueError, match="replay_capacity"):
        dataclasses.replace(c, replay_capacity=c.kappa - 1)
    with pytest.raises(ValueError, match="learning_rate"):
        dataclasses.replace(c, learning_rate=0.0)
    with pytest.raises(ValueError, match="unknown fields \\['extra'\\]"):
        LearnerConfig.from_dict({**c.to_dict(), "extra": 1})


# --- network and fast path ----------------------------------------------------------------


def test_network_shape_and_fast_path_matches_keras() -> None:
    learner = SafeTailLearner(N, DIM, get_preset("paper", 1), seed=5)
    model = learner.model
    assert model.input_shape == (None, DIM)
    assert model.output_shape == (None, 31)
    hidden = [layer for layer in model.layers if layer.name.startswith("hidden")]
    assert [layer.units for layer in hidden] == list(get_preset("paper", 1).hidden_widths)
    assert all(layer.activation.__name__ == "relu" for layer in hidden)
    x = states(2000, seed=1)
    probs = learner.predict_probabilities(x)
    np.testing.assert_allclose(probs.sum(axis=1), 1.0, rtol=1e-5)
    forward = NumpyForward.from_model(model)
    fast = np.array([forward.best_action(row) for row in x])
    np.testing.assert_array_equal(fast, probs.argmax(axis=1))
    np.testing.assert_array_equal(forward.logits(x).argmax(axis=1), probs.argmax(axis=1))


def test_fast_path_follows_training() -> None:
    learner = SafeTailLearner(N, DIM, tiny_config(learning_rate=1e-2), seed=2)
    x = states(64, seed=3)
    for i in range(32):
        learner.observe(x[i], i % 31, 0.0)
    assert learner.n_training_rounds == 2
    probs = learner.predict_probabilities(x)
    acts = [learner.act(row, explore=False) for row in x]
    np.testing.assert_array_equal(acts, probs.argmax(axis=1))


def test_numpy_forward_rejects_bad_weights() -> None:
    with pytest.raises(ValueError, match="kernel/bias pairs"):
        NumpyForward([np.zeros((2, 2))])
    with pytest.raises(ValueError, match="layer 1: input width 4"):
        NumpyForward([np.zeros((2, 3)), np.zeros(3), np.zeros((4, 2)), np.zeros(2)])


# --- schedule -----------------------------------------------------------------------------


def test_training_every_kappa_and_epsilon_schedule() -> None:
    config = tiny_config(epsilon_decay=0.4, epsilon_min=0.1)
    learner = SafeTailLearner(N, DIM, config, seed=0)
    x = states(64)
    trained_at = [i + 1 for i in range(64) if learner.observe(x[i], i % 31, -0.01)]
    assert trained_at == [16, 32, 48, 64]
    assert learner.n_training_rounds == 4
    assert learner.n_stored == 64
    assert learner.epsilon == pytest.approx(0.1)
    assert learner.last_round_loss is not None and np.isfinite(learner.last_round_loss)


def test_act_subtracts_a_known_cost_per_action_before_the_argmax() -> None:
    learner = SafeTailLearner(N, DIM, tiny_config(), seed=4)
    x = states(1)[0]
    outputs = np.asarray(learner.model(x[None, :], training=False))[0]
    greedy = learner.act(x, explore=False)
    assert greedy == int(outputs.argmax())
    # A cost equal for every action changes nothing; a prohibitive cost on the argmax moves the
    # choice to the next best output.
    assert learner.act(x, explore=False, action_cost=np.full(31, 5.0)) == greedy
    cost = np.zeros(31)
    cost[greedy] = 1e9
    runner_up = int(np.argsort(outputs)[-2])
    assert learner.act(x, explore=False, action_cost=cost) == runner_up
    # A cost that outweighs every difference between the outputs decides alone.
    ranking = np.arange(31, dtype=float) * 1e3
    assert learner.act(x, explore=False, action_cost=ranking) == 0


def test_epsilon_greedy_explores_at_rate_epsilon() -> None:
    learner = SafeTailLearner(N, DIM, tiny_config(), seed=4)
    x = states(1)[0]
    greedy = learner.act(x, explore=False)
    actions = [learner.act(x, explore=True) for _ in range(3100)]
    # ε = 1: uniform over 31 actions.
    counts = np.bincount(actions, minlength=31)
    assert counts.min() > 50
    assert all(learner.act(x, explore=False) == greedy for _ in range(10))


def test_evaluation_mode_never_explores_or_trains() -> None:
    learner = SafeTailLearner(N, DIM, tiny_config(), seed=4, training=False)
    x = states(40)
    assert {learner.act(x[0], explore=True) for _ in range(50)} == {learner.act(x[0], False)}
    assert not any(learner.observe(row, 0, 0.0) for row in x)
    assert learner.n_stored == 0 and learner.n_training_rounds == 0


def test_observe_validates() -> None:
    learner = SafeTailLearner(N, DIM, tiny_config(), seed=4)
    with pytest.raises(ValueError, match=r"state must have shape \(36,\)"):
        learner.observe(np.zeros(35, np.float32), 0, 0.0)
    with pytest.raises(ValueError, match="action_index must be in 0..30"):
        learner.observe(np.zeros(DIM, np.float32), 31, 0.0)
    with pytest.raises(ValueError, match="reward must be finite and <= 0"):
        learner.observe(np.zeros(DIM, np.float32), 0, 0.5)


# --- determinism --------------------------------------------------------------------------


def run_tiny(seed: int) -> tuple[list[int], list[float], list[np.ndarray]]:
    learner = SafeTailLearner(N, DIM, tiny_config(), seed=seed)
    env = np.random.default_rng(seed + 99)
    actions, rewards = [], []
    for _ in range(48):
        x = env.uniform(0.0, 2.0, DIM).astype(np.float32)
        a = learner.act(x, explore=True)
        # A reward that depends on the state and the action, as the simulator's would.
        r = 0.0 if (a % 3) == int(x[0] * 1.5) else -0.01 * (1 + a % 5)
        learner.observe(x, a, r)
        actions.append(a)
        rewards.append(r)
    return actions, rewards, learner.model.get_weights()


def test_same_seed_same_actions_rewards_and_weights() -> None:
    a1, r1, w1 = run_tiny(21)
    a2, r2, w2 = run_tiny(21)
    assert a1 == a2 and r1 == r2
    for x, y in zip(w1, w2, strict=True):
        np.testing.assert_array_equal(x, y)
    a3, _, w3 = run_tiny(22)
    assert a3 != a1 or any(not np.array_equal(x, y) for x, y in zip(w1, w3, strict=True))


# --- persistence --------------------------------------------------------------------------


def test_save_load_roundtrip(tmp_path: Path) -> None:
    learner = SafeTailLearner(N, DIM, tiny_config(), seed=8, metadata={"scales": [1.0, 2.0]})
    x = states(40, seed=9)
    for i in range(32):
        learner.observe(x[i], i % 31, target_reward(i))
    path = learner.save(tmp_path / "policy.keras")
    assert path.is_file() and Path(str(path) + ".json").is_file()

    loaded = SafeTailLearner.load(path)
    assert not loaded.training
    assert loaded.metadata == {"scales": [1.0, 2.0]}
    assert loaded.config == learner.config
    assert loaded.epsilon == learner.epsilon
    assert loaded.n_training_rounds == 2
    for a, b in zip(loaded.model.get_weights(), learner.model.get_weights(), strict=True):
        np.testing.assert_array_equal(a, b)
    assert [loaded.act(r, explore=True) for r in x] == [learner.act(r, False) for r in x]

    # Continuing training resumes ε, round count and the exploration generator.
    resumed = SafeTailLearner.load(path, training=True)
    assert [resumed.act(r, True) for r in x] == [learner.act(r, True) for r in x]
    for i in range(16):
        resumed.observe(x[i], 0, 0.0)
    assert resumed.n_training_rounds == 3


def test_saving_the_same_weights_twice_gives_identical_files(tmp_path: Path) -> None:
    learner = SafeTailLearner(N, DIM, tiny_config(), seed=8)
    first = learner.save(tmp_path / "a.keras").read_bytes()
    time.sleep(1.1)  # Keras would otherwise record a different save time
    second = learner.save(tmp_path / "b.keras").read_bytes()
    assert first == second
    assert SafeTailLearner.load(tmp_path / "b.keras").n_servers == N


def target_reward(i: int) -> float:
    return 0.0 if i % 4 == 0 else -0.002 * (i % 7)


def test_save_load_errors(tmp_path: Path) -> None:
    learner = SafeTailLearner(N, DIM, tiny_config(), seed=8)
    with pytest.raises(ValueError, match="must end in .keras"):
        learner.save(tmp_path / "policy.h5")
    with pytest.raises(PolicyFileError, match="missing.keras: file not found"):
        SafeTailLearner.load(tmp_path / "missing.keras")
    path = learner.save(tmp_path / "p.keras")
    sidecar = Path(str(path) + ".json")
    info = json.loads(sidecar.read_text())
    info["state_dim"] = DIM + 1
    sidecar.write_text(json.dumps(info))
    with pytest.raises(PolicyFileError, match=r"network maps \(None, 36\)"):
        SafeTailLearner.load(path)
    sidecar.write_text("{not json")
    with pytest.raises(PolicyFileError, match="p.keras.json: malformed sidecar"):
        SafeTailLearner.load(path)


def test_target_vectors_are_what_training_sees() -> None:
    learner = SafeTailLearner(N, DIM, tiny_config(), seed=1)
    x = states(3)
    learner.observe(x[0], 4, -0.01)
    learner.observe(x[1], 30, 0.0)
    np.testing.assert_allclose(learner._targets[0], target_vector(4, -0.01, N), rtol=1e-6)
    np.testing.assert_allclose(learner._targets[1], target_vector(30, 0.0, N))


# --- the value objective (contention world, docs/deviations.md D13) --------------------------


def best_of(x: np.ndarray) -> int:
    """The toy bandit's best action: depends on the state, as a server's load would."""
    return 2 if x[0] > 1.0 else 5


def learn_toy_bandit(learner: SafeTailLearner, reward_of: Callable[[np.ndarray, int], float],
                     steps: int = 3000) -> tuple[float, float, np.ndarray]:
    """Share of 200 fresh states whose greedy action is :func:`best_of`'s, before and after
    ``steps`` ε-greedy steps rewarded by ``reward_of``; and those states."""
    env = np.random.default_rng(7)
    fresh = env.uniform(0.0, 2.0, (200, DIM)).astype(np.float32)
    before = float(np.mean([learner.act(x, explore=False) == best_of(x) for x in fresh]))
    for _ in range(steps):
        x = env.uniform(0.0, 2.0, DIM).astype(np.float32)
        a = learner.act(x, explore=True)
        learner.observe(x, a, reward_of(x, a))
    after = float(np.mean([learner.act(x, explore=False) == best_of(x) for x in fresh]))
    return before, after, fresh


def toy_reward(x: np.ndarray, action: int) -> float:
    # Positive and negative values: the value objective has no sign restriction.
    return 0.5 if action == best_of(x) else -0.2 - 0.01 * action


@pytest.mark.parametrize("sampling", ["recent", "uniform"])
def test_value_objective_learns_which_action_pays(sampling: str) -> None:
    config = tiny_config(objective="value", replay_sampling=sampling, updates_per_round=32, kappa=64,
                         batch_size=32, epochs_per_round=1, replay_capacity=1024, hidden_widths=(32, 32),
                         learning_rate=3e-3, epsilon_decay=0.0, epsilon_min=1.0)  # pure exploration
    learner = SafeTailLearner(3, DIM, config, seed=5)  # 7 actions
    before, after, fresh = learn_toy_bandit(learner, toy_reward)
    assert before < 0.6 and after > 0.9, (before, after)
    # The outputs are rewards, not probabilities: the best action's is near its 0.5.
    values = learner.predict_probabilities(fresh[:50])
    best = np.array([values[i, best_of(x)] for i, x in enumerate(fresh[:50])])
    assert abs(float(np.median(best)) - 0.5) < 0.15


def test_value_objective_observes_any_finite_reward_and_trains_only_the_taken_action() -> None:
    learner = SafeTailLearner(N, DIM, tiny_config(objective="value"), seed=3)
    x = states(20, seed=4)
    learner.observe(x[0], 4, 0.7)  # a positive reward is valid here, not with §III's target
    assert np.isnan(learner._targets[0]).sum() == learner.n_actions - 1 and learner._targets[0, 4] == 0.7
    with pytest.raises(ValueError, match="out of range"):
        learner.observe(x[1], 4, float("nan"))
    with pytest.raises(ValueError, match="out of range"):
        learner.observe(x[1], learner.n_actions, 0.0)
    paper = SafeTailLearner(N, DIM, tiny_config(), seed=3)
    with pytest.raises(ValueError, match="reward must be finite and <= 0"):
        paper.observe(x[0], 4, 0.7)
    with pytest.raises(ValueError, match="objective"):
        tiny_config(objective="q-learning")


def test_value_learner_saves_and_reloads(tmp_path: Path) -> None:
    learner = SafeTailLearner(N, DIM, tiny_config(objective="value"), seed=8)
    x = states(40, seed=9)
    for i in range(32):
        learner.observe(x[i], i % 31, 0.1 * (i % 3) - 0.1)
    loaded = SafeTailLearner.load(learner.save(tmp_path / "value.keras"), training=True)
    assert loaded.config.objective == "value"
    np.testing.assert_array_equal(loaded.predict_probabilities(x), learner.predict_probabilities(x))
    for i in range(16):  # it keeps training with the masked loss
        loaded.observe(x[i], 2, 0.3)
    assert loaded.n_training_rounds == 3 and np.isfinite(loaded.last_round_loss)


# --- several value networks averaged (docs/deviations.md D13) ------------------------------


def test_value_networks_are_independent_members_whose_mean_decides() -> None:
    learner = SafeTailLearner(N, DIM, tiny_config(objective="value", n_networks=3), seed=4)
    assert learner.model.output_shape == (None, 3 * learner.n_actions)
    firsts = [learner.model.get_layer(f"net{j}_hidden0").get_weights()[0] for j in range(3)]
    assert not np.allclose(firsts[0], firsts[1]) and not np.allclose(firsts[1], firsts[2])
    x = states(40, seed=5)
    for i in range(32):
        learner.observe(x[i], i % 7, 0.2 * (i % 3) - 0.3)
    assert learner.n_training_rounds == 2
    # Each member is trained on the same tuple: the action's column in every member's block.
    stored = learner._targets[0].reshape(3, learner.n_actions)
    assert (stored[:, 0] == -0.3).all() and np.isnan(stored[:, 1:]).all()
    outputs = learner.predict_probabilities(x).reshape(len(x), 3, learner.n_actions)
    np.testing.assert_allclose(learner._forward.logits(x), outputs.mean(axis=1), rtol=1e-4, atol=1e-6)
    # The members disagree, so the decision is the mean's argmax, not any one member's.
    assert not np.allclose(outputs[:, 0], outputs[:, 1], atol=1e-3)
    cost = np.linspace(0.0, 0.1, learner.n_actions)
    chosen = [learner.act(row, explore=False, action_cost=cost) for row in x]
    np.testing.assert_array_equal(chosen, (outputs.mean(axis=1) - cost).argmax(axis=1))


def test_one_value_network_keeps_the_single_network_layout() -> None:
    # Policies saved before n_networks existed (one network) must keep loading as they were.
    one = SafeTailLearner(N, DIM, tiny_config(objective="value", n_networks=1), seed=4)
    assert [layer.name for layer in one.model.layers] == [*(f"hidden{k}" for k in range(5)), "actions"]
    assert one.model.output_shape == (None, one.n_actions) and one._targets.shape[1] == one.n_actions


def test_several_networks_only_with_the_value_objective() -> None:
    with pytest.raises(ValueError, match="n_networks \\(2\\) must be 1 with the 'target-vector' objective"):
        tiny_config(n_networks=2)
    with pytest.raises(ValueError, match="n_networks must be a positive integer"):
        tiny_config(objective="value", n_networks=0)


def test_value_networks_save_reload_and_resume_from_a_checkpoint(tmp_path: Path) -> None:
    config = tiny_config(objective="value", n_networks=2)
    learner = SafeTailLearner(N, DIM, config, seed=8)
    x = states(64, seed=9)
    for i in range(32):
        learner.observe(x[i], i % 31, 0.1 * (i % 3) - 0.1)
    loaded = SafeTailLearner.load(learner.save(tmp_path / "pair.keras"))
    assert loaded.config.n_networks == 2
    np.testing.assert_array_equal(loaded._forward.logits(x), learner._forward.logits(x))
    twin = SafeTailLearner(N, DIM, config, seed=8)
    twin.restore_training_state(learner.training_state())
    for i in range(32, 64):
        learner.observe(x[i], 3, 0.2)
        twin.observe(x[i], 3, 0.2)
    np.testing.assert_array_equal(twin._forward.logits(x), learner._forward.logits(x))

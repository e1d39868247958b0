"""Does the learner learn? A synthetic contextual bandit where the best subset depends on ω.

Toy world (n = 5): each server has 0..4 active users (uniform, independent per step); a copy
on server i takes 0.3 + 0.2·ℓ_i s plus N(0, 0.02 s) noise; τ = 0.55 s. So a server with at most
one user meets τ alone (Eq. 5 case 2: reward 0), and when none does, only the full set earns 0
(case 3). The other state entries are random noise. The best action therefore depends on the
state; a uniformly random policy is optimal for about 6 % of states.

Run as a script for the measurements quoted in docs/deviations.md (full step budgets)::

    python tests/test_policy_learning.py
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import pytest

from yafs_safetail.edge.observation import Observation
from yafs_safetail.methods.safetail import (
    SafeTailLearner,
    StateScales,
    encode_state,
    reward,
    state_dim,
    subset_of,
)
from yafs_safetail.methods.safetail.presets import PAPER_LEARNING_RATES, LearnerConfig, get_preset
from yafs_safetail.methods.safetail.spaces import random_observation

N_SERVERS = 5
TARGET_S = 0.55
SCALES = StateScales.for_use_case(1)
STATE_DIM = state_dim(N_SERVERS, 0, 2)




def toy_latency_s(obs: Observation, subset: tuple[int, ...], rng: np.random.Generator) -> float:
    users = obs.server_active_users[list(subset)]
    noise = rng.normal(0.0, 0.02, len(subset))
    return float(np.max([0.0, np.min(0.3 + 0.2 * users + noise)]))


def is_optimal(obs: Observation, action: int) -> bool:
    """Noise-free: does this action earn the maximum reward (0) for this state?"""
    subset = subset_of(action, N_SERVERS)
    fast = obs.server_active_users <= 1
    if fast.any():
        return len(subset) == 1 and bool(fast[subset[0]])
    return len(subset) == N_SERVERS


def flat_weights(learner: SafeTailLearner) -> np.ndarray:
    return np.concatenate([w.ravel() for w in learner.model.get_weights()])


@dataclasses.dataclass
class ToyResult:
    initial_optimal_fraction: float
    initial_mean_greedy_reward: float
    optimal_fraction: float
    mean_greedy_reward: float
    relative_weight_change: float
    final_epsilon: float
    n_rounds: int
    wall_s: float


def evaluate_greedy(learner: SafeTailLearner, seed: int, n_eval: int) -> tuple[float, float]:
    """(fraction of fresh states where the greedy action is optimal, its mean reward)."""
    eval_rng = np.random.default_rng(seed + 2_000_003)
    optimal = 0
    rewards = []
    for _ in range(n_eval):
        obs = random_observation(eval_rng, N_SERVERS)
        action = learner.act(encode_state(obs, SCALES), explore=False)
        subset = subset_of(action, N_SERVERS)
        optimal += is_optimal(obs, action)
        latency_s = toy_latency_s(obs, subset, eval_rng)
        rewards.append(reward(latency_s, TARGET_S, len(subset), N_SERVERS, learner.config.delta))
    return optimal / n_eval, float(np.mean(rewards))


def run_toy(config: LearnerConfig, seed: int, n_eval: int = 2000) -> ToyResult:
    """Train for ``config.train_steps`` steps; evaluate the greedy policy before and after."""
    start = time.perf_counter()
    learner = SafeTailLearner(N_SERVERS, STATE_DIM, config, seed)
    w0 = flat_weights(learner)
    initial_fraction, initial_reward = evaluate_greedy(learner, seed, n_eval)
    env_rng = np.random.default_rng(seed + 1_000_003)
    for _ in range(config.train_steps):
        obs = random_observation(env_rng, N_SERVERS)
        state = encode_state(obs, SCALES)
        action = learner.act(state, explore=True)
        subset = subset_of(action, N_SERVERS)
        latency_s = toy_latency_s(obs, subset, env_rng)
        learner.observe(state, action, reward(latency_s, TARGET_S, len(subset), N_SERVERS, config.delta))
    w1 = flat_weights(learner)
    fraction, mean_reward = evaluate_greedy(learner, seed, n_eval)
    return ToyResult(
        initial_optimal_fraction=initial_fraction,
        initial_mean_greedy_reward=initial_reward,
        optimal_fraction=fraction,
        mean_greedy_reward=mean_reward,
        relative_weight_change=float(np.linalg.norm(w1 - w0) / np.linalg.norm(w0)),
        final_epsilon=learner.epsilon,
        n_rounds=learner.n_training_rounds,
        wall_s=time.perf_counter() - start,
    )


def random_policy_optimal_fraction(n_eval: int = 20000, seed: int = 7) -> float:
    rng = np.random.default_rng(seed)
    hits = 0
    for _ in range(n_eval):
        hits += is_optimal(random_observation(rng, N_SERVERS), int(rng.integers((1 << N_SERVERS) - 1)))
    return hits / n_eval


def test_random_policy_baseline_is_low() -> None:
    assert random_policy_optimal_fraction(4000) < 0.1


def test_tuned_learns_on_a_small_budget() -> None:
    result = run_toy(get_preset("tuned", 1, train_steps=2560), seed=3, n_eval=500)
    assert result.final_epsilon == pytest.approx(0.01)
    # Best state-independent action (one fixed server) is optimal for 40 % of states.
    assert result.optimal_fraction > 0.6
    assert result.optimal_fraction > result.initial_optimal_fraction + 0.2


def best_fixed_action_reward(delta: float, seed: int = 5, n_eval: int = 2000) -> float:
    """The highest mean Eq. 5 reward any one action earns in every state (the all-five set)."""
    rng = np.random.default_rng(seed)
    observations = [random_observation(rng, N_SERVERS) for _ in range(n_eval)]
    means = []
    for action in range(2**N_SERVERS - 1):
        subset = subset_of(action, N_SERVERS)
        means.append(np.mean([reward(toy_latency_s(obs, subset, rng), TARGET_S, len(subset), N_SERVERS, delta)
                              for obs in observations]))
    return float(max(means))


def test_paper_learns_which_lone_server_meets_the_target_on_a_small_budget() -> None:
    # paper trains on §III's target vector: the argmax is the action likeliest to earn exactly 0.
    # The best state-independent action (one fixed server) is optimal for 40 % of states.
    result = run_toy(get_preset("paper", 1, train_steps=2560), seed=3, n_eval=500)
    assert result.final_epsilon == pytest.approx(0.01)
    assert result.optimal_fraction > 0.5
    assert result.optimal_fraction > result.initial_optimal_fraction + 0.2


def test_q_targets_learn_the_best_mean_reward_on_a_small_budget() -> None:
    # The original code's Q-style targets (--objective q-target) follow an action's expected
    # Eq. 5 reward, not how often it earns exactly 0. Here no state-dependent policy beats the
    # all-five set by much: a lone server that meets τ earns 0, but one that misses costs δ·e^4,
    # and all five cost at most δ when they meet it (docs/deviations.md, Q-style targets).
    config = dataclasses.replace(get_preset("paper", 1, train_steps=2560), objective="q-target",
                                 learning_rate=3e-3)
    result = run_toy(config, seed=3, n_eval=500)
    assert result.final_epsilon == pytest.approx(0.01)
    assert result.mean_greedy_reward > result.initial_mean_greedy_reward + 0.01
    # Most of the way from the untrained network's reward to the best fixed action's. (It came
    # within 0.001 of it on AVX-512 kernels before the numerical path was pinned, issue 48; on
    # the pinned path it stops at -0.0064 against -0.0023: under Q-style targets the rounding
    # decides which large subset wins, D18.)
    best_fixed = best_fixed_action_reward(config.delta)
    initial = result.initial_mean_greedy_reward
    assert result.mean_greedy_reward > initial + 0.8 * (best_fixed - initial)


def test_paper_literal_barely_moves_on_a_small_budget() -> None:
    result = run_toy(get_preset("paper-literal", 1, train_steps=1280), seed=3, n_eval=300)
    assert result.n_rounds == 10
    assert result.final_epsilon > 0.9999
    assert result.relative_weight_change < 1e-3
    assert abs(result.optimal_fraction - result.initial_optimal_fraction) < 0.05


@pytest.mark.slow
@pytest.mark.parametrize("use_case", [1, 2, 3])
def test_full_budget_paper_and_tuned_learn_paper_literal_does_not(use_case: int) -> None:
    tuned = run_toy(get_preset("tuned", use_case), seed=11)
    paper = run_toy(get_preset("paper", use_case), seed=11)
    literal = run_toy(get_preset("paper-literal", use_case), seed=11)
    assert tuned.optimal_fraction > 0.8
    # paper (§III's target vector) learns which servers earn exactly 0: far more optimal
    # greedy choices than the untrained network, and better than the best state-independent
    # action (one fixed server, 0.40) by a margin where rule 3 chose a rate that moves the
    # network far (1e-3: UC1, UC2); UC3's 1e-5, chosen because in UC3 a barely trained network
    # already earns the most reward (D6), need only pass that action.
    assert paper.optimal_fraction > paper.initial_optimal_fraction + 0.3
    assert paper.optimal_fraction > (0.5 if PAPER_LEARNING_RATES[use_case] >= 1e-4 else 0.4)
    assert literal.relative_weight_change < 1e-3
    assert abs(literal.optimal_fraction - literal.initial_optimal_fraction) < 0.05


def ablations(use_case: int) -> dict[str, LearnerConfig]:
    """``paper`` plus one or more of ``tuned``'s deviations, to attribute the effect."""
    paper, tuned = get_preset("paper-literal", use_case), get_preset("tuned", use_case)
    replay = {"replay_capacity": tuned.replay_capacity, "epochs_per_round": tuned.epochs_per_round,
              "batch_size": tuned.batch_size}
    return {
        "paper+lr": dataclasses.replace(paper, learning_rate=tuned.learning_rate),
        "paper+lr+eps": dataclasses.replace(
            paper, learning_rate=tuned.learning_rate, epsilon_decay=tuned.epsilon_decay),
        "paper+lr+replay": dataclasses.replace(
            paper, learning_rate=tuned.learning_rate, **replay),
        "paper+eps+replay": dataclasses.replace(
            paper, epsilon_decay=tuned.epsilon_decay, **replay),
    }


def main() -> None:
    print(f"random policy: optimal for {random_policy_optimal_fraction():.3f} of states")
    print("config uc steps rounds final_eps optimal_before optimal_after mean_greedy_reward "
          "rel_weight_change wall_s")
    rows: list[tuple[str, LearnerConfig]] = []
    for use_case in (1, 2, 3):
        rows += [(name, get_preset(name, use_case)) for name in ("paper-literal", "paper", "tuned")]
    rows += list(ablations(1).items())
    for label, config in rows:
        r = run_toy(config, seed=11)
        print(
            f"{label:16s} {config.use_case} {config.train_steps:5d} {r.n_rounds:3d} "
            f"{r.final_epsilon:.4f} {r.initial_optimal_fraction:.3f} {r.optimal_fraction:.3f} "
            f"{r.mean_greedy_reward:.5f} {r.relative_weight_change:.2e} {r.wall_s:.1f}"
        )


if __name__ == "__main__":
    main()

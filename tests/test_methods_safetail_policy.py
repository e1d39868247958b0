"""SafeTailPolicy: decisions from the learner, Eq. 5 rewards in the records, feedback only when learning."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from yafs_safetail.edge.scenario import load_scenario
from yafs_safetail.edge.usecases import get_use_case
from yafs_safetail.edge.world import build_world, load_inputs
from yafs_safetail.methods.policy import PolicyError
from yafs_safetail.methods.safetail import StateScales, reward, state_dim, subset_of
from yafs_safetail.methods.safetail.learner import SafeTailLearner
from yafs_safetail.methods.safetail.policy import SafeTailPolicy
from yafs_safetail.methods.safetail.presets import get_preset
from yafs_safetail.sim.hooks import EdgeModel
from yafs_safetail.sim.runner import simulate

ROOT = Path(__file__).resolve().parents[1]
STEPS = 160  # > κ = 128: one training round happens while learning


@pytest.fixture(scope="module")
def world():
    uc = get_use_case(1)
    scenario = load_scenario(ROOT / "topologies/paper_5servers.json", ROOT / "placements/paper_5servers.json")
    return build_world(scenario, uc, load_inputs(uc), STEPS, seed=3, phase="train")


def new_learner(world) -> SafeTailLearner:
    scenario = world.scenario
    return SafeTailLearner(scenario.n_servers, state_dim(scenario.n_servers, 0, 2),
                           get_preset("tuned", 1), seed=3)


def run(world, learner, training):
    policy = SafeTailPolicy(5, np.random.default_rng(0), learner=learner,
                            scales=StateScales.for_use_case(1), training=training)
    return policy, simulate(world, policy)


def test_learning_run_feeds_every_request_back_with_its_eq5_reward(world):
    learner = new_learner(world)
    policy, records = run(world, learner, training=True)
    assert len(records) == STEPS and learner.n_stored == STEPS
    assert learner.n_training_rounds == 1
    for record in records:
        expected = reward(record.latency_s, record.target_s, record.n_selected, 5, learner.config.delta)
        assert record.reward == expected and record.reward <= 0.0
        # ε is 1 until the first training round (after κ = 128 tuples), then lower.
        assert record.epsilon == 1.0 if record.step < 128 else record.epsilon < 1.0
    assert policy.decision_time_s > 0 and policy.training_time_s > 0


def test_greedy_run_does_not_train_and_follows_the_networks_argmax(world):
    learner = new_learner(world)
    weights = [w.copy() for w in learner.model.get_weights()]
    _, records = run(world, learner, training=False)
    assert learner.n_stored == 0 and learner.n_training_rounds == 0
    for before, after in zip(weights, learner.model.get_weights(), strict=True):
        np.testing.assert_array_equal(before, after)
    # Greedy: every request gets the same subset as the network's argmax for its state.
    model = EdgeModel(world)
    scales = StateScales.for_use_case(1)
    from yafs_safetail.methods.safetail import encode_state

    for record in records[:20]:
        state = encode_state(model.observe(record.step), scales)
        assert record.servers == subset_of(learner.act(state, explore=False), 5)
        assert record.epsilon == 0.0


def test_a_policy_for_another_number_of_servers_is_refused(world):
    learner = SafeTailLearner(3, state_dim(3, 0, 2), get_preset("tuned", 1), seed=3)
    with pytest.raises(PolicyError, match="3 servers"):
        SafeTailPolicy(5, np.random.default_rng(0), learner=learner,
                       scales=StateScales.for_use_case(1), training=False)

"""SafeTail assembled: a fresh learner, the policy around it and its reward, in one place.

A run (``runs.learners``), a contention sweep (``runs.sweep``, and ``runs.mechanism``
through it) build SafeTail only through :func:`make_safetail`, so every one of them seeds it,
scales its state and chooses its reward alike.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from yafs_safetail.defaults import SAFETAIL

if TYPE_CHECKING:
    from yafs_safetail.edge.scenario import EdgeScenario
    from yafs_safetail.edge.usecases import UseCase
    from yafs_safetail.methods.safetail.policy import SafeTailPolicy
    from yafs_safetail.methods.safetail.presets import LearnerConfig


def make_safetail(use_case: UseCase, scenario: EdgeScenario, config: LearnerConfig, seed: int, *,
                  metadata: Mapping[str, Any], reward: str = "paper", dispatch: str = "all",
                  name: str = SAFETAIL) -> SafeTailPolicy:
    """A SafeTail policy in training mode, with a fresh learner of ``config``.

    The learner draws from ``seed`` (its exploration, minibatches and initial weights), the
    policy's generator from (``seed``, ``"SafeTail"``) whatever ``name`` it reports, so a SafeTail
    gets the same draws whichever others run beside it; neither draws from a world's streams.

    Args:
        use_case: the use case (its state's Γ columns, its state scales).
        scenario: the servers and the user's location (the state's size).
        config: the learner's configuration; its objective may bring its own reward.
        seed: the run's seed.
        metadata: saved with the policy after its ``use_case`` entry.
        reward: the reward when the objective brings none (``Objective.own_reward``: the value
            learner's latency-cost wins).
        dispatch: how its subsets are sent (``SafeTailPolicy``).
        name: its rows' method name.
    """
    # Imported here: the learner builds its network with Keras.
    from yafs_safetail.methods.registry import method_rng
    from yafs_safetail.methods.safetail.learner import SafeTailLearner
    from yafs_safetail.methods.safetail.policy import SafeTailPolicy
    from yafs_safetail.methods.safetail.spaces import StateScales, state_dim

    n_servers = scenario.n_servers
    learner = SafeTailLearner(
        n_servers, state_dim(n_servers, len(use_case.gamma_columns), len(scenario.user_location)),
        config, seed, metadata={"use_case": use_case.number, **metadata})
    policy = SafeTailPolicy(n_servers, method_rng(seed, SAFETAIL), learner=learner,
                            scales=StateScales.for_use_case(use_case.number), training=True,
                            reward_name=config.learning_objective.own_reward or reward, dispatch=dispatch)
    policy.name = name
    return policy

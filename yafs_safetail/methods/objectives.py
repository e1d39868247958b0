"""What SafeTail's network is trained toward: one class per objective, and the registry of them.

An objective (``LearnerConfig.objective`` names one) owns everything that depends on it:

* its training targets: what one (action, reward) tuple stores (:meth:`Objective.write_target`)
  and what a round fits (:meth:`Objective.round_targets`, on the rows :meth:`Objective.round_rows`
  may draw);
* its network's output activation and loss (``network.build_network``, ``make_round_updates``);
* its rules: whether it averages several networks (:attr:`Objective.averages_networks`), the
  reward it brings with it (:attr:`Objective.own_reward`), and how a sweep trains it beside the
  others (its rows' method name, preset and dispatch).

The registry (:func:`objective_named`, :func:`objective_names`) maps each name to its objective;
a class defining ``name`` joins it. Presets, runs, sweeps and commands ask the objective, never
compare its name. Adding one is one class here, its test and its line in docs/policy.md.

Light at import (the standard library only): the commands' parsers and checks ask an objective
its rules before NumPy loads (``tests/test_first_answer.py``); the targets import NumPy, the
losses Keras, when first used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

from yafs_safetail.settings.experiment import OBJECTIVE_NAMES

if TYPE_CHECKING:
    from collections.abc import Callable

    import numpy as np

#: q-target: the discount on the next state's best output (the original code's 0.95, facts.md).
Q_TARGET_DISCOUNT = 0.95

_REGISTRY: dict[str, Objective] = {}


@dataclass(frozen=True)
class Replay:
    """The rows of a learner's replay buffer a training round sees (slots 0..n-1).

    Attributes:
        states: the encoded states.
        targets: what :meth:`Objective.write_target` stored for each tuple.
        next_states: each tuple's next state (objectives with ``keeps_next_state`` only).
        has_next: whether that next state has come yet (likewise).
    """

    states: np.ndarray
    targets: np.ndarray
    next_states: np.ndarray | None = None
    has_next: np.ndarray | None = None


class Objective:
    """What a SafeTail network learns from each (ω, A, R) tuple, and the rules that follow.

    Subclasses set the class attributes and override what differs; one instance of each is
    registered under its :attr:`name`.

    Attributes:
        name: its name (``--objective``, ``LearnerConfig.objective``, run.json, policy files).
        method_name: its rows' method name when a contention sweep trains it.
        preset: the preset a sweep trains it with unless ``--preset`` says otherwise.
        dispatch: how a sweep sends its subsets unless ``--safetail-dispatch`` says otherwise.
        averages_networks: whether it may average several networks (``n_networks`` > 1).
        sweep_networks: how many networks a sweep averages for it unless told.
        own_reward: the reward it is trained with whatever the run's reward (None: the run's;
            reward.REWARD_NAMES).
        output_activation: the output layer's activation.
        keeps_next_state: whether the learner keeps each tuple's next state for it.
    """

    name: ClassVar[str]
    method_name: ClassVar[str]
    preset: ClassVar[str] = "paper"
    dispatch: ClassVar[str] = "all"
    averages_networks: ClassVar[bool] = False
    sweep_networks: ClassVar[int] = 1
    own_reward: ClassVar[str | None] = None
    output_activation: ClassVar[str] = "softmax"
    keeps_next_state: ClassVar[bool] = False

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "name" in cls.__dict__:
            _REGISTRY[cls.name] = cls()
            OBJECTIVE_NAMES.add(cls.name)  # what --objective accepts (declared a floor below)

    def __repr__(self) -> str:
        return f"<objective {self.name}>"

    # -- the network -------------------------------------------------------------------------

    def compile_loss(self) -> Any:
        """The loss ``build_network`` compiles the model with (and a saved model reloads with)."""
        return "categorical_crossentropy"

    def round_loss(self) -> Any:
        """The same loss as a callable, for ``make_round_updates``."""
        import keras

        return keras.losses.CategoricalCrossentropy()

    # -- the targets -------------------------------------------------------------------------

    def write_target(self, row: np.ndarray, action: int, reward: float, n_servers: int) -> None:
        """Store one tuple's target in ``row`` (one entry per output of every network).

        Raises:
            ValueError: an action out of range or a reward this objective cannot learn.
        """
        raise NotImplementedError

    def round_rows(self, replay: Replay) -> int | np.ndarray:
        """The rows a round may draw: all of them (an int), or their indices."""
        return len(replay.targets)

    def round_targets(self, replay: Replay, predict: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        """What a round fits, row by row; ``predict`` is the network as it stands."""
        return replay.targets


def objective_named(name: str) -> Objective:
    """The registered objective called ``name``.

    Raises:
        ValueError: no objective has that name.
    """
    try:
        return _REGISTRY[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown objective {name!r}; valid: {', '.join(_REGISTRY)}") from None


def objective_names(keep: Callable[[Objective], bool] | None = None) -> tuple[str, ...]:
    """Every registered objective's name (those ``keep`` keeps), in the order the classes are
    defined."""
    return tuple(name for name, objective in _REGISTRY.items() if keep is None or keep(objective))


def objectives_bringing(reward_name: str) -> tuple[str, ...]:
    """The names of the objectives whose own reward is ``reward_name``."""
    return objective_names(lambda objective: objective.own_reward == reward_name)


def averages_networks(name: str | None) -> bool:
    """Whether the objective called ``name`` may average several networks (None, a preset's
    objective: no)."""
    return name is not None and objective_named(name).averages_networks


def _store_taken(row: np.ndarray, action: int, reward: float, n_actions: int) -> None:
    """Only the action taken has a target, in every network: the value loss skips the NaN
    entries and a q-target round fills them in."""
    import numpy as np

    row[...] = np.nan
    row[action::n_actions] = reward


class TargetVector(Objective):
    """§III's target vector (:func:`target_vector`), fitted by the softmax's cross-entropy."""

    name = "target-vector"
    method_name = "SafeTail"

    def write_target(self, row: np.ndarray, action: int, reward: float, n_servers: int) -> None:
        row[...] = target_vector(action, reward, n_servers)


class QTarget(Objective):
    """The original code's targets (facts.md; docs/deviations.md D18): the network's own outputs
    for the state, the taken action's entry replaced by R + 0.95 · max of its outputs for the next
    request's state, with the same softmax and cross-entropy."""

    name = "q-target"
    method_name = "SafeTail-Q"
    keeps_next_state = True

    def write_target(self, row: np.ndarray, action: int, reward: float, n_servers: int) -> None:
        from yafs_safetail.methods.safetail.spaces import n_actions

        n_total = n_actions(n_servers)
        if not 0 <= action < n_total or not math.isfinite(reward):
            raise ValueError(f"action {action!r} or reward {reward!r} out of range")
        if reward > 0.0:
            raise ValueError(f"reward must be finite and <= 0 (Eq. 5), got {reward!r}")
        _store_taken(row, action, reward, n_total)

    def round_rows(self, replay: Replay) -> int | np.ndarray:
        """Only the tuples whose next state has come."""
        import numpy as np

        assert replay.has_next is not None
        return np.flatnonzero(replay.has_next)

    def round_targets(self, replay: Replay, predict: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        """The network's outputs for each state, the taken action's entry replaced by R + γ · max
        of its outputs for the next state (rows without one keep R there; no round draws them)."""
        import numpy as np

        assert replay.next_states is not None and replay.has_next is not None
        stored = replay.targets
        n_rows = len(stored)
        taken = np.isfinite(stored)
        actions = taken.argmax(axis=1)
        rows = np.arange(n_rows)
        targets = predict(replay.states).astype(np.float32)
        best_next = predict(replay.next_states).max(axis=1)
        bootstrap = np.where(replay.has_next, Q_TARGET_DISCOUNT * best_next, 0.0)
        targets[rows, actions] = stored[rows, actions] + bootstrap
        return targets


class Value(Objective):
    """Beyond the paper (D13): the same network (or the mean of ``n_networks`` of them), linear,
    trained to predict each action's latency score with the latency-cost reward (the copy price,
    known at dispatch, is subtracted when choosing); only the action taken has a target."""

    name = "value"
    method_name = "SafeTail-CA"
    preset = "tuned"
    dispatch = "tied"
    averages_networks = True
    #: Chosen on seeds 0-6 over one network, then judged on seeds 19-30 (docs/deviations.md D13).
    sweep_networks = 3
    own_reward = "latency-cost"
    output_activation = "linear"

    def compile_loss(self) -> Any:
        from yafs_safetail.methods.safetail.network import masked_squared_error

        return masked_squared_error()

    def round_loss(self) -> Any:
        return self.compile_loss()

    def write_target(self, row: np.ndarray, action: int, reward: float, n_servers: int) -> None:
        from yafs_safetail.methods.safetail.spaces import n_actions

        n_total = n_actions(n_servers)
        if not 0 <= action < n_total or not math.isfinite(reward):
            raise ValueError(f"action {action!r} or reward {reward!r} out of range")
        _store_taken(row, action, reward, n_total)


def target_vector(action_index: int, reward: float, n_servers: int) -> np.ndarray:
    """The §III training target V^t for one (action, reward) pair.

    * reward = 0: one-hot on ``action_index``.
    * reward < 0: with N = 2^n - 1, every action whose subset is contained in the chosen
      subset (the chosen action included) gets max(0, 1/N + reward); the remaining mass
      1 - Σ(those) is spread equally over all the other actions.

    Edge cases (the paper is silent):

    * The chosen subset is the full set: every action is one of its subsets, so no "other"
      entry exists. All entries then hold the same value and the remaining mass is spread
      equally over all of them, i.e. the vector is uniform, 1/N each.
    * The remaining mass can never be negative: for reward <= 0 each adjusted entry is at most
      1/N and there are at most N of them. Positive rewards (which Eq. 5 never produces) are
      rejected instead of being given a meaning.

    Args:
        action_index: The chosen action, 0..2^n - 2.
        reward: The Eq. 5 reward of that action, finite and <= 0.
        n_servers: n, 1..10.

    Returns:
        float64 array of shape (2^n - 1,), non-negative, summing to 1 (up to float rounding).

    Raises:
        ValueError: bad ``n_servers`` or ``action_index``, or a positive / non-finite reward.
    """
    import numpy as np

    from yafs_safetail.methods.safetail.spaces import n_actions, subset_matrix

    n_total = n_actions(n_servers)
    if isinstance(action_index, bool) or not isinstance(action_index, int | np.integer):
        raise ValueError(f"action_index must be an integer, got {action_index!r}")
    if not 0 <= action_index < n_total:
        raise ValueError(
            f"action_index must be in 0..{n_total - 1} for n_servers={n_servers}, got {action_index}"
        )
    if not math.isfinite(reward) or reward > 0.0:
        raise ValueError(f"reward must be finite and <= 0 (Eq. 5), got {reward!r}")
    vector = np.empty(n_total, dtype=np.float64)
    if reward == 0.0:
        vector.fill(0.0)
        vector[action_index] = 1.0
        return vector
    contained = subset_matrix(n_servers)[action_index]
    n_contained = int(np.count_nonzero(contained))
    adjusted = max(0.0, 1.0 / n_total + reward)
    n_other = n_total - n_contained
    if n_other == 0:
        vector.fill(1.0 / n_total)
    else:
        vector.fill((1.0 - n_contained * adjusted) / n_other)
        vector[contained] = adjusted
    return vector

"""Learner configurations: ``paper`` (Table I verbatim) and ``tuned`` (documented deviations).

Every deviation of ``tuned`` from ``paper`` is listed, with its measured effect, in
docs/deviations.md.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

PRESET_NAMES = ("paper", "tuned")
USE_CASES = (1, 2, 3)

# Table I, per use case.
_TABLE_I = {
    1: {"learning_rate": 1e-7, "delta": 0.003, "n_episodes": 50, "beta": 200},
    2: {"learning_rate": 1e-6, "delta": 0.0015, "n_episodes": 30, "beta": 120},
    3: {"learning_rate": 1e-7, "delta": 0.003, "n_episodes": 50, "beta": 200},
}

# The paper gives 5 hidden ReLU layers but no widths.
DEFAULT_HIDDEN_WIDTHS = (128, 128, 128, 64, 64)

# tuned: ε reaches ε_min after this fraction of the training rounds in the step budget.
TUNED_EXPLORATION_FRACTION = 0.5


@dataclass(frozen=True, slots=True)
class LearnerConfig:
    """Everything the learner and the experiment need to know about one preset.

    Attributes:
        name: Preset name ("paper", "tuned", or a custom label).
        use_case: 1, 2 or 3.
        learning_rate: Adam's learning rate.
        delta: δ of Eq. 5.
        epsilon_start: ε before any training (the paper: 1, full exploration).
        epsilon_decay: Subtracted from ε after every training round.
        epsilon_min: ε never goes below this.
        kappa: κ, a training round runs every κ stored tuples.
        episode_steps: α_s, steps (requests) per episode.
        n_episodes: α_e, number of training episodes.
        beta: β, the number of steps each plotted point averages.
        train_steps: Training-phase length in steps (the paper's plots: 50·β).
        test_steps: Test-phase length in steps (the paper's plots: 20·β).
        hidden_widths: Widths of the FNN's hidden ReLU layers.
        replay_capacity: A round trains on the most recent ``min(replay_capacity, stored)``
            tuples; ``kappa`` means exactly the κ tuples collected since the last round.
        epochs_per_round: Passes over those tuples per training round.
        batch_size: Minibatch size within a pass (shuffled with the run's generator).
    """

    name: str
    use_case: int
    learning_rate: float
    delta: float
    epsilon_start: float
    epsilon_decay: float
    epsilon_min: float
    kappa: int
    episode_steps: int
    n_episodes: int
    beta: int
    train_steps: int
    test_steps: int
    hidden_widths: tuple[int, ...]
    replay_capacity: int
    epochs_per_round: int
    batch_size: int

    def __post_init__(self) -> None:
        object.__setattr__(self, "hidden_widths", tuple(int(w) for w in self.hidden_widths))
        positive_floats = ("learning_rate", "delta")
        for field in positive_floats:
            value = getattr(self, field)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"LearnerConfig.{field} must be finite and > 0, got {value!r}")
        for field in ("epsilon_start", "epsilon_decay", "epsilon_min"):
            value = getattr(self, field)
            if not (math.isfinite(value) and 0.0 <= value <= 1.0):
                raise ValueError(f"LearnerConfig.{field} must be in [0, 1], got {value!r}")
        if self.epsilon_min > self.epsilon_start:
            raise ValueError(
                f"LearnerConfig.epsilon_min ({self.epsilon_min}) exceeds epsilon_start "
                f"({self.epsilon_start})"
            )
        positive_ints = ("kappa", "episode_steps", "n_episodes", "beta", "train_steps",
                         "test_steps", "replay_capacity", "epochs_per_round", "batch_size")
        for field in positive_ints:
            value = getattr(self, field)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"LearnerConfig.{field} must be an integer >= 1, got {value!r}")
        if not self.hidden_widths or min(self.hidden_widths) < 1:
            raise ValueError(
                f"LearnerConfig.hidden_widths must be non-empty positive widths, got "
                f"{self.hidden_widths!r}"
            )
        if self.replay_capacity < self.kappa:
            raise ValueError(
                f"LearnerConfig.replay_capacity ({self.replay_capacity}) must be >= kappa "
                f"({self.kappa})"
            )

    @property
    def n_training_rounds(self) -> int:
        """Training rounds within ``train_steps``: floor(train_steps / κ)."""
        return self.train_steps // self.kappa

    def to_dict(self) -> dict[str, object]:
        """Plain-JSON form (tuples become lists)."""
        data = dataclasses.asdict(self)
        data["hidden_widths"] = list(self.hidden_widths)
        return data

    @classmethod
    def from_dict(cls, data: dict[str, object]) -> LearnerConfig:
        """Inverse of :meth:`to_dict`.

        Raises:
            ValueError: missing or unknown fields, or invalid values.
        """
        names = {f.name for f in dataclasses.fields(cls)}
        missing = sorted(names - data.keys())
        unknown = sorted(data.keys() - names)
        if missing or unknown:
            raise ValueError(f"LearnerConfig: missing fields {missing}, unknown fields {unknown}")
        values = dict(data)
        values["hidden_widths"] = tuple(values["hidden_widths"])  # type: ignore[arg-type]
        return cls(**values)  # type: ignore[arg-type]


def get_preset(name: str, use_case: int, *, train_steps: int | None = None) -> LearnerConfig:
    """The named preset for a use case.

    * ``paper``: Table I verbatim; a round trains one epoch (Keras's default batch of 32) on
      the κ tuples collected since the previous round.
    * ``tuned``: learning rate 1e-3; ε decays linearly to ε_min within the first half of the
      training rounds the step budget allows; each round trains 2 epochs (batch 64) on the
      most recent 2048 tuples. Everything else as ``paper``.

    Args:
        name: "paper" or "tuned".
        use_case: 1, 2 or 3.
        train_steps: Overrides the training budget (default 50·β); ``tuned`` then recomputes
            its ε decay for that budget.

    Raises:
        ValueError: unknown name or use case (the message lists the valid ones).
    """
    if name not in PRESET_NAMES:
        raise ValueError(f"unknown preset {name!r}; valid presets: {', '.join(PRESET_NAMES)}")
    if isinstance(use_case, bool) or use_case not in USE_CASES:
        raise ValueError(
            f"unknown use case {use_case!r}; valid use cases: {', '.join(map(str, USE_CASES))}"
        )
    table = _TABLE_I[use_case]
    beta = int(table["beta"])
    paper = LearnerConfig(
        name="paper",
        use_case=use_case,
        learning_rate=float(table["learning_rate"]),
        delta=float(table["delta"]),
        epsilon_start=1.0,
        epsilon_decay=3.3e-6,
        epsilon_min=0.01,
        kappa=128,
        episode_steps=256,
        n_episodes=int(table["n_episodes"]),
        beta=beta,
        train_steps=50 * beta if train_steps is None else train_steps,
        test_steps=20 * beta,
        hidden_widths=DEFAULT_HIDDEN_WIDTHS,
        replay_capacity=128,
        epochs_per_round=1,
        batch_size=32,
    )
    if name == "paper":
        return paper
    rounds_to_min = max(1, math.floor(TUNED_EXPLORATION_FRACTION * paper.n_training_rounds))
    return dataclasses.replace(
        paper,
        name="tuned",
        learning_rate=1e-3,
        epsilon_decay=(paper.epsilon_start - paper.epsilon_min) / rounds_to_min,
        replay_capacity=2048,
        epochs_per_round=2,
        batch_size=64,
    )

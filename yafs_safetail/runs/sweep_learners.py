"""Which SafeTails a contention sweep can train: one per training objective, each with its
rows' method name, its default preset and dispatch (:data:`LEARNER_DEFAULTS`), and, once a
sweep's configuration resolves them, a :class:`SafeTailVariant`.

Each is its objective's (``methods.objectives``: its rows' name, preset, dispatch, networks).
A light module (the standard library and ``methods.objectives``), as ``runs.sweep_config``,
which builds the sweep commands' parsers from it: the learner's presets are imported only when a
SafeTail's training budget is asked for.
"""

from __future__ import annotations

from dataclasses import dataclass

from yafs_safetail.methods.objectives import objective_named, objective_names

#: The row of each SafeTail learner (``SweepConfig.learners``), its objective's ``method_name``:
#: the paper's §III learner is ``SafeTail``; the original code's Q-style targets (D18) are
#: ``SafeTail-Q``; the value learner, which prices its copies by the load they join, is
#: ``SafeTail-CA`` (contention-aware, beyond the paper: docs/deviations.md D13).
SAFETAIL_LEARNERS: dict[str, str] = {name: objective_named(name).method_name for name in objective_names()}
SAFETAIL_CA = objective_named("value").method_name
SAFETAIL_Q = objective_named("q-target").method_name
#: The SafeTails a sweep trains unless ``--objectives`` says otherwise: those every measurement
#: of the contention world was made with (docs/contention.md).
DEFAULT_SWEEP_OBJECTIVES: tuple[str, ...] = ("target-vector", "value")
#: Each learner's preset and dispatch unless ``--preset`` / ``--safetail-dispatch`` say otherwise
#: (its objective's ``preset`` and ``dispatch``): the paper's as the paper has it; the
#: contention-aware one as it was chosen (D13).
LEARNER_DEFAULTS: dict[str, tuple[str, str]] = {
    name: (objective_named(name).preset, objective_named(name).dispatch) for name in objective_names()}
#: How many networks the value learner averages unless told (``SweepConfig.value_networks``;
#: its objective's ``sweep_networks``): chosen on seeds 0-6 over one network, then judged on
#: seeds 19-30 (docs/deviations.md D13).
DEFAULT_VALUE_NETWORKS = objective_named("value").sweep_networks


def training_requests(preset: str, use_case: int, steps_scale: float) -> int:
    """A SafeTail's training requests per point: its preset's budget × ``steps_scale``."""
    from yafs_safetail.methods.safetail.presets import get_preset, scaled_steps

    return scaled_steps(get_preset(preset, use_case).train_steps, steps_scale)


@dataclass(frozen=True)
class SafeTailVariant:
    """One SafeTail of a sweep, resolved from the sweep's configuration.

    Attributes:
        name: its rows' method name (``SafeTail``, ``SafeTail-Q`` or ``SafeTail-CA``).
        learner: its training objective's name (``methods.objectives``).
        preset: its learner preset.
        dispatch: how its subset is sent (all at once or tied).
        reward: the reward it is trained with (the value learner's own ``latency-cost``).
        n_networks: how many networks' predictions it averages.
        train_requests: its training requests per point.
    """

    name: str
    learner: str
    preset: str
    dispatch: str
    reward: str
    n_networks: int
    train_requests: int

    def describe(self) -> str:
        """One line for the sweep's report: how this SafeTail learns and sends."""
        networks = f" ({self.n_networks} networks averaged)" if self.n_networks > 1 else ""
        return (f"preset `{self.preset}`, learner `{self.learner}`{networks}, reward `{self.reward}`, "
                f"dispatch `{self.dispatch}`")

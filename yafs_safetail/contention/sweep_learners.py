"""Which SafeTails a contention sweep can train: one per training objective, each with its
rows' method name, its default preset and dispatch (:data:`LEARNER_DEFAULTS`), and, once a
sweep's configuration resolves them, a :class:`SafeTailVariant`.

A light module (the standard library and ``defaults``), as ``contention.sweep_config``, which
builds the sweep commands' parsers from it: the learner's presets are imported only when a
SafeTail's training budget is asked for.
"""

from __future__ import annotations

from dataclasses import dataclass

from yafs_safetail.defaults import SAFETAIL

#: The row of each SafeTail learner (``SweepConfig.learners``): the paper's §III learner is
#: ``SafeTail``; the original code's Q-style targets (D18) are ``SafeTail-Q``; the value learner,
#: which prices its copies by the load they join, is ``SafeTail-CA`` (contention-aware, beyond
#: the paper: docs/deviations.md D13).
SAFETAIL_CA = "SafeTail-CA"
SAFETAIL_Q = "SafeTail-Q"
SAFETAIL_LEARNERS: dict[str, str] = {"target-vector": SAFETAIL, "q-target": SAFETAIL_Q, "value": SAFETAIL_CA}
#: The SafeTails a sweep trains unless ``--objectives`` says otherwise: those every measurement
#: of the contention world was made with (docs/contention.md).
DEFAULT_SWEEP_OBJECTIVES: tuple[str, ...] = ("target-vector", "value")
#: Each learner's preset and dispatch unless ``--preset`` / ``--safetail-dispatch`` say otherwise:
#: the paper's as the paper has it; the contention-aware one as it was chosen (D13).
LEARNER_DEFAULTS: dict[str, tuple[str, str]] = {"target-vector": ("paper", "all"), "q-target": ("paper", "all"),
                                                "value": ("tuned", "tied")}
#: How many networks the value learner averages unless told (``SweepConfig.value_networks``):
#: chosen on seeds 0-6 over one network, then judged on seeds 19-30 (docs/deviations.md D13).
DEFAULT_VALUE_NETWORKS = 3


def training_requests(preset: str, use_case: int, steps_scale: float) -> int:
    """A SafeTail's training requests per point: its preset's budget × ``steps_scale``."""
    from yafs_safetail.methods.safetail.presets import get_preset, scaled_steps

    return scaled_steps(get_preset(preset, use_case).train_steps, steps_scale)


@dataclass(frozen=True)
class SafeTailVariant:
    """One SafeTail of a sweep, resolved from the sweep's configuration.

    Attributes:
        name: its rows' method name (``SafeTail``, ``SafeTail-Q`` or ``SafeTail-CA``).
        learner: its training objective (one of OBJECTIVES).
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

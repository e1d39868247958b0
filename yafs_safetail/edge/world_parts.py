"""What a world is drawn from: the use case, its traces, the scenario and the world's settings.

Every world of the project is drawn from these four parts: the paper's single-user runs
(``worlds.recipe``, used by the experiment and the Gymnasium environment ``sim.env``) and
the contention world (``contention.world``, which draws its request blocks and background
tenants as edge worlds). They read the parts with :func:`read_world_parts` (the world's settings
with a run's overrides already applied: ``settings.world.apply_world_overrides``) and draw every
world with :meth:`WorldParts.draw`, so a setting changes every world the same way.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from yafs_safetail.defaults import DEFAULT_STEP_INTERVAL_S, DEFAULT_TRACE_DIR
from yafs_safetail.edge.calibration import WorldSettings
from yafs_safetail.edge.energy import EnergyModel
from yafs_safetail.edge.failures import FailureSettings
from yafs_safetail.edge.inputs import TraceInputs, load_inputs, load_scenario_for
from yafs_safetail.edge.movement import MobilityPlan
from yafs_safetail.edge.scenario import EdgeScenario
from yafs_safetail.edge.usecases import UseCase, get_use_case
from yafs_safetail.edge.world import DEFAULT_EPISODE_STEPS, DEFAULT_MAX_LOAD, EdgeWorld, build_world

__all__ = ["OnWorldParts", "WorldParts", "read_world_parts"]


@dataclass(frozen=True)
class WorldParts:
    """Everything a world is drawn from, read and checked once; the seed and phase pick the draws.

    Attributes:
        use_case: the use case.
        inputs: its traces and compute model (they do not depend on the seed).
        scenario: the topology and placement, checked against the traces.
        settings: the world's readings and calibrated parameters, any overrides applied.
    """

    use_case: UseCase
    inputs: TraceInputs
    scenario: EdgeScenario
    settings: WorldSettings

    def draw(self, n_steps: int, seed: int, phase: str, *, episode_steps: int = DEFAULT_EPISODE_STEPS,
             max_load: int = DEFAULT_MAX_LOAD, failures: FailureSettings | None = None,
             energy: EnergyModel | None = None,
             step_interval_s: float = DEFAULT_STEP_INTERVAL_S,
             mobility: MobilityPlan | None = None) -> EdgeWorld:
        """The world of ``n_steps`` requests drawn from ``(seed, phase)`` (``edge.world.build_world``,
        whose documentation says what each option does; their defaults are its own)."""
        return build_world(self.scenario, self.use_case, self.inputs, n_steps, seed=seed, phase=phase,
                           episode_steps=episode_steps, max_load=max_load, settings=self.settings,
                           failures=failures, energy=energy, step_interval_s=step_interval_s,
                           mobility=mobility)


class OnWorldParts:
    """The parts' four members read through an object built on them (``parts``)."""

    parts: WorldParts

    @property
    def use_case(self) -> UseCase:
        return self.parts.use_case

    @property
    def inputs(self) -> TraceInputs:
        return self.parts.inputs

    @property
    def scenario(self) -> EdgeScenario:
        return self.parts.scenario

    @property
    def settings(self) -> WorldSettings:
        return self.parts.settings


def read_world_parts(use_case: int, settings: WorldSettings, topology: Path | str, placement: Path | str,
                     traces_dir: Path | str | None = None, inputs: TraceInputs | None = None,
                     scenario: EdgeScenario | None = None) -> WorldParts:
    """Read a world's parts from the use case's number, its files and the world's settings.

    Args:
        use_case: the use case's number (1, 2 or 3).
        settings: the world's settings, overrides already applied
            (``settings.world.apply_world_overrides``).
        topology: the topology JSON.
        placement: the placement JSON.
        traces_dir: the traces folder (None: the repository's).
        inputs: the use case's trace inputs read earlier (by another world of the same run: they
            depend on neither the seed nor the settings), instead of reading them again.
        scenario: likewise, the scenario read earlier from the same topology and placement.

    Raises:
        ValueError: an unknown use case, or a bad trace, model, topology or placement file (one
            line naming it).
    """
    case = get_use_case(use_case)
    if inputs is None:
        inputs = load_inputs(case, DEFAULT_TRACE_DIR if traces_dir is None else traces_dir)
    if scenario is None:
        scenario = load_scenario_for(inputs, Path(topology), Path(placement))
    return WorldParts(use_case=case, inputs=inputs, scenario=scenario, settings=settings)

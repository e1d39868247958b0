"""The one recipe for a run's world: from a configuration to the pre-drawn world of a phase.

The experiment (``runs.experiment``), the API, the Gymnasium environment (``sim.env``) and the
YAFS-style example (``examples/paper_scenario/main.py``) all make their worlds here (``worlds``, the
floor above ``edge`` and ``methods``, below ``sim``, ``contention`` and ``runs``), so a setting that
changes the world (the preset's world, ``--target-latency-s``, ``--load-peak-users``,
``--target-compute``, the topology, the failures and power models...) changes it the same way in
all of them; the contention world takes its input and mobility rules from here too.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from yafs_safetail.defaults import DEFAULT_STEP_INTERVAL_S
from yafs_safetail.edge.calibration import world_settings
from yafs_safetail.edge.energy import EnergyModel, ServerPowerModel
from yafs_safetail.edge.failures import DEFAULT_MTTR_S, FailureSettings, read_down_file
from yafs_safetail.edge.movement import (
    MobilityPlan,
    MovementError,
    default_area_m,
    server_positions_m,
)
from yafs_safetail.edge.routes import RandomWaypoint, read_route
from yafs_safetail.edge.scenario import EdgeScenario
from yafs_safetail.edge.signal import DEFAULT_SIGNAL_RULE
from yafs_safetail.edge.world import EdgeWorld
from yafs_safetail.edge.world_parts import OnWorldParts, WorldParts, read_world_parts
from yafs_safetail.methods.safetail.presets import (
    PRESET_WORLDS,
    LearnerConfig,
    get_preset,
    scaled_steps,
)
from yafs_safetail.settings.declare import check_config, field_of, setting_of
from yafs_safetail.settings.experiment import (
    ExperimentConfig,
    ExperimentError,
    Mobility,
    learner_overrides,
)
from yafs_safetail.settings.input_paths import resolve_input
from yafs_safetail.settings.world import WorldOverrideError, apply_world_overrides

__all__ = [
    "TRAIN", "TEST", "WorldRecipe", "input_file", "traces_folder", "failure_settings", "energy_model",
    "MobilitySettings", "check_mobility_settings", "mobility_plan", "learner_config", "world_recipe",
    "make_world",
]

#: The phases a run's worlds are drawn for (independent random streams).
TRAIN, TEST = "train", "test"


@dataclass(frozen=True)
class WorldRecipe(OnWorldParts):
    """Everything a run's worlds are drawn from, read and checked once.

    Attributes:
        parts: what every world is drawn from (``edge.world_parts``): the use case, its traces
            and compute model, the topology and placement checked against the traces, and the
            world's settings (the preset's world, or the configuration's own, with the run's
            overrides applied); :attr:`use_case`, :attr:`inputs`, :attr:`scenario` and
            :attr:`settings` read them.
        overrides: the overrides that changed the world (an option repeating the world's own
            value is left out), for ``run.json``.
        full_preset: the learner preset at full budget.
        learner: the learner of this run (its training budget and hyperparameter overrides).
        test_steps: the test phase's requests.
        failures: which servers fail and the user's time-out (``edge.failures``).
        energy: the servers' and the device's power models (``edge.energy``).
        step_interval_s: time between two requests (the outages are drawn over the phase).
        mobility: how the user moves (``edge.movement``); None: it stays where the topology
            puts it.
    """

    parts: WorldParts
    full_preset: LearnerConfig
    learner: LearnerConfig
    test_steps: int
    overrides: dict[str, Any] = field(default_factory=dict)
    failures: FailureSettings = field(default_factory=FailureSettings)
    energy: EnergyModel = field(default_factory=EnergyModel)
    step_interval_s: float = DEFAULT_STEP_INTERVAL_S
    mobility: MobilityPlan | None = None

    def n_steps(self, phase: str) -> int:
        """The requests of ``phase`` (``"train"``: the learner's budget; else the test's)."""
        return self.learner.train_steps if phase == TRAIN else self.test_steps

    def make_world(self, phase: str, seed: int) -> EdgeWorld:
        """The world of ``phase`` drawn from ``seed`` (every method of the phase replays it)."""
        return self.parts.draw(self.n_steps(phase), seed, phase, episode_steps=self.learner.episode_steps,
                               failures=self.failures, energy=self.energy,
                               step_interval_s=self.step_interval_s, mobility=self.mobility)


def input_file(path: str | Path) -> Path:
    """An input option's file: as given when it exists there, else the packaged default of that
    name (``topologies/campus_5servers.json`` from any folder; ``settings.input_paths``),
    else as given (its reader then names it)."""
    given = Path(path)
    return given if given.exists() else resolve_input(given, Path.cwd())


def traces_folder(config: ExperimentConfig, style: str = "option") -> Path:
    """The run's traces folder (``--traces``): as given when it exists there (``~`` expanded),
    else the packaged folder of that name (``traces`` from any folder), as :func:`input_file`.

    Raises:
        ExperimentError: no such folder (its files are checked as they are read: one line
            naming the file, the row and the column).
    """
    folder = input_file(Path(config.traces_dir).expanduser())
    if not folder.is_dir():
        raise ExperimentError(f"{_label('traces_dir', style)} {config.traces_dir}: no such folder")
    return folder


def _label(name: str, style: str) -> str:
    """How an error names the configuration field ``name`` (:meth:`Setting.label`)."""
    return setting_of(field_of(ExperimentConfig, name)).label(name, style)


def failure_settings(config: ExperimentConfig, n_servers: int, style: str = "option") -> FailureSettings:
    """The run's failures from its options (the down-intervals file read once, to check it).

    Raises:
        ExperimentError: ``--failure-probability`` together with ``--failure-mttf-s``.
        FailureFileError: a bad down-intervals file (one line: file, row, field).
    """
    mttr_s = DEFAULT_MTTR_S if config.failure_mttr_s is None else float(config.failure_mttr_s)
    if config.failure_probability is not None and config.failure_mttf_s is not None:
        raise ExperimentError(f"{_label('failure_probability', style)}: give it or "
                              f"{_label('failure_mttf_s', style)}, "
                              "not both (the probability sets the mean time to failure)")
    if config.failure_probability is not None:
        settings = FailureSettings.for_unavailability(float(config.failure_probability), mttr_s,
                                                      config.timeout_s)
    else:
        settings = FailureSettings(mttf_s=config.failure_mttf_s, mttr_s=mttr_s, timeout_s=config.timeout_s)
    if config.down_intervals is not None:
        down_file = input_file(config.down_intervals)
        read_down_file(down_file, n_servers)  # bad input: one line, before any draw
        settings = dataclasses.replace(settings, down_file=down_file)
    return settings


def energy_model(config: ExperimentConfig, style: str = "option") -> EnergyModel:
    """The run's power models: the cited defaults, with ``--server-idle-w``/``--server-max-w``.

    Raises:
        ExperimentError: a maximum power below the idle power.
    """
    default = ServerPowerModel()
    idle_w = default.idle_w if config.server_idle_w is None else float(config.server_idle_w)
    max_w = default.max_w if config.server_max_w is None else float(config.server_max_w)
    if max_w < idle_w:
        raise ExperimentError(f"{_label('server_max_w', style)}: {max_w:g} W is below the idle power {idle_w:g} W")
    return EnergyModel(server=ServerPowerModel(idle_w=idle_w, max_w=max_w))


class MobilitySettings(Protocol):
    """The settings of how users move (``settings.experiment.Mobility``'s fields): the
    experiment's, and the contention world's, which declares the same settings."""

    @property
    def mobility(self) -> str: ...
    @property
    def route(self) -> Path | None: ...
    @property
    def speed_mps(self) -> tuple[float, float]: ...
    @property
    def pause_s(self) -> float: ...


def _mobility_label(name: str, style: str) -> str:
    """How an error names the mobility setting ``name`` (the same in every configuration)."""
    return setting_of(field_of(Mobility, name)).label(name, style)


def check_mobility_settings(config: MobilitySettings, style: str = "option",
                            error: type[ValueError] = ExperimentError) -> None:
    """The mobility settings that do not go together, without reading any file.

    Raises:
        ValueError: (``error``) a route without ``--mobility route`` or the reverse, or random
            waypoint's speeds or pause without it.
    """
    mode = config.mobility
    if mode == "route" and config.route is None:
        raise error(f"{_mobility_label('mobility', style)} route: needs {_mobility_label('route', style)} FILE")
    if config.route is not None and mode != "route":
        raise error(f"{_mobility_label('route', style)}: only with {_mobility_label('mobility', style)} route")
    if mode != "random-waypoint":
        for name in ("speed_mps", "pause_s"):
            if getattr(config, name) != field_of(Mobility, name).default:
                raise error(f"{_mobility_label(name, style)}: only with "
                            f"{_mobility_label('mobility', style)} random-waypoint")


def mobility_plan(config: MobilitySettings, scenario: EdgeScenario, style: str = "option",
                  error: type[ValueError] = ExperimentError) -> MobilityPlan | None:
    """How the run's users move, from its settings (the route file read once, to check it).

    Args:
        config: the experiment's or the contention world's configuration.
        scenario: the topology (every server's position, the user's start).
        style: how errors name a setting (as :func:`world_recipe`).
        error: what a bad combination raises (the contention world's own error there).

    Raises:
        ValueError: (``error``) settings that do not go together
            (:func:`check_mobility_settings`), or a topology that does not place every server.
        RouteError: a bad route file (one line: file, point, what is wrong).
    """
    check_mobility_settings(config, style, error)
    mode = config.mobility
    if mode == "off":
        return None
    try:
        server_positions_m(scenario)
    except MovementError as problem:
        raise error(f"{_mobility_label('mobility', style)} {mode}: {problem}") from None
    if mode == "route":
        assert config.route is not None
        return MobilityPlan(route=read_route(input_file(config.route), scenario.topology.origin))
    speeds = tuple(float(v) for v in config.speed_mps)
    return MobilityPlan(random_waypoint=RandomWaypoint(
        default_area_m(scenario, DEFAULT_SIGNAL_RULE), (speeds[0], speeds[1]), float(config.pause_s)))


def learner_config(config: ExperimentConfig) -> tuple[LearnerConfig, LearnerConfig]:
    """The preset at full budget, and the learner this run trains: the preset with the run's
    training steps and ``settings.experiment.LearnerOverrides`` applied (here, where the
    configuration meets the presets, a floor above the settings).

    Raises:
        ValueError: an unknown preset or use case.
    """
    full = get_preset(config.preset, config.use_case)
    learner = get_preset(config.preset, config.use_case,
                         train_steps=scaled_steps(full.train_steps, config.steps_scale))
    overrides = learner_overrides(config)
    # A number the user gave as an integer is still the float hyperparameter the preset has.
    typed = {name: type(getattr(learner, name))(value) for name, value in overrides.items()}
    return full, dataclasses.replace(learner, **typed)


def world_recipe(config: ExperimentConfig, style: str = "option") -> WorldRecipe:
    """Check the configuration's fields and read what its worlds are drawn from.

    Args:
        config: the run's configuration.
        style: how errors name a setting (``"option"``: ``--target-latency-s``; ``"field"``:
            ``target_latency_s``), as :func:`~yafs_safetail.settings.declare.check_config`.

    Raises:
        ValueError: a bad setting or input file (one line naming it).
    """
    check_config(config, style)
    full, learner = learner_config(config)
    preset_world = config.world or world_settings(PRESET_WORLDS[config.preset])
    parts = read_world_parts(config.use_case, preset_world, input_file(config.topology), input_file(config.placement),
                             traces_folder(config, style))
    try:
        settings, overrides = apply_world_overrides(parts.settings, config)
    except WorldOverrideError as error:  # named as the run's option (or field)
        raise ExperimentError(f"{_label(error.name, style)}: {error.value!r} is out of range") from None
    return WorldRecipe(parts=dataclasses.replace(parts, settings=settings), full_preset=full, learner=learner,
                       test_steps=scaled_steps(full.test_steps, config.steps_scale), overrides=overrides,
                       failures=failure_settings(config, parts.scenario.n_servers, style),
                       energy=energy_model(config, style), step_interval_s=config.step_interval_s,
                       mobility=mobility_plan(config, parts.scenario, style))


def make_world(config: ExperimentConfig, phase: str, seed: int | None = None) -> EdgeWorld:
    """The world of ``phase`` for ``config`` (seed: the configuration's unless given)."""
    return world_recipe(config).make_world(phase, config.seed if seed is None else seed)

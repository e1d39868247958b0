"""Every setting of a run, declared once: its type, default, help text, check, and whether it
changes the results.

A run's configuration is four small groups, each a frozen dataclass a reader can take in at a
glance:

- :class:`Task`: what to run (use case, preset, seed, budget, the methods compared);
- :class:`WorldSetup`: the world it runs in (topology, placement, traces, the world's settings
  and the run's own overrides of them);
- :class:`LearnerOverrides`: SafeTail's hyperparameters that replace the preset's;
- :class:`Output`: where the run writes and how it runs (never what it computes, except which
  files the folder holds).

:class:`ExperimentConfig` is the four together (it inherits their fields, so ``config.seed``
and ``ExperimentConfig(seed=3)`` read as before). Each field carries a :class:`Setting` in its
metadata (declared with :func:`setting`; the machinery lives in ``settings.declare``, the
command line derived from it in ``settings.options``): the command-line options of the scripts
(:func:`add_options`), the configuration from parsed options (:func:`config_from_args`), the
checks at run start (:func:`check_config`), the campaign grid's settable fields and the run id
(``runs.grid``: :data:`RESULT_FIELDS`), the Gymnasium environment's keywords (``sim.env``), the
learner's hyperparameters (``worlds.recipe.learner_config``) and ``run.json``'s record of what was
overridden (:func:`learner_overrides`). The world's overrides are ``settings.world``'s, shared
with the contention world.

Adding a setting is one field in one group (CONTRIBUTING.md shows an example).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, ClassVar

# Only light modules here: the scripts build their parsers and check their arguments from this
# module before NumPy, pandas, simpy or TensorFlow load (``--help`` answers at once). The
# defaults and choices come from yafs_safetail.defaults; what runs a configuration is imported
# where it is used.
from yafs_safetail.defaults import (
    DEFAULT_FIGURE_FORMATS,
    DEFAULT_PLACEMENT,
    DEFAULT_STEP_INTERVAL_S,
    DEFAULT_TOPOLOGY,
    DEFAULT_TRACE_DIR,
    MOBILITY_MODELS,
    OBJECTIVES,
    PRESET_NAMES,
    USE_CASES,
    WALKING_SPEED_MPS,
)
from yafs_safetail.settings.checks import (
    BOOLEAN,
    FORMATS,
    LEVELS,
    NON_NEGATIVE_INTEGER,
    NON_NEGATIVE_NUMBER,
    POSITIVE_INTEGER,
    POSITIVE_NUMBER,
    PROBABILITY_BELOW_ONE,
    SPEED_RANGE,
    Names,
    one_of,
)
from yafs_safetail.settings.declare import Provided, SettingError, setting, setting_of
from yafs_safetail.settings.world import WorldOverrides, WorldSettings

__all__ = [
    "ExperimentError", "Task", "WorldInputs", "WorldOverrides", "FailuresAndPower", "Mobility", "WorldSetup",
    "LearnerOverrides", "Output", "ExperimentConfig", "GROUPS", "FIRST_RESULT_FIELDS", "LATER_RESULT_FIELDS",
    "RESULT_FIELDS", "RUNTIME_FIELDS", "GRID_RUNTIME_FIELDS", "OBJECTIVE_NAMES", "learner_overrides",
    "expand_method_spec", "USER_METHODS",
]


class ExperimentError(SettingError):
    """A bad experiment setting (one line naming the setting and what is wrong)."""


#: The objectives ``--objective`` accepts: the project's (``defaults.OBJECTIVES``), and every
#: class ``methods.objectives`` defines, which adds its name when defined (a floor above this one).
OBJECTIVE_NAMES = Names(OBJECTIVES)


# ----------------------------------------------------------------------------- the groups


def expand_method_spec(spec: str) -> str:
    """A ``--method [NAME=]FILE.py:CLASS`` spec with ``~`` in its file expanded, as every path
    option's is (``settings.parse.user_path``); a ``module:Class`` spec is returned as it is."""
    name, sep, target = spec.partition("=")
    if not sep or ":" in name or "/" in name:  # no NAME= prefix (as methods.registry reads it)
        name, sep, target = "", "", spec
    return f"{name}{sep}{Path(target).expanduser()}" if target.startswith("~") else spec


#: ``--method`` specs to users' policies (``methods.registry.UserMethod``, each file loaded and
#: checked): the ``methods`` package provides it when imported, a floor above the declarations.
USER_METHODS = Provided("--method", "yafs_safetail.methods")


@dataclass(frozen=True)
class Task:
    """What to run: which use case, with which learner preset and seed, how long, against what."""

    use_case: int = setting(1, "use case: 1 object detection, 2 instance segmentation, 3 noise removal",
                            check=one_of(USE_CASES, int), flag="--uc")
    preset: str = setting(
        "paper", "learner preset (default: paper = Table I with the readings under which it learns, "
        "in the calibrated world; paper-literal = Table I verbatim; tuned = ours; deviations D1, D6, D8 in the documentation)",
        check=one_of(PRESET_NAMES))
    seed: int = setting(0, "the run's seed (default 0)", check=NON_NEGATIVE_INTEGER)
    steps_scale: float = setting(1.0, "fraction of the preset's training and testing steps (default 1)",
                                 check=POSITIVE_NUMBER)
    redundancy_levels: tuple[int, ...] = setting(
        (1, 2, 3), "levels x of Rand-x, MinLoad-x, MinProp-x (default 1,2,3)", check=LEVELS,
        flag="--redundancy")
    # Users' policies, methods.registry.UserMethod (a higher floor's type, so not named here).
    methods: tuple[Any, ...] = setting(
        (), "add your own Policy to the comparison (also module:Class; repeatable; named after the "
        "class unless NAME= is given)", flag="--method", action="append", metavar="[NAME=]FILE.py:CLASS",
        from_cli=USER_METHODS)
    policy: Path | None = setting(None, "evaluate this saved policy (.keras) without training", optional=True)


@dataclass(frozen=True)
class WorldInputs:
    """What the run's world is read from: the topology, the traces, the world's settings."""

    topology: Path = setting(DEFAULT_TOPOLOGY, "YAFS topology JSON with 1 to 10 edge servers "
                             "(default topologies/paper_5servers.json)")
    placement: Path = setting(DEFAULT_PLACEMENT, "YAFS placement JSON (default: placements/<topology file name>)")
    traces_dir: Path = setting(
        DEFAULT_TRACE_DIR, "your own measured traces: a folder with the packaged traces' CSVs and models/, in "
        "their formats (default: the packaged traces; \"Measure your own\" in the documentation)",
        flag="--traces", metavar="DIR")
    step_interval_s: float = setting(
        DEFAULT_STEP_INTERVAL_S, f"simulated time between two requests, one load-trace row "
        f"(default {DEFAULT_STEP_INTERVAL_S:g})", check=POSITIVE_NUMBER)
    world: WorldSettings | None = setting(
        None, "the world settings; None: the preset's world (methods.safetail.presets.PRESET_WORLDS)",
        flag="", optional=True)
@dataclass(frozen=True)
class FailuresAndPower:
    """Which servers fail, how long a user waits, what the servers draw (beyond the paper;
    docs/failures_energy.md). None everywhere: no server fails, no time-out, and the energy
    models' cited defaults."""

    failure_mttf_s: float | None = setting(
        None, "each server's mean time to failure in seconds (exponential up and down times, "
        "each server starting in its stationary state; default: servers never fail)",
        check=POSITIVE_NUMBER, optional=True)
    failure_mttr_s: float | None = setting(
        None, "each server's mean time to repair in seconds (default: edge.failures.DEFAULT_MTTR_S, "
        "one load-trace minute)", check=POSITIVE_NUMBER, optional=True)
    failure_probability: float | None = setting(
        None, "each server's stationary probability of being down (sets the mean time to failure "
        "from the mean time to repair; not with --failure-mttf-s; 0: no random failures)",
        check=PROBABILITY_BELOW_ONE, optional=True)
    down_intervals: Path | None = setting(
        None, "a CSV of scripted outages, header server,down_s,up_s (server index from 0, seconds "
        "from the phase's start), added to the random ones", optional=True)
    timeout_s: float | None = setting(
        None, "how long the user waits for a first reply before the on-device fallback, in seconds "
        "(default: with failures, the world's worst-case latency of a live copy; without, none)",
        check=POSITIVE_NUMBER, optional=True)
    server_idle_w: float | None = setting(
        None, "a server's power with no request running, in watts (default: edge.energy's "
        "ASSUMED_IDLE_POWER_W)", check=NON_NEGATIVE_NUMBER, optional=True)
    server_max_w: float | None = setting(
        None, "a server's power at its load limit, in watts (default: edge.energy's "
        "I7_11700_BASE_POWER_W, the paper's server CPU)", check=NON_NEGATIVE_NUMBER, optional=True)


@dataclass(frozen=True)
class Mobility:
    """Whether and how the user moves (beyond the paper; docs/mobility.md). Off: the user stays
    where the topology puts it and every link keeps the topology's condition."""

    mobility: str = setting(
        "off", "how the user moves: off, random-waypoint, or route (--route); on the move each "
        "link's condition follows the user's distance to its server, so the topology must place "
        "every edge server (x, y or lat, lon; e.g. topologies/campus_5servers.json)",
        check=one_of(MOBILITY_MODELS))
    route: Path | None = setting(
        None, "with --mobility route: the route, a CSV (time_s,x_m,y_m or time_s,lat,lon) or a GPX "
        "track (e.g. routes/campus_walk.csv)", optional=True)
    speed_mps: tuple[float, float] = setting(
        WALKING_SPEED_MPS, "with --mobility random-waypoint: the speed range in m/s, slowest,fastest "
        "(default 1,1.5, walking; 0,0: at rest)", check=SPEED_RANGE, metavar="SLOWEST,FASTEST")
    pause_s: float = setting(30.0, "with --mobility random-waypoint: the pause at each destination in "
                             "seconds (default 30)", check=NON_NEGATIVE_NUMBER)


@dataclass(frozen=True)
class WorldSetup(Mobility, FailuresAndPower, WorldOverrides, WorldInputs):
    """The world the run happens in: its inputs, the run's overrides of the world's settings
    (``settings.world``, shared with the contention world), its failures and power models, and
    how the user moves, fields in that order."""


@dataclass(frozen=True)
class LearnerOverrides:
    """SafeTail's hyperparameters that replace its preset's. Each field is named as the
    :class:`~yafs_safetail.methods.safetail.presets.LearnerConfig` field it replaces; None keeps
    the preset's. The run is then no longer the preset's configuration, and ``run.json`` and
    ``summary.md`` say so."""

    learning_rate: float | None = setting(
        None, "Adam's learning rate for SafeTail instead of the preset's (e.g. the paper preset's "
        "network with tuned's 1e-3); the run is then no longer the preset's, and run.json and "
        "summary.md say so", check=POSITIVE_NUMBER, optional=True)
    energy_price_per_j: float | None = setting(
        None, "beyond the paper: subtract this price times a request's energy (J) from SafeTail's "
        "Eq. 5 reward (default 0: the paper's reward; deviation D15 in the documentation)",
        check=NON_NEGATIVE_NUMBER, optional=True)
    failure_penalty: float | None = setting(
        None, "beyond the paper: subtract this from SafeTail's Eq. 5 reward for every request that "
        "did not end with a reply (default 0; deviation D15 in the documentation)",
        check=NON_NEGATIVE_NUMBER, optional=True)
    objective: str | None = setting(
        None, "what SafeTail's network is trained toward: target-vector (the paper's §III text; every "
        "preset's default), q-target (the original code's Q-style targets, deviation D18) or, beyond the paper, value (the network regresses each "
        "action's latency score, less the D15 prices when set, and copies to busy servers are priced "
        "at dispatch: the contention world's SafeTail-CA learner; deviations D13, D15 in the "
        "documentation)", check=one_of(OBJECTIVE_NAMES),
        optional=True, deprecated=("--learner",))
    n_networks: int | None = setting(
        None, "with --objective value: how many value networks, each from its own initial weights, "
        "SafeTail averages (default 1; deviation D13 in the documentation)", check=POSITIVE_INTEGER,
        flag="--value-networks", optional=True)


#: The result fields run ids were first recorded with. Every later one (a setting added since) is
#: left out of a run id while it is at its default, so every configuration that does not use it
#: keeps its id: a new setting needs no entry here.
FIRST_RESULT_FIELDS: tuple[str, ...] = (
    "use_case", "preset", "seed", "steps_scale", "redundancy_levels", "methods", "policy", "topology",
    "placement", "traces_dir", "step_interval_s", "world", "target_latency_s", "load_peak_users",
    "target_compute", "learning_rate", "write_yafs_csv", "figures")


@dataclass(frozen=True)
class Output:
    """Where the run writes and how it runs. Only which files the folder holds (YAFS CSVs,
    figures) changes the results; the rest never does."""

    out_dir: Path = setting(Path("results/uc1"), "results folder, written only when the run succeeds; "
                            "never replaced unless --overwrite", changes_results=False, flag="--out")
    write_yafs_csv: bool = setting(False, "also write each method's YAFS result CSVs under yafs/ (~70 MB for UC1)",
                                   check=BOOLEAN, flag="--yafs-csv", action="store_true",
                                   negation="--no-yafs-csv")
    figures: bool = setting(True, "skip the figures", check=BOOLEAN, flag="--no-figures", action="store_false")
    # Which copies of the same figures: not part of the run id, like the run's log.
    figure_formats: tuple[str, ...] = setting(
        DEFAULT_FIGURE_FORMATS, "figure formats, comma-separated: png, pdf or png,pdf (default png; "
        "PDF copies take as long again)", changes_results=False, check=FORMATS, flag="--figure-format",
        metavar="FORMATS", in_grid=True)
    progress: bool = setting(True, "show progress bars on stderr (the phases are logged either way)",
                             changes_results=False, check=BOOLEAN, flag="")
    command: str = setting("", "the command line, recorded in run.json", changes_results=False, flag="")
    workers: int = setting(2, "processes: the baselines are tested in workers-1 other processes while "
                           "SafeTail trains (default 2; 1 = one process; same results)",
                           changes_results=False, check=POSITIVE_INTEGER)
    overwrite: bool = setting(False, "replace an earlier results folder at --out (only a results folder)",
                              changes_results=False, check=BOOLEAN, action="store_true")
    force: bool = setting(False, "run a budget beyond the limits (10 GB of results or 4 GB of memory)",
                          changes_results=False, check=BOOLEAN, action="store_true")
    run_id: str = setting("", "the campaign's identifier of this configuration, recorded in run.json as "
                          "campaign_run_id (runs.campaign); empty outside campaigns",
                          changes_results=False, flag="")
    resume: bool = setting(False, "continue an interrupted run's training from its checkpoint (give the "
                           "same options; the results equal an uninterrupted run's)",
                           changes_results=False, check=BOOLEAN, action="store_true")
    checkpoint_every_s: float | None = setting(
        60.0, "wall-clock seconds between two training checkpoints, kept beside --out as "
        ".<name>.checkpoint until the run ends (default 60)",
        changes_results=False, check=NON_NEGATIVE_NUMBER, optional=True)


@dataclass(frozen=True)
class ExperimentConfig(Output, LearnerOverrides, WorldSetup, Task):
    """Everything one run depends on: :class:`Task`, :class:`WorldSetup`,
    :class:`LearnerOverrides` and :class:`Output` together (their fields, in that order). The
    same configuration gives identical results files."""

    #: What check_config raises for a bad field.
    setting_error: ClassVar[type[ValueError]] = ExperimentError


#: The groups of :class:`ExperimentConfig`, in the order a reader meets them.
GROUPS: tuple[type, ...] = (Task, WorldSetup, LearnerOverrides, Output)
#: Every field a run's results may depend on (the run id hashes exactly these).
RESULT_FIELDS: tuple[str, ...] = tuple(f.name for f in fields(ExperimentConfig) if setting_of(f).changes_results)
#: Fields that say where a run goes and how it shows itself, never what it computes.
RUNTIME_FIELDS: tuple[str, ...] = tuple(f.name for f in fields(ExperimentConfig)
                                        if not setting_of(f).changes_results)
#: Result fields added after run ids were first recorded (hashed only when set).
LATER_RESULT_FIELDS: tuple[str, ...] = tuple(name for name in RESULT_FIELDS if name not in FIRST_RESULT_FIELDS)
#: Runtime fields a campaign grid may still set (e.g. the figures' formats); not in the run id.
GRID_RUNTIME_FIELDS: tuple[str, ...] = tuple(f.name for f in fields(ExperimentConfig)
                                             if setting_of(f).in_grid)


# ----------------------------------------------------------------------------- the learner


def learner_overrides(config: LearnerOverrides) -> dict[str, Any]:
    """The learner hyperparameters this configuration sets (field: value), for ``run.json``."""
    return {item.name: getattr(config, item.name) for item in fields(LearnerOverrides)
            if getattr(config, item.name) is not None}

"""What a contention sweep is: its axis, methods and SafeTails (:class:`ContentionSweep`; the
load sweep :class:`SweepConfig`, the failure sweep :class:`FailureSweepConfig`), each field
declared once with its option and check (``settings.declare.setting``). Which SafeTails a sweep
can train, and how each one learns, is ``runs.sweep_learners``.

Light modules only (the standard library, ``defaults``, ``settings``,
``contention.config``, ``edge.failure_settings``, ``methods.objectives``): the sweep commands build their parsers from
these classes, and ``--help`` or a bad argument must answer before NumPy, pandas or TensorFlow
loads (``tests/test_first_answer.py``). What needs the learner's presets (each SafeTail's training
budget) imports them when asked, after the arguments are checked. ``runs.sweep`` runs the
sweeps.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

from yafs_safetail.contention.config import (
    SUMMARY_COLUMNS,
    TARGETS,
    ContentionConfig,
    ContentionError,
)
from yafs_safetail.defaults import PRESET_NAMES, SAFETAIL_DISPATCH
from yafs_safetail.edge.failure_settings import DEFAULT_MTTR_S, FailureSettings
from yafs_safetail.methods.objectives import objective_named
from yafs_safetail.runs.sweep_checks import (
    FAILURE_LEVELS,
    LEARNERS,
    LOADS,
    METHOD_NAMES,
    ONE_LOAD,
)
from yafs_safetail.runs.sweep_learners import (
    DEFAULT_SWEEP_OBJECTIVES,
    DEFAULT_VALUE_NETWORKS,
    SafeTailVariant,
    training_requests,
)
from yafs_safetail.settings.checks import BOOLEAN, POSITIVE_INTEGER, one_of
from yafs_safetail.settings.declare import check_config, same_as, setting
from yafs_safetail.settings.experiment import FailuresAndPower, LearnerOverrides, Task

if TYPE_CHECKING:
    from yafs_safetail.contention.world import ContentionWorld
    from yafs_safetail.methods.registry import UserMethod

#: Every fixed method of the load sweep (the SafeTails are added unless left out).
DEFAULT_SWEEP_METHODS: tuple[str, ...] = (
    "Oracle", "Rand-1", "Rand-2", "MinLoad-1", "MinLoad-2", "MinProp-1", "MinProp-2", "Hedge", "Tied",
)
#: Every fixed method of the failure sweep: the x = 3 baselines too, since a third copy is what
#: survives two servers down at once.
DEFAULT_FAILURE_METHODS: tuple[str, ...] = (
    "Oracle", "Rand-1", "Rand-2", "Rand-3", "MinLoad-1", "MinLoad-2", "MinLoad-3",
    "MinProp-1", "MinProp-2", "MinProp-3", "Hedge", "Tied",
)
#: Every sweep's world unless its options say otherwise (the commands' defaults): 50 users, a full
#: server queues, no background tenants; the rest is ContentionConfig's own (cancel on reply,
#: shared links, the paper's topology).
SWEEP_WORLD = ContentionConfig(users=50, queue=True, background=False)
#: Test requests per point (load or failure level) at steps scale 1.
TEST_REQUESTS = 20_000
#: What every point's table ends with: each method's figures and its training budget.
#: (No wall times: the same seed must give the same file.)
_ROW_COLUMNS: tuple[str, ...] = (*SUMMARY_COLUMNS, "train_requests")
#: The load sweep's sweep.csv columns, in order.
SWEEP_COLUMNS: tuple[str, ...] = ("load", "offered_load", *_ROW_COLUMNS)
#: The failure sweep's columns, in order (failure_sweep.csv, and each level's sweep.csv).
FAILURE_SWEEP_COLUMNS: tuple[str, ...] = ("failure_level", "load", "offered_load", *_ROW_COLUMNS)
#: The failure sweep's offered load unless told: the load sweep's lowest, the one load at which
#: Oracle's five copies per request leave its queues stable (they grow without bound from 0.3 on,
#: docs/contention.md), so that a lost request measures failures, not Oracle's own overload.
DEFAULT_FAILURE_LOAD = 0.1


def _absolute_spec(spec: str) -> str:
    """A user's ``[NAME=]FILE.py:CLASS`` with its file's path absolute, as a point records every
    input file (a ``module:Class`` spec as it is)."""
    name, sep, target = spec.partition("=")
    if not sep or ":" in name or "/" in name:  # no NAME= prefix (as methods.registry reads it)
        name, sep, target = "", "", spec
    source, _, class_name = target.rpartition(":")
    if not (source.endswith(".py") or "/" in source or "\\" in source):
        return spec
    return f"{name}{sep}{Path(source).resolve()}:{class_name}"


def _user_methods(specs: Any) -> tuple[UserMethod, ...]:
    """The users' policies a point's settings record (each loaded again in the point's process)."""
    from yafs_safetail.methods.registry import UserMethod  # NumPy: only when a point is built

    return tuple(UserMethod(str(spec)) for spec in specs)


@dataclass(frozen=True)
class SweepAxis:
    """What a sweep varies from one point to the next.

    Attributes:
        column: the table's column holding each point's value.
        label: the logs' name for it (``load 0.5: ...``).
        folder: each point's folder prefix (``<folder>-<value>``).
        kind: each point's campaign run kind (``runs.engines.RUN_KINDS``).
    """

    column: str
    label: str
    folder: str
    kind: str


LOAD_POINT = "load_point"
FAILURE_POINT = "failure_point"
LOAD_AXIS = SweepAxis("load", "load", "load", LOAD_POINT)
FAILURE_AXIS = SweepAxis("failure_level", "failure level", "level", FAILURE_POINT)


def _scaled_steps(steps: int, scale: float) -> int:
    """``methods.safetail.presets.scaled_steps``, imported when a sweep is sized, not with the
    options (the ``methods`` package loads NumPy)."""
    from yafs_safetail.methods.safetail.presets import scaled_steps

    return scaled_steps(steps, scale)


@dataclass(frozen=True)
class ContentionSweep:
    """What every sweep shares: the contention world of every point (``base``; what the axis
    varies, ``phase`` and ``n_requests`` are set per point and phase) and the methods and
    SafeTails it runs, each field declared once with its help (``settings.declare.setting``; the
    sweep commands derive their options from them). ``objectives`` names the SafeTails it trains
    (:attr:`safetails` resolves each one's preset, dispatch and reward). The value learner has
    its own reward (``"latency-cost"``), so ``reward`` is the paper learner's and stays
    ``"paper"`` when the value learner runs alone (docs/deviations.md D13).

    A sweep is one of the subclasses, which say what the axis is (:attr:`axis`, :attr:`points`)
    and what each point's world is (:meth:`point_world`)."""

    base: ContentionConfig
    methods: tuple[str, ...] = setting(DEFAULT_SWEEP_METHODS, "fixed methods, comma-separated (default: all)",
                                       check=METHOD_NAMES)
    # A run's --method: users' own policies, each a row beside the built-in methods.
    user_methods: tuple[UserMethod, ...] = same_as(Task, "methods")
    safetail: bool = setting(True, "fixed methods only", check=BOOLEAN, flag="--no-safetail",
                             action="store_false")
    preset: str | None = setting(None, "every SafeTail's preset (default: paper for SafeTail, tuned for "
                                 "SafeTail-CA)", check=one_of(PRESET_NAMES), optional=True)
    steps_scale: float = same_as(Task, "steps_scale", help="scales SafeTail's training requests and the 20,000 "
                                 "test requests per sweep point (load or failure level)")
    reward: str = setting("paper", "the paper learner's reward: Eq. 5 (default) or Eq. 5 without case 3's free "
                          "miss with all servers (the contention world in the documentation); SafeTail-CA has its own",
                          check=one_of(("paper", "no-free-miss")))
    target: str = setting("eq4", "the target τ of SafeTail's reward: eq4 (Eq. 4, the paper) or "
                          "observed-load (its compute term at the servers' load seen at dispatch; "
                          "deviation D12 in the documentation)", check=one_of(TARGETS))
    # The run's --objective, several of them: each names one SafeTail the sweep trains.
    objectives: tuple[str, ...] = setting(
        DEFAULT_SWEEP_OBJECTIVES, "the SafeTails to train by their learners' objectives, comma-separated "
        "(default target-vector,value): target-vector (the paper's §III learner, row SafeTail), q-target "
        "(the original code's Q-style targets, row SafeTail-Q, deviation D18) and value (the same network "
        "predicting each action's latency, its copies priced at dispatch: row SafeTail-CA, deviation D13 in "
        "the documentation)", check=LEARNERS, deprecated=("--learner",))
    dispatch: str | None = setting(
        None, "how every SafeTail's subset is sent: all at once (the paper; SafeTail's default) or tied "
        "(cancelled once one copy starts running, as Tied; with the value learner at least two copies; "
        "SafeTail-CA's default)", check=one_of(SAFETAIL_DISPATCH), flag="--safetail-dispatch", optional=True)
    test_requests_per_load: int | None = setting(
        None, "test requests per sweep point (default 20,000 × --steps-scale): more decide each p99 more "
        "closely",
        check=POSITIVE_INTEGER, flag="--test-requests", optional=True)
    n_networks: int | None = same_as(
        LearnerOverrides, "n_networks", help="how many networks' predictions SafeTail-CA (the value learner) "
        f"averages (default {DEFAULT_VALUE_NETWORKS}; deviation D13 in the documentation)")

    #: What the sweep varies (each subclass's).
    axis: ClassVar[SweepAxis]

    #: What check_config raises for a bad field.
    setting_error: ClassVar[type[ValueError]] = ContentionError

    def __post_init__(self) -> None:
        check_config(self, "field")  # each field against its declaration
        n_networks = self.networks_averaged
        learners = [objective_named(name) for name in self.objectives]
        if n_networks > 1 and not any(learner.averages_networks for learner in learners):
            raise ContentionError(f"{n_networks} value networks: only the value learner averages networks")
        if all(learner.own_reward for learner in learners) and self.reward != "paper":
            rewards = ", ".join(sorted({str(learner.own_reward) for learner in learners}))
            raise ContentionError(f"reward {self.reward!r}: the {' and '.join(self.objectives)} learner has its own "
                                  f"reward ({rewards}); leave the reward at paper")

    @property
    def networks_averaged(self) -> int:
        """The networks the value learner averages (``n_networks`` resolved; 1 without a learner
        that averages networks)."""
        if self.n_networks is not None:
            return self.n_networks
        return max((objective_named(name).sweep_networks for name in self.objectives), default=1)

    @property
    def safetails(self) -> tuple[SafeTailVariant, ...]:
        """The SafeTails this sweep trains, in ``learners``' order (none with ``safetail`` off)."""
        if not self.safetail:
            return ()
        variants = []
        for name in self.objectives:
            learner = objective_named(name)
            preset = self.preset or learner.preset
            variants.append(SafeTailVariant(
                name=learner.method_name, learner=name, preset=preset, dispatch=self.dispatch or learner.dispatch,
                reward=learner.own_reward or self.reward,
                n_networks=self.networks_averaged if learner.averages_networks else 1,
                train_requests=training_requests(preset, self.base.use_case, self.steps_scale)))
        return tuple(variants)

    @property
    def test_requests(self) -> int:
        if self.test_requests_per_load is not None:
            return self.test_requests_per_load
        return _scaled_steps(TEST_REQUESTS, self.steps_scale)

    # ------------------------------------------------------------------ what each sweep says

    @property
    def points(self) -> tuple[float, ...]:
        """The axis's values, ascending."""
        raise NotImplementedError

    @property
    def columns(self) -> tuple[str, ...]:
        """The table's columns, in order."""
        raise NotImplementedError

    def point_world(self, value: float) -> ContentionConfig:
        """The test world at ``value`` (the training world: the same with phase ``"train"``)."""
        raise NotImplementedError

    def point_columns(self, value: float, world: ContentionWorld) -> dict[str, Any]:
        """The columns each row of the point ``value`` starts with (its world ``world``)."""
        raise NotImplementedError

    def point_settings(self, value: float) -> dict[str, Any]:
        """One point of the sweep as a campaign run's settings (JSON values, paths absolute)."""
        base = self.base
        conditions = base.user_conditions
        if conditions not in ("topology", "generated"):
            conditions = str(Path(conditions).resolve())
        return {
            "use_case": base.use_case, "users": base.users, "load": base.load, "seed": base.seed,
            "queue": base.queue, "cancel": base.cancel, "background": base.background, "world": base.world,
            "links": base.links,
            "topology": str(Path(base.topology).resolve()), "placement": str(Path(base.placement).resolve()),
            "user_conditions": conditions, "methods": list(self.methods), "safetail": self.safetail,
            "preset": self.preset, "steps_scale": self.steps_scale, "reward": self.reward,
            # The recorded names of the objectives and the networks ("learner", "value_networks")
            # are part of every point's run id: they stay as the first sweeps wrote them.
            "target": self.target, "learner": list(self.objectives), "dispatch": self.dispatch,
            "test_requests": self.test_requests, "value_networks": self.networks_averaged,
            **base.world_overrides(), **base.mobility_settings(),
            # Only when given, so that a sweep without them keeps its points' ids.
            **({"user_methods": [_absolute_spec(method.spec) for method in self.user_methods]}
               if self.user_methods else {}),
            **({"traces_dir": str(Path(base.traces_dir).expanduser().resolve())}
               if base.traces_dir is not None else {}),
        }

    @staticmethod
    def _shared_from_settings(settings: Mapping[str, Any]) -> dict[str, Any]:
        """The fields :meth:`point_settings` records, back from them (every sweep's)."""
        base = ContentionConfig(
            use_case=settings["use_case"], users=settings["users"], seed=settings["seed"],
            queue=settings["queue"], cancel=settings["cancel"], background=settings["background"],
            # Absent from the folders of earlier versions, whose links were read at the start.
            links=settings.get("links", "at-start"), world=settings["world"],
            topology=Path(settings["topology"]), placement=Path(settings["placement"]),
            user_conditions=settings["user_conditions"],
            traces_dir=Path(settings["traces_dir"]) if settings.get("traces_dir") else None,
        ).with_world_overrides(settings).with_mobility(settings)
        # One learner's name in the folders of earlier versions, which trained one SafeTail.
        learners = settings["learner"]
        return dict(base=base, methods=tuple(settings["methods"]), safetail=settings["safetail"],
                    preset=settings["preset"], steps_scale=settings["steps_scale"], reward=settings["reward"],
                    target=settings["target"],
                    objectives=(learners,) if isinstance(learners, str) else tuple(learners),
                    dispatch=settings["dispatch"], user_methods=_user_methods(settings.get("user_methods", ())),
                    # Absent from the folders of earlier versions, where it followed steps_scale.
                    test_requests_per_load=settings.get("test_requests"),
                    n_networks=settings.get("value_networks", 1))


@dataclass(frozen=True)
class SweepConfig(ContentionSweep):
    """A load sweep: every method at each offered load in ``loads`` (``experiments/load_sweep.py``)."""

    loads: tuple[float, ...] = setting((0.1, 0.3, 0.5, 0.7, 0.9),
                                       "offered loads, comma-separated (default 0.1,0.3,0.5,0.7,0.9)",
                                       check=LOADS)

    axis: ClassVar[SweepAxis] = LOAD_AXIS

    @property
    def points(self) -> tuple[float, ...]:
        return self.loads

    @property
    def columns(self) -> tuple[str, ...]:
        return SWEEP_COLUMNS

    def point_world(self, value: float) -> ContentionConfig:
        return replace(self.base, load=value, rate_per_user_hz=None, phase="test", n_requests=self.test_requests)

    def point_columns(self, value: float, world: ContentionWorld) -> dict[str, Any]:
        return {"load": value, "offered_load": world.offered_load()}

    def point_settings(self, value: float) -> dict[str, Any]:
        return {**super().point_settings(value), "load": value}

    @classmethod
    def from_point_settings(cls, settings: Mapping[str, Any]) -> SweepConfig:
        """The one-load sweep a campaign run's settings describe."""
        return cls(**cls._shared_from_settings(settings), loads=(float(settings["load"]),))


@dataclass(frozen=True)
class FailureSweepConfig(ContentionSweep):
    """A failure sweep (issue 31): every method at one offered load (``load``) as each server's
    stationary probability of being down rises through ``failure_levels`` (random failures,
    exponential up and down times with mean repair ``mttr_s``; ``edge.failures``). Level 0 is
    the world without failures (and without a time-out)."""

    methods: tuple[str, ...] = setting(DEFAULT_FAILURE_METHODS, "fixed methods, comma-separated (default: all)",
                                       check=METHOD_NAMES)
    failure_levels: tuple[float, ...] = setting(
        (0.0, 0.05, 0.1, 0.2, 0.3), "each server's stationary probability of being down, comma-separated, "
        "one sweep point each (default 0,0.05,0.1,0.2,0.3)", check=FAILURE_LEVELS)
    load: float = setting(DEFAULT_FAILURE_LOAD, f"the offered load at every level (default {DEFAULT_FAILURE_LOAD:g}: the one "
                          "load of the load sweep at which Oracle's queues are stable)", check=ONE_LOAD)
    # A run's --failure-mttr-s, under the name a sweep point's settings have always recorded.
    mttr_s: float = same_as(
        FailuresAndPower, "failure_mttr_s", default=DEFAULT_MTTR_S, optional=False, flag="--failure-mttr-s",
        deprecated=("--mttr-s",), help=f"each server's mean time to repair in seconds (default {DEFAULT_MTTR_S:g}; "
        "its mean time to failure follows from the level)")
    timeout_s: float | None = same_as(
        FailuresAndPower, "timeout_s", help="how long a user waits for a reply before the on-device fallback "
        "(default: the world's worst-case latency of a live uncontended copy)")

    axis: ClassVar[SweepAxis] = FAILURE_AXIS

    @property
    def points(self) -> tuple[float, ...]:
        return tuple(sorted(self.failure_levels))

    @property
    def columns(self) -> tuple[str, ...]:
        return FAILURE_SWEEP_COLUMNS

    def failures(self, level: float) -> FailureSettings:
        """The failure model at ``level`` (0: none)."""
        return FailureSettings.for_unavailability(level, mttr_s=self.mttr_s, timeout_s=self.timeout_s)

    def point_world(self, value: float) -> ContentionConfig:
        return replace(self.base, load=self.load, rate_per_user_hz=None, failures=self.failures(value),
                       phase="test", n_requests=self.test_requests)

    def point_columns(self, value: float, world: ContentionWorld) -> dict[str, Any]:
        return {"failure_level": value, "load": self.load, "offered_load": world.offered_load()}

    def point_settings(self, value: float) -> dict[str, Any]:
        return {**super().point_settings(value), "load": self.load, "failure_level": value,
                "mttr_s": self.mttr_s, "timeout_s": self.timeout_s}

    @classmethod
    def from_point_settings(cls, settings: Mapping[str, Any]) -> FailureSweepConfig:
        """The one-level sweep a campaign run's settings describe."""
        return cls(**cls._shared_from_settings(settings), failure_levels=(float(settings["failure_level"]),),
                   load=float(settings["load"]), mttr_s=float(settings["mttr_s"]), timeout_s=settings["timeout_s"])


#: Each point kind's configuration (a campaign run's ``kind`` -> the sweep it is one point of).
POINT_KINDS: dict[str, type[SweepConfig] | type[FailureSweepConfig]] = {
    LOAD_POINT: SweepConfig, FAILURE_POINT: FailureSweepConfig}

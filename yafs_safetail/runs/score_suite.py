"""The scoring suite: one policy in every world the project has, as one campaign.

``yafs-safetail score --method FILE.py:CLASS`` runs the policy beside SafeTail, Oracle, the
fixed baselines and the strongest simple policy (:data:`LEAST_LOADED`, the two least-loaded
servers of all) in eight scenarios (:data:`SCENARIOS`): the paper's three use cases, the
contention world at a low, a middle and a high load, servers that fail, and a user who walks.
Each (scenario, seed) is one campaign run (``runs.campaign``: cached by run id, resumable after
a kill, on every core or on Ray), made by the machinery the single commands use: a run of the
run command (kind ``experiment``) or a point of a load or failure sweep that keeps its test
requests one by one (``runs.sweep_points.PER_REQUEST``), so that the report can pair them.

A profile (:data:`PROFILES`) says how big: ``quick`` answers in minutes on two cores, ``full``
runs the paper's budgets over three seeds. ``results.score_report`` reads the folders.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from typing import TYPE_CHECKING, Any

from yafs_safetail.defaults import CAMPUS_TOPOLOGY, MOBILITY_SPEEDS_MPS
from yafs_safetail.runs.sweep_config import (
    DEFAULT_FAILURE_LOAD,
    SWEEP_WORLD,
    ContentionSweep,
    FailureSweepConfig,
    SweepConfig,
)
from yafs_safetail.settings.checks import one_of
from yafs_safetail.settings.declare import setting

if TYPE_CHECKING:
    from yafs_safetail.runs.grid import RunSpec

# Light at import (the command's --help lists the profiles and scenarios): the campaign's
# machinery, with NumPy behind it, is imported where the runs are made.

#: The strongest simple policy (docs/results.md, "Against the strongest simple policy"): each
#: request to the two servers with the fewest active users among all, as a user's policy would
#: be given, so that it runs in both worlds whatever the baseline reading.
LEAST_LOADED = "LeastLoaded-2=yafs_safetail.methods.baselines:LeastLoadedTwo"
LEAST_LOADED_NAME = "LeastLoaded-2"

#: The suite's kinds of scenario: a run of the paper's world, or one contention sweep point.
PAPER_WORLD, LOAD, FAILURES = "paper world", "load", "failures"


@dataclass(frozen=True)
class Scenario:
    """One place the policy is scored.

    Attributes:
        name: its folder and its row in the report.
        title: what it is, in plain words.
        world: :data:`PAPER_WORLD`, :data:`LOAD` or :data:`FAILURES`.
        use_case: the use case it serves.
        load: the contention world's offered load (sweep points only).
        walking: the user walks around the campus (the paper's world only).
    """

    name: str
    title: str
    world: str
    use_case: int = 1
    load: float | None = None
    walking: bool = False


#: Each server's stationary probability of being down in the failure scenario.
FAILURE_LEVEL = 0.2

SCENARIOS: tuple[Scenario, ...] = (
    Scenario("uc1", "the paper's world, use case 1", PAPER_WORLD, use_case=1),
    Scenario("uc2", "the paper's world, use case 2", PAPER_WORLD, use_case=2),
    Scenario("uc3", "the paper's world, use case 3", PAPER_WORLD, use_case=3),
    Scenario("load-low", "many users sharing the servers, offered load 0.1", LOAD, load=0.1),
    Scenario("load-mid", "many users sharing the servers, offered load 0.5", LOAD, load=0.5),
    Scenario("load-high", "many users sharing the servers, offered load 0.9", LOAD, load=0.9),
    Scenario("failures", f"many users, each server down {FAILURE_LEVEL:.0%} of the time, offered load "
             f"{DEFAULT_FAILURE_LOAD:g}", FAILURES, load=DEFAULT_FAILURE_LOAD),
    Scenario("walking", "the paper's world, use case 1, the user walking on the campus "
             f"({MOBILITY_SPEEDS_MPS['walking'][0]:g}-{MOBILITY_SPEEDS_MPS['walking'][1]:g} m/s)",
             PAPER_WORLD, use_case=1, walking=True),
)


@dataclass(frozen=True)
class ScoreProfile:
    """How big the suite is (recorded in the report, so anyone can rerun it).

    Attributes:
        name: ``quick`` or ``full``.
        seeds: every scenario's seeds.
        steps_scale: the training budget of SafeTail (and of a policy that learns) in the
            paper's world, as a fraction of the preset's.
        users: users sharing the servers in the contention world.
        contention_steps_scale: the training budget in the contention world, as a fraction.
        test_requests: test requests per contention scenario and seed (None: the sweeps'
            default, 20,000 × the budget).
    """

    name: str
    seeds: tuple[int, ...]
    steps_scale: float
    users: int
    contention_steps_scale: float
    test_requests: int | None


PROFILES: dict[str, ScoreProfile] = {
    "quick": ScoreProfile("quick", seeds=(0,), steps_scale=0.25, users=20, contention_steps_scale=0.1,
                          test_requests=5000),
    "full": ScoreProfile("full", seeds=(0, 1, 2), steps_scale=1.0, users=SWEEP_WORLD.users,
                         contention_steps_scale=1.0, test_requests=None),
}


@dataclass(frozen=True)
class ScoreSuite:
    """The suite's own settings beside a run's (each declared once; the command's options come
    from here)."""

    profile: str = setting("quick", "quick (default): a quarter of the paper's training budget, one seed, "
                           "20 users, minutes on two cores; full: the paper's budgets, seeds 0,1,2, 50 users",
                           check=one_of(tuple(PROFILES)))
    scenario: str = setting(SCENARIOS[0].name, "a scenario of the suite",
                            check=one_of(tuple(scenario.name for scenario in SCENARIOS)))


def profile_settings(profile: ScoreProfile) -> dict[str, Any]:
    """The profile as the report records it."""
    return {**asdict(profile), "seeds": list(profile.seeds)}


#: Where a scenario's run of one seed goes, below the suite's folder.
RUN_FOLDER = "{scenario}/seed{seed}"


def run_folder(scenario: Scenario, seed: int) -> str:
    """:data:`RUN_FOLDER` for one scenario and seed."""
    return RUN_FOLDER.format(scenario=scenario.name, seed=seed)


def _paper_world_specs(scenario: Scenario, methods: list[str], profile: ScoreProfile) -> list[RunSpec]:
    from yafs_safetail.runs.grid import expand

    base: dict[str, Any] = {"use_case": scenario.use_case, "steps_scale": profile.steps_scale, "methods": methods,
                            "figures": False}
    if scenario.walking:
        base.update(topology=str(CAMPUS_TOPOLOGY), mobility="random-waypoint",
                    speed_mps=list(MOBILITY_SPEEDS_MPS["walking"]))
    return expand(base, {"seed": list(profile.seeds)}, name=RUN_FOLDER.replace("{scenario}", scenario.name),
                  source="score_policy.py")


def _sweep_config(scenario: Scenario, methods: list[str], profile: ScoreProfile, seed: int) -> ContentionSweep:
    from yafs_safetail.methods.registry import UserMethod

    base = replace(SWEEP_WORLD, use_case=scenario.use_case, users=profile.users, seed=seed)
    shared: dict[str, Any] = {"base": base, "steps_scale": profile.contention_steps_scale,
                              "test_requests_per_load": profile.test_requests,
                              "user_methods": tuple(UserMethod(spec) for spec in methods)}
    assert scenario.load is not None
    if scenario.world == FAILURES:
        return FailureSweepConfig(**shared, failure_levels=(FAILURE_LEVEL,), load=scenario.load)
    return SweepConfig(**shared, loads=(scenario.load,))


def _sweep_specs(scenario: Scenario, methods: list[str], profile: ScoreProfile) -> list[RunSpec]:
    from yafs_safetail.runs.grid import RunSpec
    from yafs_safetail.runs.sweep_points import PER_REQUEST, point_run_id

    specs = []
    for seed in profile.seeds:
        config = _sweep_config(scenario, methods, profile, seed)
        value = config.points[0]
        settings = {**config.point_settings(value), PER_REQUEST: True}
        specs.append(RunSpec(name=run_folder(scenario, seed), run_id=point_run_id(settings, config.axis.kind),
                             settings=settings, kind=config.axis.kind))
    return specs


def suite_specs(method: str, profile: ScoreProfile,
                scenarios: tuple[Scenario, ...] = SCENARIOS) -> list[RunSpec]:
    """Every run of the suite for the policy ``method`` (``[NAME=]FILE.py:CLASS`` or
    ``module:CLASS``), scenario by scenario, seeds ascending."""
    methods = [method, LEAST_LOADED]
    specs: list[RunSpec] = []
    for scenario in scenarios:
        if scenario.world == PAPER_WORLD:
            specs += _paper_world_specs(scenario, methods, profile)
        else:
            specs += _sweep_specs(scenario, methods, profile)
    return specs


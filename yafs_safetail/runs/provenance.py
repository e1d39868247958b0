"""What a run's ``run.json`` records: its settings, its world, and what each learner adds."""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yafs_safetail
from yafs_safetail import results, versions
from yafs_safetail.edge.scenario import REPOSITORY
from yafs_safetail.edge.signal import DEFAULT_SIGNAL_RULE
from yafs_safetail.edge.traces import DEFAULT_TRACE_DIR, same_traces
from yafs_safetail.methods.learning import LearningPolicy
from yafs_safetail.methods.policy import PolicyError
from yafs_safetail.settings.declare import changed_settings

if TYPE_CHECKING:
    from yafs_safetail.edge.phase_world import EdgeWorld
    from yafs_safetail.runs.experiment import ExperimentConfig, _Inputs

#: ``run.json`` keys of the run itself that a learner's fields replace: the run's preset and β
#: are those of the learner's settings (SafeTail's, which ``--policy`` reads from its file).
LEARNER_SET_KEYS = ("preset", "beta")
#: Settings every title names already (use case, preset, seed) or the run records apart (its
#: budget, its learning rate): ``changed_settings`` leaves them out, and the output's own.
TITLED_SETTINGS = ("use_case", "preset", "seed", "steps_scale", "learning_rate")


def titled_settings() -> tuple[str, ...]:
    """The settings titles never list: :data:`TITLED_SETTINGS` and what the output is (figures,
    formats, folder: they change which files exist, not what any says)."""
    from yafs_safetail.settings.experiment import Output

    return (*TITLED_SETTINGS, *(item.name for item in dataclasses.fields(Output)))


def recorded_path(path: Path) -> str:
    """A file's path as run.json records it: relative to the project when inside it."""
    return os.path.relpath(path, REPOSITORY) if path.resolve().is_relative_to(REPOSITORY) else str(path)


def own_traces(config: ExperimentConfig) -> Path | None:
    """The traces folder ``--traces`` named, or None when the run read the packaged one."""
    from yafs_safetail.worlds.recipe import traces_folder

    folder = traces_folder(config)
    return None if folder.resolve() == DEFAULT_TRACE_DIR.resolve() else folder


def learners_fields(learners: Sequence[LearningPolicy]) -> dict[str, Any]:
    """Every learner's :meth:`~LearningPolicy.run_json_fields`, merged.

    Raises:
        PolicyError: two learners give the same key.
    """
    merged: dict[str, Any] = {}
    owners: dict[str, str] = {}
    for policy in learners:
        for key, value in policy.run_json_fields().items():
            if key in owners:
                raise PolicyError(f"{policy.name}: run_json_fields() gives {key!r}, which "
                                  f"{owners[key]} gives too")
            owners[key] = policy.name
            merged[key] = value
    return merged


def failures_and_energy(world: EdgeWorld) -> dict[str, Any]:
    """``run.json``'s ``failures`` and ``energy`` entries: the settings the world was drawn with
    (the time-out as the user waits it, None when it never gives up) and the power models."""
    failures = world.failures
    down_file = failures.down_file
    return {
        "failures": {
            "enabled": failures.enabled,
            "mttf_s": failures.mttf_s,
            "mttr_s": failures.mttr_s,
            "unavailability": failures.unavailability,
            "down_file": None if down_file is None else recorded_path(down_file),
            "timeout_s": None if math.isinf(world.timeout_s) else world.timeout_s,
        },
        "energy": {
            "server": {**dataclasses.asdict(world.energy.server),
                       "per_process_w": world.energy.server.per_process_w},
            "radio": dataclasses.asdict(world.energy.radio),
        },
    }


def mobility_fields(config: ExperimentConfig, world: EdgeWorld) -> dict[str, Any]:
    """``run.json``'s ``mobility`` entry when the user moves (none otherwise, so that a run at
    rest writes what it always did): the model, the route file or random waypoint's speeds
    and pause, and the distance-to-condition rule's edges."""
    movement = world.movement
    if movement is None:
        return {}
    entry: dict[str, Any] = {"model": config.mobility}
    if config.route is not None:
        entry["route"] = recorded_path(Path(config.route))
    else:
        entry.update(speed_mps=[float(v) for v in config.speed_mps], pause_s=float(config.pause_s))
    entry["condition_edges_m"] = [round(edge, 3) for edge in DEFAULT_SIGNAL_RULE.distance_edges_m()]
    return {"mobility": entry}


def run_metadata(config: ExperimentConfig, inputs: _Inputs, learners: Sequence[LearningPolicy],
                 methods: list[str]) -> results.RunMetadata:
    """The run's ``run.json`` (its learners trained, every method named in ``methods``).

    Raises:
        PolicyError: a learner's key is one the run records itself.
    """
    test_world = inputs.test_world
    learned = learners_fields(learners)
    traces = own_traces(config)
    # A copy of the packaged traces is the packaged traces: titles name only traces of one's own.
    untitled = (*titled_settings(), *(("traces_dir",) if traces is None or same_traces(traces) else ()))
    extra: dict[str, Any] = {
        "steps_scale": config.steps_scale,
        "step_interval_s": config.step_interval_s,
        "episode_steps": inputs.learner_config.episode_steps,
        "fallback_latency_s": test_world.fallback_latency_s,
        "nu": test_world.nu,
        "world": test_world.settings.to_dict(),
        **failures_and_energy(test_world),
        **mobility_fields(config, test_world),
        results.PLACEMENT_KEY: recorded_path(Path(config.placement)),
        # Only when --traces names another folder, so that every other run writes what it did.
        **({results.TRACES_KEY: recorded_path(traces)} if traces is not None else {}),
        # The libraries' versions, and a note when they are not the lock's (summary.md says it).
        **versions.run_json_fields(),
        # Only when set, as learning_rate_override: summary.md scores no closeness to the
        # paper in a world the run's options changed.
        **({results.WORLD_OVERRIDES_KEY: dict(inputs.world_overrides)}
           if inputs.world_overrides else {}),
        # Only when set, so that a run with the preset's own rate is what it always was.
        **({results.LEARNING_RATE_OVERRIDE_KEY: float(config.learning_rate)}
           if config.learning_rate is not None else {}),
        **({"campaign_run_id": config.run_id} if config.run_id else {}),
        # Only when any is set: what the titles of its figures and summary.md add.
        **({results.CHANGED_SETTINGS_KEY: list(changed)} if (changed := changed_settings(
            config, skip=untitled)) else {}),
    }
    own = [key for key in learned
           if key in extra or (key in results.RUN_JSON_KEYS and key not in LEARNER_SET_KEYS)]
    if own:
        raise PolicyError(f"{_owner_of(learners, own[0])}: run_json_fields() gives {own[0]!r}, "
                          "which run.json records of the run itself")
    return results.RunMetadata(
        use_case=inputs.use_case.number,
        use_case_name=inputs.use_case.description,
        preset=learned.pop("preset", config.preset),
        seed=config.seed,
        n_servers=inputs.scenario.n_servers,
        beta=learned.pop("beta", inputs.learner_config.beta),
        train_steps=0 if inputs.train_world is None else inputs.learner_config.train_steps,
        test_steps=test_world.n_steps,
        topology=recorded_path(Path(config.topology)),
        methods=methods,
        package_version=yafs_safetail.__version__,
        command=config.command,
        extra={**extra, **learned},
    )


def _owner_of(learners: Sequence[LearningPolicy], key: str) -> str:
    """The name of the learner whose run.json fields hold ``key``."""
    return next(policy.name for policy in learners if key in policy.run_json_fields())

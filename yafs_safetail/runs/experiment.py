"""One SafeTail experiment: train SafeTail, then test it and every other method on the same requests.

The flow reads top to bottom in :func:`run_experiment`:

1. check the configuration and every input (use case, preset, seed, step scale, redundancy
   levels, topology and placement, a saved policy, users' policies) before TensorFlow is
   imported or the output is touched;
2. draw the two phases' worlds (common random numbers: every method of a phase replays the
   same requests, trace rows and per-server draws);
3. start the other methods' test phase in worker processes (``workers - 1`` of them);
4. build the learner (or load a saved policy) and train SafeTail for the preset's training
   steps (ε-greedy, a training round every κ tuples), then test it greedily;
5. collect every method's rows and write the results folder under a temporary name, then
   rename it into place, so a failed run never leaves half-written results and never destroys
   an earlier run's folder.

Each step after the checks is a logged phase (``logs.Phase``: start, every 10% of a long
phase, end with its wall time), written to stderr as the entry point configured it and, with
the configuration and the command, into the folder's ``run.log``.

Every method runs its own YAFS-compatible simulation (``sim.runner``) with the edge model as its
delay hooks and writes the YAFS result CSVs under ``yafs/``.
"""

from __future__ import annotations

import dataclasses
import importlib
import logging
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

import yafs_safetail
from yafs_safetail import results
from yafs_safetail.edge.scenario import DEFAULT_TOPOLOGY as DEFAULT_TOPOLOGY  # (re-exported)
from yafs_safetail.edge.scenario import REPOSITORY, EdgeScenario
from yafs_safetail.edge.usecases import UseCase
from yafs_safetail.edge.world import EdgeWorld
from yafs_safetail.logs import RUN_LOG_FILE, Phase, run_log
from yafs_safetail.methods.registry import SAFETAIL, baseline_names, sort_methods
from yafs_safetail.methods.safetail.persistence import read_policy_sidecar
from yafs_safetail.methods.safetail.presets import LearnerConfig
from yafs_safetail.methods.safetail.spaces import MAX_SERVERS, StateScales, state_dim
from yafs_safetail.record import records_frame
from yafs_safetail.runs.budget import check_budget
from yafs_safetail.runs.checkpoint import (
    CheckpointError,
    TrainingCheckpoint,
    check_checkpoint_place,
    checkpoint_folder,
    discard_checkpoint,
    has_checkpoint,
    read_checkpoint,
    write_checkpoint,
)
from yafs_safetail.runs.config import ExperimentConfig, ExperimentError  # (also imported from here)
from yafs_safetail.runs.output import StagedOutput
from yafs_safetail.runs.workers import MethodsJob, method_rng, start_workers
from yafs_safetail.runs.world_recipe import TEST, TRAIN, world_recipe
from yafs_safetail.sim.runner import Simulation, simulate

POLICY_FILE = "policy.keras"
YAFS_DIR = "yafs"

log = logging.getLogger(__name__)


#: Training requests between two chances to checkpoint (and two progress-bar updates).
CHECKPOINT_CHUNK_STEPS = 100


@dataclass
class ExperimentReport:
    """What a finished run produced and where the time went.

    ``timings_s`` (seconds of wall time): ``setup`` (checks, traces, worlds, learner; includes
    ``tf_import``), ``simulation`` (this process's simulations without the learner's share),
    ``decisions`` and ``training`` (SafeTail's learner), ``baselines_in_workers`` (the
    longest worker's wall time, overlapping the above; 0 with one worker),
    ``waiting_for_workers`` (after SafeTail's test), ``writing`` (results files and policy),
    ``plotting`` and ``total``.
    """

    out_dir: Path
    summary: pd.DataFrame
    timings_s: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class _Inputs:
    """What the checks produce: everything the run needs, nothing written yet."""

    use_case: UseCase
    learner_config: LearnerConfig
    scenario: EdgeScenario
    train_world: EdgeWorld | None
    test_world: EdgeWorld
    world_overrides: dict[str, Any] = field(default_factory=dict)


def _check(config: ExperimentConfig) -> _Inputs:
    """Check the configuration and inputs, and draw the worlds (steps 1 and 2)."""
    if config.learning_rate is not None and config.policy is not None:
        raise ExperimentError("--learning-rate: nothing trains with --policy; give one or the other")
    if not config.redundancy_levels:
        raise ExperimentError("--redundancy: give at least one level x")
    recipe = world_recipe(config)  # every field's own check, then the traces and the scenario
    use_case, scenario = recipe.use_case, recipe.scenario
    names = [m.name for m in config.methods]
    if len(set(names)) != len(names):
        raise ExperimentError(f"--method: two methods are named {sorted(n for n in names if names.count(n) > 1)[0]!r}")
    if scenario.n_servers > MAX_SERVERS:
        raise ExperimentError(
            f"{config.topology}: entity: {scenario.n_servers} edge servers; SafeTail supports 1 to "
            f"{MAX_SERVERS} (its network has one output per subset, 2^n - 1; paper assumption iii)")
    for x in config.redundancy_levels:
        if isinstance(x, bool) or not isinstance(x, int) or not 1 <= x <= scenario.n_servers:
            raise ExperimentError(
                f"--redundancy: x={x!r} must be an integer in 1..{scenario.n_servers} "
                f"(the servers in {config.topology})"
            )
    for method in config.methods:  # a policy that cannot be built fails here, before any run
        method.make(scenario.n_servers, method_rng(config.seed, method.name))
    if config.policy is not None:
        _check_saved_policy(config.policy, use_case, scenario)
    n_methods = 1 + len(baseline_names(config.redundancy_levels)) + len(config.methods)
    check_budget(config, recipe.full_preset, recipe.learner, recipe.test_steps, n_methods)
    return _Inputs(
        use_case=use_case,
        learner_config=recipe.learner,
        scenario=scenario,
        train_world=recipe.make_world(TRAIN, config.seed) if config.policy is None else None,
        test_world=recipe.make_world(TEST, config.seed),
        world_overrides=recipe.overrides,
    )


def _check_saved_policy(path: Path, use_case: UseCase, scenario: EdgeScenario) -> None:
    """A saved policy must exist and fit the topology and use case (read before TensorFlow)."""
    if not Path(path).is_file():
        raise ExperimentError(f"--policy {path}: no such file")
    saved = read_policy_sidecar(path)
    trained_for = saved.get("config", {}).get("use_case")
    if trained_for is not None and int(trained_for) != use_case.number:
        raise ExperimentError(f"--policy {path}: trained for use case {trained_for}, not {use_case.number}")
    expected_dim = state_dim(scenario.n_servers, len(use_case.gamma_columns),
                             len(scenario.user_location))
    if int(saved["n_servers"]) != scenario.n_servers or int(saved["state_dim"]) != expected_dim:
        raise ExperimentError(
            f"--policy {path}: trained for {saved['n_servers']} servers and "
            f"{saved['state_dim']} state entries; use case {use_case.number} on "
            f"{scenario.topology.source} has {scenario.n_servers} servers and {expected_dim}"
        )


def run_experiment(config: ExperimentConfig) -> ExperimentReport:
    """Run one use case end to end and write its results folder (see docs/results.md).

    Raises:
        ValueError: a bad setting or input file (one-line message naming it).
        OSError: the output folder cannot be written.
    """
    timings = {"setup": 0.0, "tf_import": 0.0, "simulation": 0.0, "decisions": 0.0, "training": 0.0,
               "baselines_in_workers": 0.0, "waiting_for_workers": 0.0, "writing": 0.0, "plotting": 0.0}
    started = time.perf_counter()
    output = StagedOutput(Path(config.out_dir), config.overwrite)  # checks the target first
    inputs = _check(config)
    checkpoints = _Checkpoints.for_run(config, inputs, output.target)
    checked_s = time.perf_counter() - started
    # Nothing is logged before here: bad input stays one line on stderr, even with --verbose.
    try:
        with output as staging:
            with run_log(staging / RUN_LOG_FILE):
                _log_start(config, inputs, staging, checked_s)
                summary = _run_into(staging, config, inputs, timings, started, checkpoints)
                log.debug("time (s): %s", ", ".join(f"{part} {seconds:.2f}" for part, seconds in timings.items()))
                log.info("UC%d run: done (%.1f s)", inputs.use_case.number, timings["total"])
            # The results are complete: nothing left to resume. The checkpoint goes before the
            # results are renamed into place (the lock is still ours, so it is no other run's
            # checkpoint), so a run killed at any moment never leaves a finished folder beside
            # a checkpoint, which a campaign, skipping the finished run, would never remove.
            if checkpoints is not None:
                discard_checkpoint(output.target)
            output.publish()
    except BaseException as error:
        if checkpoints is not None and checkpoints.written:
            error.add_note(f"training checkpoint kept in {checkpoint_folder(output.target)}: "
                           "the same command with --resume continues it")
        raise
    return ExperimentReport(out_dir=config.out_dir, summary=summary, timings_s=timings)


def _log_start(config: ExperimentConfig, inputs: _Inputs, staging: Path, checked_s: float) -> None:
    """What run.log opens with: the command, the version, and what this run is."""
    use_case = inputs.use_case
    training = ("no training (saved policy)" if inputs.train_world is None
                else f"{inputs.train_world.n_steps} training requests")
    n_methods = 1 + len(baseline_names(config.redundancy_levels)) + len(config.methods)
    log.info("yafs-safetail %s: %s", yafs_safetail.__version__, config.command or "(run from Python)")
    log.info("UC%d %s, preset %s, seed %d: %s, %d test requests per method, %d methods, %d process(es)",
             use_case.number, use_case.description, config.preset, config.seed, training,
             inputs.test_world.n_steps, n_methods, config.workers)
    settings = {f.name: getattr(config, f.name) for f in dataclasses.fields(config) if f.name != "world"}
    log.debug("configuration: %s", ", ".join(f"{name}={value!s}" for name, value in settings.items()))
    log.debug("world: %s", inputs.test_world.settings.to_dict())
    log.debug("checks and worlds: %.2f s", checked_s)
    log.debug("writing into %s, renamed to %s when the run succeeds", staging, config.out_dir)


@dataclass
class _Checkpoints:
    """A run's training checkpoints: the one it resumes from, and when to write the next."""

    target: Path
    run_id: str
    every_s: float
    resume_from: TrainingCheckpoint | None
    last_written: float = field(default_factory=time.perf_counter)
    written: bool = False

    @classmethod
    def for_run(cls, config: ExperimentConfig, inputs: _Inputs, target: Path) -> _Checkpoints | None:
        """None when the run does not train or checkpoints are off. Reads the checkpoint to
        resume from (CheckpointError before anything runs if it does not fit)."""
        # A resumed training phase cannot append to the YAFS CSVs of the interrupted one.
        trains = inputs.train_world is not None and not config.write_yafs_csv
        if config.resume and not trains:
            raise CheckpointError("--resume: only a training run with no --yafs-csv and no "
                                  "--policy keeps checkpoints")
        if not trains or config.checkpoint_every_s is None:
            return None
        from yafs_safetail.runs.grid import config_run_id

        check_checkpoint_place(target)
        run_id = config_run_id(config)
        resume_from = read_checkpoint(target, run_id) if config.resume else None
        if resume_from is None and has_checkpoint(target):
            log.warning("%s holds an interrupted run's checkpoint; this run starts over and "
                        "replaces it (--resume continues it)", checkpoint_folder(target))
        return cls(target, run_id, float(config.checkpoint_every_s), resume_from,
                   written=resume_from is not None)

    def due(self) -> bool:
        """Whether the next chance should write a checkpoint (``every_s`` has passed)."""
        return time.perf_counter() - self.last_written >= self.every_s

    def write(self, policy: Any, next_step: int, records: list[Any], force: bool = False) -> None:
        if not (force or self.due()):
            return
        # Set first: a kill during the write leaves the previous checkpoint or this one, both
        # of which --resume continues.
        self.written = True
        write_checkpoint(self.target, TrainingCheckpoint(
            run_id=self.run_id, next_step=next_step, learner_state=policy.learner.training_state(),
            records=list(records), decision_time_s=policy.decision_time_s,
            training_time_s=policy.training_time_s))
        self.last_written = time.perf_counter()


def _run_into(staging: Path, config: ExperimentConfig, inputs: _Inputs,
              timings: dict[str, float], started: float,
              checkpoints: _Checkpoints | None) -> pd.DataFrame:
    """Steps 3 to 5 into the staging folder; returns the summary."""
    yafs_dir = staging / YAFS_DIR if config.write_yafs_csv else None
    if yafs_dir is not None:
        yafs_dir.mkdir()
    prefix = f"UC{inputs.use_case.number}"
    job = MethodsJob(
        names=tuple(baseline_names(config.redundancy_levels)), user_methods=config.methods,
        seed=config.seed, world=inputs.test_world, step_interval_s=config.step_interval_s,
        yafs_dir=yafs_dir, episode_steps=inputs.learner_config.episode_steps,
        progress_label=f"{prefix} other methods test", bar=config.progress,
    )
    workers = start_workers(job, config.workers)
    try:
        learner, safetail_frames = _safetail(config, inputs, yafs_dir, timings, started, checkpoints)
        other_frames = _other_methods(job, workers, timings)
    finally:
        for worker in workers:
            worker.stop()
    requests = pd.concat([*safetail_frames, *other_frames], ignore_index=True)
    run = _run_metadata(config, inputs, learner, sort_methods([SAFETAIL, *job.method_names]))
    t0 = time.perf_counter()
    with Phase(f"{prefix} writing results", logger=log):
        summary = results.write_results(staging, requests, run)
        learner.save(staging / POLICY_FILE)
    timings["writing"] = time.perf_counter() - t0
    if config.figures:
        from yafs_safetail.figures import draw_figures

        t0 = time.perf_counter()
        with Phase(f"{prefix} figures", logger=log):
            draw_figures(staging, requests, run)
        timings["plotting"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - started
    return summary


def _safetail(config: ExperimentConfig, inputs: _Inputs, yafs_dir: Path | None,
              timings: dict[str, float], started: float,
              checkpoints: _Checkpoints | None) -> tuple[Any, list[pd.DataFrame]]:
    """Build or load the learner; train SafeTail (unless evaluating a saved policy; from a
    checkpoint when resuming), then test it greedily. Returns the learner and SafeTail's rows
    of both phases."""
    t0 = time.perf_counter()
    scenario, use_case = inputs.scenario, inputs.use_case
    with Phase(f"UC{use_case.number} {SAFETAIL} setup (TensorFlow, the learner)", logger=log):
        from yafs_safetail.methods.safetail.learner import SafeTailLearner
        from yafs_safetail.methods.safetail.policy import SafeTailPolicy

        # The learner builds its network with Keras; importing it (and TensorFlow) takes seconds
        # the first time, so it is done here to show up as its own part of the setup.
        importlib.import_module("keras")
        timings["tf_import"] = time.perf_counter() - t0
        if config.policy is None:
            learner = SafeTailLearner(
                scenario.n_servers,
                state_dim(scenario.n_servers, len(use_case.gamma_columns), len(scenario.user_location)),
                inputs.learner_config, config.seed,
                metadata={"use_case": use_case.number, "topology": str(config.topology)},
            )
        else:
            learner = SafeTailLearner.load(config.policy, training=False)
    timings["setup"] = time.perf_counter() - started
    policy = SafeTailPolicy(scenario.n_servers, method_rng(config.seed, SAFETAIL), learner=learner,
                            scales=StateScales.for_use_case(use_case.number), training=True)
    episode_steps = inputs.learner_config.episode_steps

    def phase(world: EdgeWorld, name: str) -> pd.DataFrame:
        with Phase(f"UC{use_case.number} {SAFETAIL} {name}", world.n_steps, bar=config.progress,
                   logger=log) as progress:
            records = simulate(world, policy, config.step_interval_s,
                               None if yafs_dir is None else yafs_dir / f"{SAFETAIL}_{name}", progress)
        return records_frame(records, name, episode_steps)

    t0 = time.perf_counter()
    frames = []
    if inputs.train_world is not None:
        frames.append(records_frame(_train(config, inputs, policy, yafs_dir, checkpoints),
                                    "train", episode_steps))
        log.info("UC%d %s: training rounds %d, final ε %.4f", use_case.number, SAFETAIL,
                 learner.n_training_rounds, learner.epsilon)
    policy.training = False
    frames.append(phase(inputs.test_world, "test"))
    timings["decisions"] = policy.decision_time_s
    timings["training"] = policy.training_time_s
    # Simulation time is reported without the learner's share.
    timings["simulation"] = time.perf_counter() - t0 - policy.decision_time_s - policy.training_time_s
    return learner, frames


def _train(config: ExperimentConfig, inputs: _Inputs, policy: Any, yafs_dir: Path | None,
           checkpoints: _Checkpoints | None) -> list[Any]:
    """SafeTail's training phase, from its checkpoint when resuming; returns every record."""
    world = inputs.train_world
    assert world is not None
    path = None if yafs_dir is None else yafs_dir / f"{SAFETAIL}_train"
    with Phase(f"UC{inputs.use_case.number} {SAFETAIL} train", world.n_steps, bar=config.progress,
               logger=log) as progress:
        if checkpoints is None:
            return simulate(world, policy, config.step_interval_s, path, progress)
        earlier: list[Any] = []
        first_step = 0
        if checkpoints.resume_from is not None:
            state = checkpoints.resume_from
            policy.learner.restore_training_state(state.learner_state)
            policy.decision_time_s, policy.training_time_s = state.decision_time_s, state.training_time_s
            earlier, first_step = list(state.records), state.next_step
            log.info("UC%d %s train: resumed from the checkpoint at request %d", inputs.use_case.number,
                     SAFETAIL, first_step)
            progress.update(first_step)

        def after_chunk(simulation: Simulation) -> None:
            # Only between two requests with nothing running can a fresh simulation take over.
            # Checked before the rows are joined: most chances write nothing.
            if simulation.quiescent and checkpoints.due():
                checkpoints.write(policy, simulation.next_step, earlier + simulation.records)

        records = earlier + simulate(world, policy, config.step_interval_s, path, progress,
                                     first_step=first_step, after_chunk=after_chunk,
                                     chunk_steps=CHECKPOINT_CHUNK_STEPS)
        checkpoints.write(policy, world.n_steps, records, force=True)  # a kill while testing resumes here
        return records


def _other_methods(job: MethodsJob, workers: Sequence[Any], timings: dict[str, float]) -> list[pd.DataFrame]:
    """The other methods' test rows, in report order (run here when no worker ran them)."""
    by_name: dict[str, pd.DataFrame] = {}
    if workers:
        t0 = time.perf_counter()
        log.debug("waiting for %d worker process(es)", len(workers))
        for worker in workers:
            frames, wall_s = worker.result()
            by_name.update(zip(worker.job.method_names, frames, strict=True))
            timings["baselines_in_workers"] = max(timings["baselines_in_workers"], wall_s)
        timings["waiting_for_workers"] = time.perf_counter() - t0
    else:
        frames, wall_s = job.run()
        by_name.update(zip(job.method_names, frames, strict=True))
        timings["simulation"] += wall_s
    return [by_name[name] for name in job.method_names]


def _recorded_path(path: Path) -> str:
    """A file's path as run.json records it: relative to the project when inside it."""
    return os.path.relpath(path, REPOSITORY) if path.resolve().is_relative_to(REPOSITORY) else str(path)


def _run_metadata(config: ExperimentConfig, inputs: _Inputs, learner: Any,
                  methods: list[str]) -> results.RunMetadata:
    test_world = inputs.test_world
    topology = Path(config.topology)
    return results.RunMetadata(
        use_case=inputs.use_case.number,
        use_case_name=inputs.use_case.description,
        preset=learner.config.name,
        seed=config.seed,
        n_servers=inputs.scenario.n_servers,
        beta=learner.config.beta,
        train_steps=0 if inputs.train_world is None else inputs.learner_config.train_steps,
        test_steps=test_world.n_steps,
        topology=_recorded_path(topology),
        methods=methods,
        package_version=yafs_safetail.__version__,
        command=config.command,
        extra={
            "steps_scale": config.steps_scale,
            "step_interval_s": config.step_interval_s,
            "episode_steps": inputs.learner_config.episode_steps,
            "fallback_latency_s": test_world.fallback_latency_s,
            "nu": test_world.nu,
            "world": test_world.settings.to_dict(),
            results.PLACEMENT_KEY: _recorded_path(Path(config.placement)),
            # Only when set, as learning_rate_override: summary.md scores no closeness to the
            # paper in a world the run's options changed.
            **({results.WORLD_OVERRIDES_KEY: dict(inputs.world_overrides)}
               if inputs.world_overrides else {}),
            "learner": learner.config.to_dict(),
            "training_rounds": learner.n_training_rounds,
            "final_epsilon": learner.epsilon,
            "policy_source": str(config.policy) if config.policy else POLICY_FILE,
            # Only when set, so that a run with the preset's own rate is what it always was.
            **({results.LEARNING_RATE_OVERRIDE_KEY: float(config.learning_rate)}
               if config.learning_rate is not None else {}),
            **({"campaign_run_id": config.run_id} if config.run_id else {}),
        },
    )

"""One SafeTail experiment: train SafeTail, then test it and every other method on the same requests.

The flow reads top to bottom in :func:`run_experiment`:

1. check the configuration and every input (use case, preset, seed, step scale, redundancy
   levels, topology and placement, a saved policy, users' policies) before TensorFlow is
   imported or the output is touched;
2. draw the two phases' worlds (common random numbers: every method of a phase replays the
   same requests, trace rows and per-server draws), the test world first: each user's policy,
   built afresh, chooses the servers of its first request, so that a policy that cannot
   choose stops the run in seconds instead of after SafeTail's training;
3. start the test phase of the methods that do not learn in worker processes (``workers - 1``
   of them; ``runs.workers``);
4. build the learning methods (``runs.learners``: SafeTail, or its saved policy, and users'
   learners) and train then test each of them (``runs.phases``, ``runs.training``);
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
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

import yafs_safetail
from yafs_safetail import results
from yafs_safetail.edge.scenario import DEFAULT_TOPOLOGY as DEFAULT_TOPOLOGY  # (re-exported)
from yafs_safetail.edge.scenario import (
    REPOSITORY as REPOSITORY,  # imported from here by tests and scripts
)
from yafs_safetail.edge.scenario import EdgeScenario
from yafs_safetail.edge.usecases import UseCase
from yafs_safetail.edge.world import EdgeWorld
from yafs_safetail.logs import RUN_LOG_FILE, Phase, run_log
from yafs_safetail.methods.objectives import averages_networks, objective_names
from yafs_safetail.methods.registry import baseline_names, method_rng, sort_methods
from yafs_safetail.methods.safetail.persistence import read_policy_sidecar
from yafs_safetail.methods.safetail.presets import LearnerConfig
from yafs_safetail.methods.safetail.spaces import MAX_SERVERS, state_dim
from yafs_safetail.runs.budget import check_budget
from yafs_safetail.runs.checkpoint import checkpoint_folder, discard_checkpoint, resumable_after
from yafs_safetail.runs.figures_worker import FiguresWorker, start_figures_worker
from yafs_safetail.runs.learners import check_learners, learner_names, make_learners
from yafs_safetail.runs.output import StagedOutput
from yafs_safetail.runs.phases import LearnersJob, run_learners, run_other_methods
from yafs_safetail.runs.provenance import run_metadata
from yafs_safetail.runs.training import Checkpoints
from yafs_safetail.runs.workers import MethodsJob, MethodsWorker, start_workers
from yafs_safetail.settings.experiment import (  # (also imported from here)
    ExperimentConfig,
    ExperimentError,
)
from yafs_safetail.sim.selection import DISPATCH as SINGLE_USER_DISPATCH
from yafs_safetail.worlds.recipe import TEST, TRAIN, world_recipe

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
    if config.objective is not None and config.policy is not None:
        raise ExperimentError("--objective: a saved policy has its own learner (--policy); give one or the other")
    if config.n_networks is not None and not averages_networks(config.objective):
        averaging = " or ".join(objective_names(lambda objective: objective.averages_networks))
        raise ExperimentError(f"--value-networks {config.n_networks}: only the {averaging} learner averages "
                              f"networks; give --objective {averaging}")
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
    if config.policy is not None:
        _check_saved_policy(config.policy, use_case, scenario)
    n_methods = 1 + len(baseline_names(config.redundancy_levels)) + len(config.methods)
    check_budget(config, recipe.full_preset, recipe.learner, recipe.test_steps, n_methods)
    # Each phase's world comes from its own streams of the seed, so drawing the test world
    # first changes no draw; it lets a user's policy be tried before the (longer) training
    # world is drawn.
    test_world = recipe.make_world(TEST, config.seed)
    _check_user_policies(config, test_world)
    return _Inputs(
        use_case=use_case,
        learner_config=recipe.learner,
        scenario=scenario,
        train_world=recipe.make_world(TRAIN, config.seed) if config.policy is None else None,
        test_world=test_world,
        world_overrides=recipe.overrides,
    )


def check_user_policies(config: ExperimentConfig) -> None:
    """Each ``--method`` policy of ``config`` asked for its test phase's first request, as the
    run itself asks (PolicyError, one line): what a command running many such runs as a campaign
    (the mobility sweep) checks once before the campaign starts. Draws the test world only."""
    if config.methods:
        _check_user_policies(config, world_recipe(config).make_world(TEST, config.seed))


def _check_user_policies(config: ExperimentConfig, world: EdgeWorld) -> None:
    """Ask each ``--method`` policy, built afresh, for the servers of the test phase's first
    request, so that one that cannot choose fails now (PolicyError), before any training.

    Nothing the run uses is touched: the instance is a throwaway one with its own twin of the
    method's generator, and the observation is read from the pre-drawn world (no draw) into
    arrays of its own, so a policy that writes into it cannot change the world every method
    replays.
    """
    if not config.methods:
        return
    first = world.observation(0, np.array(world.background_users[0]))
    for method in config.methods:
        copies: dict[str, Any] = {f.name: np.array(value) for f in dataclasses.fields(first)
                                  if isinstance(value := getattr(first, f.name), np.ndarray)}
        observation = dataclasses.replace(first, **copies)
        method.check_first_choice(world.n_servers, method_rng(config.seed, method.name),
                                  observation, SINGLE_USER_DISPATCH)


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
    check_learners(config, trains=inputs.train_world is not None)
    checkpoints = Checkpoints.for_run(config, inputs.train_world is not None, output.target)
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
        if checkpoints is not None and checkpoints.wrote and not resumable_after(error):
            # Nothing --resume could continue: the checkpoint is this run's own, so it goes.
            discard_checkpoint(output.target)
        elif checkpoints is not None and checkpoints.written:
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


def _run_into(staging: Path, config: ExperimentConfig, inputs: _Inputs,
              timings: dict[str, float], started: float,
              checkpoints: Checkpoints | None) -> pd.DataFrame:
    """Steps 3 to 5 into the staging folder; returns the summary."""
    yafs_dir = staging / YAFS_DIR if config.write_yafs_csv else None
    if yafs_dir is not None:
        yafs_dir.mkdir()
    prefix = f"UC{inputs.use_case.number}"
    others = MethodsJob(
        names=tuple(baseline_names(config.redundancy_levels)),
        user_methods=tuple(m for m in config.methods if not m.learns),
        seed=config.seed, world=inputs.test_world, step_interval_s=config.step_interval_s,
        yafs_dir=yafs_dir, episode_steps=inputs.learner_config.episode_steps,
        progress_label=f"{prefix} other methods test", bar=config.progress,
    )
    workers = start_workers(others, config.workers)  # forked before TensorFlow loads
    figures_worker = None  # (stopped below even if forking it fails)
    try:
        figures_worker = start_figures_worker(config.workers) if config.figures else None  # likewise
        return _learn_write_draw(staging, config, inputs, timings, started, checkpoints, others, workers,
                                 figures_worker, yafs_dir)
    finally:  # (stopping a process that has ended frees its pipe)
        for worker in workers:
            worker.stop()
        if figures_worker is not None:
            figures_worker.stop()


def _learn_write_draw(staging: Path, config: ExperimentConfig, inputs: _Inputs, timings: dict[str, float],
                      started: float, checkpoints: Checkpoints | None, others: MethodsJob,
                      workers: list[MethodsWorker], figures_worker: FiguresWorker | None,
                      yafs_dir: Path | None) -> pd.DataFrame:
    """Steps 4 and 5: the learners, the other methods' rows, then the files and figures."""
    prefix = f"UC{inputs.use_case.number}"
    with Phase(f"{prefix} {', '.join(learner_names(config))} setup (TensorFlow, the learners)", logger=log):
        learners = make_learners(config, inputs, timings)
    timings["setup"] = time.perf_counter() - started
    learners_job = LearnersJob(
        train_world=inputs.train_world, test_world=inputs.test_world,
        step_interval_s=config.step_interval_s, episode_steps=inputs.learner_config.episode_steps,
        prefix=prefix, yafs_dir=yafs_dir, bar=config.progress, chunk_steps=CHECKPOINT_CHUNK_STEPS)
    learner_frames = run_learners(learners_job, learners, checkpoints, timings)
    other_frames = run_other_methods(others, workers, timings)
    requests = pd.concat([*learner_frames, *other_frames], ignore_index=True)
    run = run_metadata(config, inputs, learners,
                       sort_methods([*(policy.name for policy in learners), *others.method_names]))
    t0 = time.perf_counter()
    if figures_worker is not None:  # drawn there while the files are written here
        figures_worker.draw(staging, requests, run, config.figure_formats)
    with Phase(f"{prefix} writing results", logger=log):
        summary = results.write_results(staging, requests, run)
        for policy in learners:
            policy.save(staging / policy.policy_file())
    timings["writing"] = time.perf_counter() - t0
    if config.figures:
        t1 = time.perf_counter()
        with Phase(f"{prefix} figures", logger=log):
            if figures_worker is not None:
                figures_worker.wait()
            else:
                from yafs_safetail.results.figures.run_figures import draw_figures

                draw_figures(staging, requests, run, formats=config.figure_formats)
        # With a figures process, from handing it the rows: the drawing overlaps the writing.
        timings["plotting"] = time.perf_counter() - (t0 if figures_worker is not None else t1)
    timings["total"] = time.perf_counter() - started
    return summary

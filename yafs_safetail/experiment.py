"""One SafeTail experiment: train SafeTail, then test it and every baseline on the same requests.

The flow reads top to bottom in :func:`run_experiment`:

1. check the configuration (use case, preset, seed, step scale, redundancy levels), load the
   traces and the scenario (topology + placement JSON);
2. draw the two phases' worlds (common random numbers: every method of a phase replays the
   same requests, trace rows and per-server draws). Everything so far is checked before
   TensorFlow is imported or the output is touched;
3. start the baselines' test phase in worker processes (``workers - 1`` of them);
4. import TensorFlow and build the learner (or load a saved policy);
5. train SafeTail for the preset's training steps (ε-greedy, a training round every κ tuples),
   then test it greedily (no exploration, no training) on the test world;
6. collect the baselines' rows and write the results folder under a temporary name, then
   rename it into place, so a failed run never leaves half-written results and never
   destroys an earlier run's folder.

Every method runs its own YAFS-compatible :class:`~yafs_safetail.yafs.core.Sim` with the
edge model as its delay hooks and writes the YAFS result CSVs under ``yafs/``. A method's
simulation depends only on the world and its own seeded generator, so running the baselines
in other processes gives the same files as running everything in one.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
import multiprocessing
import os
import shutil
import sys
import time
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from pathlib import Path

import numpy as np
import pandas as pd

import yafs_safetail
from yafs_safetail import results
from yafs_safetail.edge.calibration import WorldSettings, world_settings
from yafs_safetail.edge.model import EdgeModel, edge_application
from yafs_safetail.edge.topology_io import load_scenario
from yafs_safetail.edge.traces import DEFAULT_TRACE_DIR
from yafs_safetail.edge.usecases import UseCase, get_use_case
from yafs_safetail.edge.world import EdgeWorld, build_world, load_inputs
from yafs_safetail.placement import EdgePlacement
from yafs_safetail.policy.learner import read_policy_sidecar
from yafs_safetail.policy.presets import LearnerConfig, get_preset
from yafs_safetail.policy.state import StateScales, state_dim
from yafs_safetail.population import DEFAULT_STEP_INTERVAL_S, EdgePopulation
from yafs_safetail.selection import (
    RequestRecord,
    SafeTailSelection,
    SubsetSelection,
    make_baseline,
)
from yafs_safetail.yafs.core import Sim
from yafs_safetail.yafs.topology import Topology

REPOSITORY = Path(__file__).resolve().parents[1]
DEFAULT_TOPOLOGY = REPOSITORY / "topologies" / "paper_5servers.json"
DEFAULT_PLACEMENT = REPOSITORY / "placements" / "paper_5servers.json"
POLICY_FILE = "policy.keras"
YAFS_DIR = "yafs"
#: Requests simulated between two progress-bar updates.
PROGRESS_CHUNK_STEPS = 500


#: The world each preset runs in (yafs_safetail.edge.calibration): ``paper-literal`` keeps the
#: first release's world so that its results stay as they were.
PRESET_WORLDS = {"paper": "calibrated", "paper-literal": "landed", "tuned": "calibrated"}


class ExperimentError(ValueError):
    """A bad experiment setting (one line naming the setting and what is wrong)."""


@dataclass(frozen=True)
class ExperimentConfig:
    """Everything one run depends on; the same config and seed give identical result files.

    Attributes:
        use_case: 1 object detection, 2 instance segmentation, 3 noise removal.
        preset: ``"paper"`` (the default: Table I with the readings under which it learns, in
            the calibrated world), ``"paper-literal"`` (Table I letter for letter, in the
            landed world) or ``"tuned"`` (our learner settings, in the calibrated world); see
            :data:`PRESET_WORLDS`.
        seed: the run's seed (non-negative integer); every random draw derives from it.
        out_dir: the results folder (replaced atomically when the run succeeds).
        topology: YAFS topology JSON (user, access point, edge servers).
        placement: YAFS placement JSON (the service on each edge server, in index order).
        traces_dir: folder with the trace CSVs and the compute models.
        steps_scale: fraction of the preset's training and testing steps (for quick runs).
        redundancy_levels: the x of Rand-x, MinLoad-x and MinProp-x.
        step_interval_s: simulated time between two requests (one load-trace row).
        write_yafs_csv: write each method's YAFS result CSVs under ``yafs/``.
        figures: draw Figs. (a)-(g) into ``figures/``.
        progress: show progress bars on stderr.
        policy: a saved policy (``.keras``) to evaluate without training.
        command: the command line, recorded in ``run.json``.
        workers: processes for the run: the baselines' test phase runs in ``workers - 1``
            forked processes while this one trains SafeTail (1: everything here). The
            results do not depend on it.
        world: the world settings; None: the preset's world (:data:`PRESET_WORLDS`).
    """

    use_case: int = 1
    preset: str = "paper"
    seed: int = 0
    out_dir: Path = Path("results/uc1")
    topology: Path = DEFAULT_TOPOLOGY
    placement: Path = DEFAULT_PLACEMENT
    traces_dir: Path = DEFAULT_TRACE_DIR
    steps_scale: float = 1.0
    redundancy_levels: tuple[int, ...] = (1, 2, 3)
    step_interval_s: float = DEFAULT_STEP_INTERVAL_S
    write_yafs_csv: bool = True
    figures: bool = True
    progress: bool = True
    policy: Path | None = None
    command: str = ""
    workers: int = 2
    world: WorldSettings | None = None


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


def baseline_names(redundancy_levels: Sequence[int]) -> list[str]:
    """Oracle, then Rand-x, MinLoad-x, MinProp-x for every x."""
    names = [results.ORACLE]
    for family in ("Rand", "MinLoad", "MinProp"):
        names += [f"{family}-{x}" for x in redundancy_levels]
    return names


def method_rng(seed: int, method: str) -> np.random.Generator:
    """A method's own generator (Rand draws, MinLoad tie-breaks), independent per method."""
    return np.random.default_rng(np.random.SeedSequence([seed, zlib.crc32(method.encode())]))


def scaled_steps(steps: int, scale: float) -> int:
    """``steps * scale`` rounded, at least one step."""
    return max(1, round(steps * scale))


def _check_config(config: ExperimentConfig) -> tuple[UseCase, LearnerConfig]:
    use_case = get_use_case(config.use_case)
    if isinstance(config.seed, bool) or not isinstance(config.seed, int) or config.seed < 0:
        raise ExperimentError(f"--seed: expected a non-negative integer, got {config.seed!r}")
    if not (isinstance(config.steps_scale, float | int) and math.isfinite(config.steps_scale)
            and config.steps_scale > 0):
        raise ExperimentError(f"--steps-scale: expected a positive number, got {config.steps_scale!r}")
    base = get_preset(config.preset, use_case.number)
    learner_config = get_preset(
        config.preset, use_case.number,
        train_steps=scaled_steps(base.train_steps, config.steps_scale),
    )
    if isinstance(config.workers, bool) or not isinstance(config.workers, int) or config.workers < 1:
        raise ExperimentError(f"--workers: expected a positive integer, got {config.workers!r}")
    if not config.redundancy_levels:
        raise ExperimentError("--redundancy: give at least one level x")
    return use_case, learner_config


def _prepare_output(out_dir: Path) -> Path:
    """A fresh temporary folder beside ``out_dir`` (the run is renamed into place at the end)."""
    parent = out_dir.resolve().parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise OSError(f"--out {out_dir}: cannot create {parent}: {error.strerror}") from None
    if out_dir.exists() and not out_dir.is_dir():
        raise ExperimentError(f"--out {out_dir}: exists and is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OSError(f"--out {out_dir}: {parent} is not writable")
    staging = parent / f".{out_dir.name}.partial-{os.getpid()}"
    shutil.rmtree(staging, ignore_errors=True)
    try:
        staging.mkdir()
    except OSError as error:
        raise OSError(f"--out {out_dir}: cannot write in {parent}: {error.strerror}") from None
    return staging


def _publish(staging: Path, out_dir: Path) -> None:
    """Move the finished run into place; an older run in ``out_dir`` goes only after that."""
    target = out_dir.resolve()
    previous = None
    if target.exists():
        previous = target.parent / f".{target.name}.previous-{os.getpid()}"
        shutil.rmtree(previous, ignore_errors=True)
        os.replace(target, previous)
    os.replace(staging, target)
    if previous is not None:
        shutil.rmtree(previous, ignore_errors=True)


def simulate(
    world: EdgeWorld,
    make_selection: Callable[[EdgeModel], SubsetSelection],
    step_interval_s: float = DEFAULT_STEP_INTERVAL_S,
    results_path: Path | None = None,
    progress_label: str | None = None,
) -> list[RequestRecord]:
    """Run every request of ``world`` through a fresh Sim with the given selection.

    This is the one way a method meets the edge world: the experiment, the examples and the
    tests all call it (a YAFS-style script can do the same by hand, see
    ``examples/paper_scenario/main.py``).

    Args:
        world: the phase's pre-drawn world (its scenario gives topology and placement).
        make_selection: builds the method's selection on the run's edge model.
        step_interval_s: time between requests.
        results_path: YAFS results path prefix (None: no YAFS CSVs).
        progress_label: show a progress bar with this label (None: silent).

    Returns:
        One record per request, in step order.
    """
    scenario = world.scenario
    edge = EdgeModel(world)
    topology = Topology()
    topology.load(scenario.topology.data)
    sim = Sim(
        topology,
        default_results_path=str(results_path) if results_path else None,
        link_delay=edge,
        service_model=edge,
        write_results=results_path is not None,
    )
    selection = make_selection(edge)
    population = EdgePopulation(scenario.user_node, step_interval_s)
    sim.deploy_app(
        edge_application(scenario.app_name, scenario.module_name),
        EdgePlacement(scenario.placement),
        population,
        selection,
    )
    n_steps = world.n_steps
    bar = None
    if progress_label is not None:
        from tqdm import tqdm

        bar = tqdm(total=n_steps, desc=progress_label, unit="req", file=sys.stderr, leave=False)
    done = 0
    while done < n_steps:
        # Chunked runs only to move the progress bar; Sim.run continues the same simulation.
        done = min(n_steps, done + PROGRESS_CHUNK_STEPS)
        sim.run(until=population.until_s(done))
        if bar is not None:
            bar.update(len(selection.records) - bar.n)
    if bar is not None:
        bar.close()
    if len(selection.records) != n_steps:
        raise RuntimeError(
            f"{selection.name}: {len(selection.records)} of {n_steps} requests completed; "
            f"step_interval_s={step_interval_s} may be shorter than a request's latency"
        )
    return selection.records


def records_frame(records: Sequence[RequestRecord], phase: str, episode_steps: int) -> pd.DataFrame:
    """The ``requests.csv`` rows of one method and phase."""
    frame = pd.DataFrame(
        {
            "method": [r.method for r in records],
            "phase": phase,
            "episode": [r.step // episode_steps for r in records],
            "step": [r.step for r in records],
            "request_id": [r.request_id for r in records],
            "latency_s": [r.latency_s for r in records],
            "target_s": [r.target_s for r in records],
            "deviation_s": [r.deviation_s for r in records],
            "n_selected": [r.n_selected for r in records],
            "access_rate": [r.access_rate for r in records],
            "servers": [";".join(map(str, r.servers)) for r in records],
            "reward": [r.reward for r in records],
            "refused": [r.refused for r in records],
            "fallback": [int(r.fallback) for r in records],
            "upload_s": [r.upload_s for r in records],
            "propagation_s": [r.propagation_s for r in records],
            "download_s": [r.download_s for r in records],
            "compute_s": [r.compute_s for r in records],
            "epsilon": [r.epsilon for r in records],
        }
    )
    return frame


def run_experiment(config: ExperimentConfig) -> ExperimentReport:
    """Run one use case end to end and write its results folder (see docs/results.md).

    Raises:
        ValueError: a bad setting or input file (one-line message naming it).
        OSError: the output folder cannot be written.
    """
    timings = {"setup": 0.0, "tf_import": 0.0, "simulation": 0.0, "decisions": 0.0, "training": 0.0,
               "baselines_in_workers": 0.0, "waiting_for_workers": 0.0, "writing": 0.0, "plotting": 0.0}
    started = time.perf_counter()

    # 1. configuration and inputs, all checked before TensorFlow is imported or anything written
    use_case, learner_config = _check_config(config)
    inputs = load_inputs(use_case, config.traces_dir)
    scenario = load_scenario(config.topology, config.placement,
                             known_conditions=inputs.rtt_pools_s.keys(),
                             n_load_devices=inputs.n_load_devices)
    for x in config.redundancy_levels:
        if isinstance(x, bool) or not isinstance(x, int) or not 1 <= x <= scenario.n_servers:
            raise ExperimentError(
                f"--redundancy: x={x!r} must be an integer in 1..{scenario.n_servers} "
                f"(the servers in {config.topology})"
            )
    if config.policy is not None:
        if not Path(config.policy).is_file():
            raise ExperimentError(f"--policy {config.policy}: no such file")
        saved = read_policy_sidecar(config.policy)
        expected_dim = state_dim(scenario.n_servers, len(use_case.gamma_columns),
                                 len(scenario.user_location))
        if int(saved["n_servers"]) != scenario.n_servers or int(saved["state_dim"]) != expected_dim:
            raise ExperimentError(
                f"--policy {config.policy}: trained for {saved['n_servers']} servers and "
                f"{saved['state_dim']} state entries; use case {use_case.number} on "
                f"{config.topology} has {scenario.n_servers} servers and {expected_dim}"
            )

    # 2. the two phases' worlds (common random numbers for every method of a phase)
    episode_steps = learner_config.episode_steps

    settings = config.world or world_settings(PRESET_WORLDS[config.preset])

    def world(phase: str, n_steps: int) -> EdgeWorld:
        return build_world(scenario, use_case, inputs, n_steps, seed=config.seed, phase=phase,
                           episode_steps=episode_steps, settings=settings)

    train_world = world("train", learner_config.train_steps) if config.policy is None else None
    test_world = world("test", scaled_steps(learner_config.test_steps, config.steps_scale))

    staging = _prepare_output(config.out_dir)
    try:
        report = _run_into(staging, config, use_case, learner_config, scenario, train_world,
                           test_world, timings, started)
        _publish(staging, config.out_dir)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    report.out_dir = config.out_dir
    return report


@dataclass(frozen=True)
class _BaselineJob:
    """The test phase of some baselines: everything a worker process needs (inherited by fork)."""

    names: tuple[str, ...]
    seed: int
    world: EdgeWorld
    step_interval_s: float
    yafs_dir: Path | None
    episode_steps: int
    progress_prefix: str | None

    def run(self) -> tuple[list[pd.DataFrame], float]:
        """Simulate each baseline; returns its requests rows (in ``names`` order) and the wall time."""
        started = time.perf_counter()
        frames = []
        for name in self.names:
            rng = method_rng(self.seed, name)
            records = simulate(
                self.world,
                lambda edge, name=name, rng=rng: make_baseline(name, edge, rng),
                self.step_interval_s,
                None if self.yafs_dir is None else self.yafs_dir / f"{name}_test",
                None if self.progress_prefix is None else f"{self.progress_prefix} {name} test",
            )
            frames.append(records_frame(records, "test", self.episode_steps))
        return frames, time.perf_counter() - started


def _worker_main(job: _BaselineJob, sender: Connection) -> None:
    try:
        outcome = (True, job.run())
    except BaseException as error:  # every failure goes back to the parent
        outcome = (False, error)
    try:
        sender.send(outcome)
    except Exception as error:  # e.g. an exception that does not pickle
        sender.send((False, RuntimeError(f"baseline worker: {type(error).__name__}: {error}")))
    sender.close()


class _BaselineWorker:
    """A forked process running a :class:`_BaselineJob` while this process trains SafeTail.

    Forking (rather than spawning) shares the worlds without pickling them and starts at
    once; the worker never touches TensorFlow.
    """

    def __init__(self, job: _BaselineJob) -> None:
        self.job = job
        context = multiprocessing.get_context("fork")
        self._receiver, sender = context.Pipe(duplex=False)
        self._process = context.Process(target=_worker_main, args=(job, sender), daemon=True,
                                         name="yafs-safetail-baselines")
        self._process.start()
        sender.close()

    def result(self) -> tuple[list[pd.DataFrame], float]:
        """Wait for the job's result; re-raises its exception."""
        try:
            ok, payload = self._receiver.recv()
        except EOFError:
            self._process.join()
            raise RuntimeError(
                f"baseline worker ended without a result (exit code {self._process.exitcode})"
            ) from None
        self._process.join()
        if not ok:
            raise payload
        return payload

    def stop(self) -> None:
        """End the process if it is still running (the run failed) and free the pipe."""
        if self._process.is_alive():
            self._process.terminate()
            self._process.join()
        self._receiver.close()


def _start_baselines(job: _BaselineJob, workers: int) -> list[_BaselineWorker]:
    """Forks ``workers - 1`` processes (at most one per baseline), each taking every
    (workers - 1)-th baseline; none with one worker, where ``fork`` does not exist, or inside a
    daemonic process (e.g. a ``multiprocessing.Pool`` worker, which may not have children)."""
    n_processes = min(workers - 1, len(job.names))
    if (n_processes < 1 or "fork" not in multiprocessing.get_all_start_methods()
            or multiprocessing.current_process().daemon):
        return []
    # Progress bars stay with this process: bars from several processes garble a terminal.
    return [
        _BaselineWorker(dataclasses.replace(job, names=job.names[i::n_processes], progress_prefix=None))
        for i in range(n_processes)
    ]


def _run_into(staging, config, use_case, learner_config, scenario, train_world, test_world, timings,
              started):
    train_steps = learner_config.train_steps
    test_steps = test_world.n_steps
    episode_steps = learner_config.episode_steps
    yafs_dir = staging / YAFS_DIR
    if config.write_yafs_csv:
        yafs_dir.mkdir()

    def results_path(method: str, phase: str) -> Path | None:
        return yafs_dir / f"{method}_{phase}" if config.write_yafs_csv else None

    def label(method: str, phase: str) -> str | None:
        return f"UC{use_case.number} {method} {phase}" if config.progress else None

    # 3. the baselines' test phase: in worker processes while this one trains SafeTail (they
    #    need no TensorFlow, and every method's simulation is independent of the others')
    baselines = tuple(baseline_names(config.redundancy_levels))
    job = _BaselineJob(
        names=baselines, seed=config.seed, world=test_world,
        step_interval_s=config.step_interval_s, yafs_dir=yafs_dir if config.write_yafs_csv else None,
        episode_steps=episode_steps, progress_prefix=f"UC{use_case.number}" if config.progress else None,
    )
    workers = _start_baselines(job, config.workers)
    try:
        t0 = time.perf_counter()
        from yafs_safetail.policy.learner import SafeTailLearner

        # The learner builds its network with Keras; importing it (and TensorFlow) takes
        # seconds the first time, so it is done here to show up as its own part of the setup.
        importlib.import_module("keras")
        timings["tf_import"] = time.perf_counter() - t0

        # 4. the learner: fresh, or a saved policy evaluated without training
        scales = StateScales.for_use_case(use_case.number)
        if config.policy is None:
            learner = SafeTailLearner(
                scenario.n_servers,
                state_dim(scenario.n_servers, len(use_case.gamma_columns), len(scenario.user_location)),
                learner_config,
                config.seed,
                metadata={"use_case": use_case.number, "topology": str(config.topology)},
            )
        else:
            learner = SafeTailLearner.load(config.policy, training=False)
            if learner.n_servers != scenario.n_servers:
                raise ExperimentError(
                    f"--policy {config.policy}: trained for {learner.n_servers} servers, "
                    f"the topology has {scenario.n_servers}"
                )
            learner_config = learner.config
        timings["setup"] = time.perf_counter() - started

        # 5. SafeTail: training, then testing greedily on the test world
        selections: list[SafeTailSelection] = []

        def safetail(explore: bool, learn: bool) -> Callable[[EdgeModel], SubsetSelection]:
            def build(edge: EdgeModel) -> SubsetSelection:
                selection = SafeTailSelection(edge, learner, scales, explore=explore, learn=learn)
                selections.append(selection)
                return selection
            return build

        frames = []
        t0 = time.perf_counter()
        if train_world is not None:
            records = simulate(train_world, safetail(True, True), config.step_interval_s,
                               results_path(results.SAFETAIL, "train"), label(results.SAFETAIL, "train"))
            frames.append(records_frame(records, "train", episode_steps))
        records = simulate(test_world, safetail(False, False), config.step_interval_s,
                           results_path(results.SAFETAIL, "test"), label(results.SAFETAIL, "test"))
        frames.append(records_frame(records, "test", episode_steps))
        timings["simulation"] += time.perf_counter() - t0
        for selection in selections:
            timings["decisions"] += selection.decision_time_s
            timings["training"] += selection.training_time_s
        # Simulation time is reported without the learner's share.
        timings["simulation"] -= timings["decisions"] + timings["training"]

        # 6. the baselines' rows, in report order (here if no worker ran them)
        by_name: dict[str, pd.DataFrame] = {}
        if workers:
            t0 = time.perf_counter()
            for worker in workers:
                worker_frames, wall_s = worker.result()
                by_name.update(zip(worker.job.names, worker_frames, strict=True))
                timings["baselines_in_workers"] = max(timings["baselines_in_workers"], wall_s)
            timings["waiting_for_workers"] = time.perf_counter() - t0
        else:
            job_frames, wall_s = job.run()
            by_name.update(zip(job.names, job_frames, strict=True))
            timings["simulation"] += wall_s
        frames += [by_name[name] for name in baselines]
        methods = [results.SAFETAIL, *baselines]
    finally:
        for worker in workers:
            worker.stop()

    # 6. results files, the policy, the figures
    requests = pd.concat(frames, ignore_index=True)
    run = results.RunMetadata(
        use_case=use_case.number,
        use_case_name=use_case.description,
        preset=learner_config.name,
        seed=config.seed,
        n_servers=scenario.n_servers,
        beta=learner_config.beta,
        train_steps=0 if train_world is None else train_steps,
        test_steps=test_steps,
        topology=os.path.relpath(config.topology, REPOSITORY)
        if Path(config.topology).resolve().is_relative_to(REPOSITORY) else str(config.topology),
        methods=methods,
        package_version=yafs_safetail.__version__,
        command=config.command,
        extra={
            "steps_scale": config.steps_scale,
            "step_interval_s": config.step_interval_s,
            "episode_steps": episode_steps,
            "fallback_latency_s": test_world.fallback_latency_s,
            "nu": test_world.nu,
            "world": test_world.settings.to_dict(),
            "learner": learner_config.to_dict(),
            "training_rounds": learner.n_training_rounds,
            "final_epsilon": learner.epsilon,
            "policy_source": str(config.policy) if config.policy else POLICY_FILE,
        },
    )
    t0 = time.perf_counter()
    summary = results.write_results(staging, requests, run)
    learner.save(staging / POLICY_FILE)
    timings["writing"] = time.perf_counter() - t0
    if config.figures:
        from yafs_safetail.figures import draw_figures

        t0 = time.perf_counter()
        draw_figures(staging)
        timings["plotting"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - started
    return ExperimentReport(out_dir=staging, summary=summary, timings_s=timings)

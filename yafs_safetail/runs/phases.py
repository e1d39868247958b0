"""A run's phases for every method: the learners train then test here, the others test in workers.

Every method gets the same requests of a phase (common random numbers): each runs its own
simulation over the phase's :class:`~yafs_safetail.edge.world.EdgeWorld` with its own
generator. The methods that do not learn need only the test phase and run in forked workers
(``runs.workers``) while this process trains the learners, one after the other.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from yafs_safetail.edge.world import EdgeWorld
from yafs_safetail.logs import Phase
from yafs_safetail.methods.learning import TEST_PHASE, TRAIN_PHASE, LearningPolicy
from yafs_safetail.record import records_frame
from yafs_safetail.runs.training import Checkpoints, train
from yafs_safetail.runs.workers import MethodsJob, MethodsWorker
from yafs_safetail.sim.runner import simulate

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class LearnersJob:
    """What the learners' phases need.

    Attributes:
        train_world: the training phase's world (None: no training, e.g. ``--policy``).
        test_world: the test phase's world.
        step_interval_s: simulated time between two requests.
        episode_steps: α_s, for the rows' episode numbers.
        prefix: what the logged phases' names start with (e.g. ``"UC1"``).
        yafs_dir: where the YAFS CSVs go (None: not written).
        bar: show progress bars.
        chunk_steps: training requests between two chances to checkpoint.
    """

    train_world: EdgeWorld | None
    test_world: EdgeWorld
    step_interval_s: float
    episode_steps: int
    prefix: str
    yafs_dir: Path | None
    bar: bool
    chunk_steps: int

    def yafs_path(self, policy: LearningPolicy, phase: str) -> Path | None:
        return None if self.yafs_dir is None else self.yafs_dir / f"{policy.name}_{phase}"


def run_learners(job: LearnersJob, learners: Sequence[LearningPolicy],
                 checkpoints: Checkpoints | None, timings_s: dict[str, float]) -> list[pd.DataFrame]:
    """Train (unless there is no training world) then test each learner, in order; returns
    their rows, each learner's training rows then its test rows. Adds the learners' decision,
    training and (the rest) simulation time to ``timings_s``."""
    started = time.perf_counter()
    frames = []
    for policy in learners:
        if job.train_world is not None:
            records = train(policy, job.train_world, job.step_interval_s,
                            f"{job.prefix} {policy.name} {TRAIN_PHASE}",
                            yafs_path=job.yafs_path(policy, TRAIN_PHASE), bar=job.bar,
                            checkpoints=checkpoints, chunk_steps=job.chunk_steps)
            frames.append(records_frame(records, TRAIN_PHASE, job.episode_steps, job.train_world.movement))
            summary = policy.end_training()
            if summary:
                log.info("%s %s: %s", job.prefix, policy.name, summary)
        policy.begin_phase(TEST_PHASE)
        with Phase(f"{job.prefix} {policy.name} {TEST_PHASE}", job.test_world.n_steps, bar=job.bar,
                   logger=log) as progress:
            records = simulate(job.test_world, policy, job.step_interval_s,
                               job.yafs_path(policy, TEST_PHASE), progress)
        frames.append(records_frame(records, TEST_PHASE, job.episode_steps, job.test_world.movement))
    learning_s = 0.0
    for policy in learners:
        timings_s["decisions"] += policy.decision_time_s
        timings_s["training"] += policy.training_time_s
        learning_s += policy.decision_time_s + policy.training_time_s
    # Simulation time is reported without the learners' share.
    timings_s["simulation"] += time.perf_counter() - started - learning_s
    return frames


def run_other_methods(job: MethodsJob, workers: Sequence[MethodsWorker],
                      timings_s: dict[str, float]) -> list[pd.DataFrame]:
    """The other methods' test rows, in the job's order (run here when no worker ran them)."""
    by_name: dict[str, pd.DataFrame] = {}
    if workers:
        started = time.perf_counter()
        log.debug("waiting for %d worker process(es)", len(workers))
        for worker in workers:
            frames, wall_s = worker.result()
            by_name.update(zip(worker.job.method_names, frames, strict=True))
            timings_s["baselines_in_workers"] = max(timings_s["baselines_in_workers"], wall_s)
        timings_s["waiting_for_workers"] = time.perf_counter() - started
    else:
        frames, wall_s = job.run()
        by_name.update(zip(job.method_names, frames, strict=True))
        timings_s["simulation"] += wall_s
    return [by_name[name] for name in job.method_names]

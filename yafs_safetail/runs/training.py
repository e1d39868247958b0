"""The training phase of a run's learning methods, with checkpoints for ``--resume``.

Every learning method (:class:`~yafs_safetail.methods.learning.LearningPolicy`: SafeTail, a
user's learner) trains the same way, one after the other, on the same training world: its own
simulation, in chunks of ``chunk_steps`` requests; after a chunk with no copy running the run
may write a checkpoint (``runs.checkpoint``) holding every method trained so far. With
``--resume`` a method restores its state from the checkpoint and a fresh simulation starts at
the checkpoint's step (``deploy(..., first_step=)``: the same step numbers, request ids and
clock), so the results are those of an uninterrupted run.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

from yafs_safetail.edge.world import EdgeWorld
from yafs_safetail.logs import Phase
from yafs_safetail.methods.learning import TRAIN_PHASE, LearningPolicy
from yafs_safetail.record import RequestRecord
from yafs_safetail.runs import checkpoint
from yafs_safetail.runs.checkpoint import (
    CheckpointError,
    MethodTraining,
    TrainingCheckpoint,
    check_checkpoint_place,
    checkpoint_folder,
    has_checkpoint,
    read_checkpoint,
)
from yafs_safetail.runs.grid import config_run_id
from yafs_safetail.settings.experiment import ExperimentConfig
from yafs_safetail.sim.runner import Simulation, simulate

log = logging.getLogger(__name__)


@dataclass
class Checkpoints:
    """A run's training checkpoints: the one it resumes from, and when to write the next.

    Attributes:
        target: the run's results folder (the checkpoint goes beside it).
        run_id: the configuration's identity the checkpoint carries.
        every_s: wall time between two checkpoints.
        resume_from: the checkpoint to continue (``--resume``), or None.
        trained: the methods whose training has ended, as the next checkpoint records them.
        written: whether this run has written (or resumed from) a checkpoint that
            ``--resume`` can continue.
        wrote: whether this run itself has written the checkpoint (not only resumed from one).
    """

    target: Path
    run_id: str
    every_s: float
    resume_from: TrainingCheckpoint | None
    trained: dict[str, MethodTraining] = field(default_factory=dict)
    last_written: float = field(default_factory=time.perf_counter)
    written: bool = False
    wrote: bool = False

    @classmethod
    def for_run(cls, config: ExperimentConfig, trains: bool, target: Path) -> Checkpoints | None:
        """None when the run does not train or checkpoints are off. Reads the checkpoint to
        resume from (CheckpointError before anything runs if it does not fit)."""
        # A resumed training phase cannot append to the YAFS CSVs of the interrupted one.
        trains = trains and not config.write_yafs_csv
        if config.resume and not trains:
            raise CheckpointError("--resume: only a training run with no --yafs-csv and no "
                                  "--policy keeps checkpoints")
        if not trains or config.checkpoint_every_s is None:
            return None
        check_checkpoint_place(target)
        run_id = config_run_id(config)
        resume_from = read_checkpoint(target, run_id) if config.resume else None
        if resume_from is None and has_checkpoint(target):
            log.warning("%s holds an interrupted run's checkpoint; this run starts over and "
                        "replaces it (--resume continues it)", checkpoint_folder(target))
        return cls(target, run_id, float(config.checkpoint_every_s), resume_from,
                   written=resume_from is not None)

    def resumed(self, method: str) -> MethodTraining | None:
        """Where ``method``'s interrupted training stood (None: it starts from the start)."""
        return None if self.resume_from is None else self.resume_from.methods.get(method)

    def due(self) -> bool:
        """Whether the next chance should write a checkpoint (``every_s`` has passed)."""
        return time.perf_counter() - self.last_written >= self.every_s

    def write(self, policy: LearningPolicy, next_step: int, records: list[RequestRecord],
              done: bool = False) -> None:
        """Write a checkpoint with ``policy`` at ``next_step`` if one is due or its training is
        ``done`` (then it is kept for every later checkpoint of the run)."""
        if not (done or self.due()):
            return
        stand = MethodTraining(next_step=next_step, policy_state=policy.checkpoint_state(),
                               records=list(records), decision_time_s=policy.decision_time_s,
                               training_time_s=policy.training_time_s)
        if done:
            self.trained[policy.name] = stand
        # Set first: a kill during the write leaves the previous checkpoint or this one, both
        # of which --resume continues.
        self.written = self.wrote = True
        # Through the module: tests stop a run right after a chosen checkpoint.
        checkpoint.write_checkpoint(self.target, TrainingCheckpoint(
            run_id=self.run_id, methods={**self.trained, policy.name: stand}))
        self.last_written = time.perf_counter()


def train(policy: LearningPolicy, world: EdgeWorld, step_interval_s: float, label: str, *,
          yafs_path: Path | None, bar: bool, checkpoints: Checkpoints | None,
          chunk_steps: int) -> list[RequestRecord]:
    """One learning method's training phase on ``world`` (from its checkpoint when resuming).

    Args:
        policy: the learning method; put in its training phase here.
        world: the training phase's world.
        step_interval_s: simulated time between two requests.
        label: the logged phase's name (e.g. ``"UC1 SafeTail train"``).
        yafs_path: where its YAFS CSVs go (None: not written; never with checkpoints).
        bar: show a progress bar.
        checkpoints: the run's checkpoints (None: none kept).
        chunk_steps: requests between two chances to checkpoint.

    Returns:
        Every training record, in step order.
    """
    policy.begin_phase(TRAIN_PHASE)
    with Phase(label, world.n_steps, bar=bar, logger=log) as progress:
        if checkpoints is None:
            return simulate(world, policy, step_interval_s, yafs_path, progress)
        earlier: list[RequestRecord] = []
        first_step = 0
        saved = checkpoints.resumed(policy.name)
        if saved is not None:
            policy.restore_checkpoint_state(saved.policy_state)
            policy.decision_time_s, policy.training_time_s = saved.decision_time_s, saved.training_time_s
            earlier, first_step = list(saved.records), saved.next_step
            log.info("%s: resumed from the checkpoint at request %d", label, first_step)
            progress.update(first_step)

        def after_chunk(simulation: Simulation) -> None:
            # Only between two requests with nothing running can a fresh simulation take over.
            # Checked before the rows are joined: most chances write nothing.
            if simulation.quiescent and checkpoints.due():
                checkpoints.write(policy, simulation.next_step, earlier + simulation.records)

        records = earlier + simulate(world, policy, step_interval_s, yafs_path, progress,
                                     first_step=first_step, after_chunk=after_chunk,
                                     chunk_steps=chunk_steps)
        # Kept for every later checkpoint: a kill while testing (or while the next method
        # trains) resumes from here.
        checkpoints.write(policy, world.n_steps, records, done=True)
        return records

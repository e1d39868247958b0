"""Training checkpoints: where an interrupted run's training stood, for ``--resume``.

While the run's learning methods train (``runs.training``: SafeTail, then any user's
learner, one after the other), the run writes a checkpoint beside its target folder,
``.<target>.checkpoint/``, at most every ``checkpoint_every_s`` seconds and once more when each
method's training ends. It holds, per learning method trained so far, its whole training
state (``LearningPolicy.checkpoint_state``: for SafeTail the weights, Adam's slots, replay
buffer, counters and random generators), its training records so far and its next step. A
checkpoint is taken only between two requests with no copy running, so a fresh simulation
started at that step continues the interrupted one exactly: a resumed run writes the same
results files as an uninterrupted one.

The checkpoint belongs to one configuration (the campaign run id of its settings and code
version, :func:`yafs_safetail.runs.grid.config_run_id`); ``--resume`` with any other refuses.
The folder carries a marker file, and only a folder with the marker is ever replaced or
removed; it is removed when the run's results are complete, just before they are renamed
into place, and when the run fails in a way ``--resume`` cannot get past
(:func:`resumable_after`).

The state is a pickle: it is read back only from a folder this tool made (the marker), by the
same code version, never from elsewhere.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import pickle
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from yafs_safetail.record import RequestRecord
from yafs_safetail.runs.output import OutputError
from yafs_safetail.stopping import terminating

#: The marker file inside every checkpoint folder this tool made.
CHECKPOINT_MARKER = ".yafs-safetail-checkpoint"
CHECKPOINT_FILE = "training.pickle"
#: Bumped when the checkpoint's contents change: an older checkpoint is refused, not misread.
#: 2: one :class:`MethodTraining` per learning method. 3: a checksummed header.
CHECKPOINT_FORMAT = 3
#: The file's first line: this magic, the format and the SHA-256 of the pickle that follows.
#: A copy cut short or a flipped byte fails the checksum instead of unpickling to wrong numbers.
CHECKPOINT_MAGIC = b"yafs-safetail-checkpoint"


class CheckpointError(ValueError):
    """A checkpoint that cannot be resumed (one line naming it and why)."""


@dataclass
class MethodTraining:
    """Where one learning method's training stood between two requests.

    Attributes:
        next_step: the training world's step of its next request (the world's length: done).
        policy_state: :meth:`LearningPolicy.checkpoint_state
            <yafs_safetail.methods.learning.LearningPolicy.checkpoint_state>`.
        records: its training records of steps ``0 .. next_step - 1``.
        decision_time_s: the policy's decision time so far (timings only).
        training_time_s: the policy's training time so far (timings only).
    """

    next_step: int
    policy_state: object
    records: list[RequestRecord] = field(default_factory=list)
    decision_time_s: float = 0.0
    training_time_s: float = 0.0


@dataclass
class TrainingCheckpoint:
    """Where a run's training stood between two requests.

    Attributes:
        run_id: the configuration's identity (:func:`yafs_safetail.runs.grid.config_run_id`).
        methods: by method name, in training order, each learning method trained so far (the
            last one possibly in the middle of its training).
    """

    run_id: str
    methods: dict[str, MethodTraining] = field(default_factory=dict)


def resumable_after(error: BaseException) -> bool:
    """Whether a run stopped by ``error`` can be continued from its checkpoint.

    Yes when it was stopped from outside (Ctrl-C, SIGTERM, a worker killed) or by the system
    (``OSError``: a full disk, an unwritable folder): the same command with ``--resume``
    continues once that is past. No for any other error: bad input or a bug (a user's policy
    that returns no server, raises, ...) stops the same command again at the same place, and
    the fix (an edited policy file) changes the run id the checkpoint is tied to, so
    ``--resume`` would refuse it: such a checkpoint is only a hidden megabyte-sized folder.
    A SIGTERM is a stop from outside whatever exception it surfaced as.
    """
    # A SIGTERM that lands inside library code may surface as another exception (an import it
    # interrupts raises ImportError): the process's flag says it was a stop from outside.
    return not isinstance(error, Exception) or isinstance(error, OSError) or terminating()


def checkpoint_folder(target: Path) -> Path:
    """The checkpoint folder of a run whose results go to ``target`` (beside it)."""
    return target.parent / f".{target.name}.checkpoint"


def _check_ours(folder: Path, option: str) -> None:
    if (folder.exists() or folder.is_symlink()) and not (
            folder.is_dir() and not folder.is_symlink() and (folder / CHECKPOINT_MARKER).is_file()):
        raise OutputError(f"{option}: {folder} exists and is not a yafs-safetail checkpoint; "
                          "move it away or choose another folder")


def check_checkpoint_place(target: Path, option: str = "--out") -> None:
    """Refuse (OutputError) a run whose checkpoint folder's name is taken by something else."""
    _check_ours(checkpoint_folder(target), option)


def write_checkpoint(target: Path, checkpoint: TrainingCheckpoint) -> None:
    """Write (or replace) the checkpoint of the run going to ``target``, atomically: a reader
    sees the previous checkpoint or this one, never part of one."""
    folder = checkpoint_folder(target)
    _check_ours(folder, "--out")
    folder.mkdir(exist_ok=True)
    (folder / CHECKPOINT_MARKER).touch()
    first = not (folder / CHECKPOINT_FILE).is_file()
    payload = pickle.dumps(checkpoint, protocol=pickle.HIGHEST_PROTOCOL)
    header = b"%s %d sha256=%s\n" % (CHECKPOINT_MAGIC, CHECKPOINT_FORMAT,
                                     hashlib.sha256(payload).hexdigest().encode())
    handle, temporary = tempfile.mkstemp(prefix=".training-", suffix=".partial", dir=folder)
    try:
        with os.fdopen(handle, "wb") as stream:
            stream.write(header)
            stream.write(payload)
            stream.flush()
            # On disk before the rename: a crash after it must not leave an empty checkpoint.
            os.fsync(stream.fileno())
        os.replace(temporary, folder / CHECKPOINT_FILE)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        if first:  # nothing of an earlier checkpoint to keep (e.g. the disk is full)
            discard_checkpoint(target)
        raise


def _unpickle_checked(path: Path) -> TrainingCheckpoint:
    """The checkpoint in ``path`` once its header and checksum hold (CheckpointError if not)."""
    start_over = "to start over, run without --resume (that replaces it)"
    try:
        data = path.read_bytes()
    except OSError as error:
        raise CheckpointError(f"--resume: {path} cannot be read ({error.strerror}); "
                              f"{start_over}") from None
    header, _, payload = data.partition(b"\n")
    fields = header.split(b" ")
    if len(fields) != 3 or fields[0] != CHECKPOINT_MAGIC or not fields[2].startswith(b"sha256="):
        raise CheckpointError(f"--resume: {path} is not a checkpoint this version of the tool "
                              f"wrote; {start_over}")
    if fields[1] != b"%d" % CHECKPOINT_FORMAT:
        raise CheckpointError(f"--resume: {path} was written by another version of the tool "
                              f"(format {fields[1].decode(errors='replace')}); {start_over}")
    if hashlib.sha256(payload).hexdigest().encode() != fields[2].removeprefix(b"sha256="):
        raise CheckpointError(f"--resume: {path} is damaged (cut short or corrupted: its "
                              f"checksum does not match); {start_over}")
    try:
        checkpoint = pickle.loads(payload)
    except Exception as error:  # the checksum held, so the pickle is ours: a code change
        raise CheckpointError(f"--resume: {path} cannot be loaded by this version of the tool "
                              f"({type(error).__name__}); {start_over}") from None
    if not isinstance(checkpoint, TrainingCheckpoint):
        raise CheckpointError(f"--resume: {path} is not a training checkpoint; {start_over}")
    return checkpoint


def read_checkpoint(target: Path, run_id: str) -> TrainingCheckpoint:
    """The checkpoint of the interrupted run going to ``target``.

    Raises:
        CheckpointError: none there, unreadable, of another format or of another configuration.
    """
    folder = checkpoint_folder(target)
    path = folder / CHECKPOINT_FILE
    if not (folder / CHECKPOINT_MARKER).is_file() or not path.is_file():
        raise CheckpointError(f"--resume: no checkpoint of an interrupted run for {target} "
                              f"(looked for {path}); run without --resume")
    checkpoint = _unpickle_checked(path)
    if checkpoint.run_id != run_id:
        raise CheckpointError(
            f"--resume: {path} is of another configuration or code version (run id "
            f"{checkpoint.run_id}, this run {run_id}); give the interrupted run's options, or "
            "run without --resume")
    return checkpoint


def matches(target: Path, run_id: str) -> bool:
    """Whether ``target``'s run left a checkpoint of this very configuration (a campaign then
    resumes it instead of starting over)."""
    try:
        read_checkpoint(target, run_id)
    except CheckpointError:
        return False
    return True


def has_checkpoint(target: Path) -> bool:
    """Whether an interrupted run left a checkpoint for ``target``."""
    return (checkpoint_folder(target) / CHECKPOINT_MARKER).is_file()


def discard_checkpoint(target: Path) -> None:
    """Remove the checkpoint of ``target``'s run: only the files this tool writes there (the
    checkpoint, a partial one, the marker), then the folder if that leaves it empty; anything
    else someone put inside stays, and so does the folder."""
    folder = checkpoint_folder(target)
    if not (folder.is_dir() and not folder.is_symlink() and (folder / CHECKPOINT_MARKER).is_file()):
        return
    for ours in [folder / CHECKPOINT_FILE, *folder.glob(".training-*.partial"), folder / CHECKPOINT_MARKER]:
        if ours.is_file() and not ours.is_symlink():
            ours.unlink(missing_ok=True)
    with contextlib.suppress(OSError):  # not empty: something that is not ours is inside
        folder.rmdir()

"""Where a run's results go, without ever losing what is already there.

A run writes into a fresh temporary folder beside its target (``.NAME.partial-XXXX``) and
renames it into place only when everything is written. Before it starts, the target is
checked: ``/``, the home folder, the working folder, the project and any folder holding one
of them are refused; a folder that exists and is not empty must be a finished results folder
of this tool (it has ``run.json`` and ``requests.csv``, or a load sweep's ``sweep.csv``), and is replaced only with
``overwrite``. A lock beside the target (``.NAME.lock``, held with ``flock`` for the whole run,
so a killed run never leaves a stale lock) makes a second run on the same target fail at once.
Whatever happens, the temporary folder is removed and the lock released; the temporary
folder of a run killed outright (SIGKILL) is removed by the next run on the same target. Only
what carries this tool's marker is ever removed: a lock file starting with ``LOCK_MARKER``, a
temporary folder holding ``STAGING_MARKER``; an earlier results folder goes only with
``overwrite``, after the new one is in place. Replacing it takes two renames (the earlier run
aside into ``.NAME.previous-XXXX``, marked ``PREVIOUS_MARKER``, then the new one into place); a
run killed between them leaves the earlier run aside, and the next run on the target puts it
back before anything else.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import logging
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

from yafs_safetail.edge.scenario import REPOSITORY
from yafs_safetail.results.files import folder_mode

RUN_FILE = "run.json"
REQUESTS_FILE = "requests.csv"
#: A load sweep's table (experiments/load_sweep.py), which it writes instead of requests.csv.
SWEEP_FILE = "sweep.csv"
#: experiments/training_mechanism.py's table.
MECHANISM_FILE = "mechanism.csv"


#: What a write into a full file system (or a full quota) fails with.
DISK_FULL_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT})


class OutputError(ValueError):
    """An output folder the run refuses to write (one line naming it and why)."""


def is_results_folder(folder: Path) -> bool:
    """True for a finished results folder of this tool: ``run.json`` naming the package
    version, beside ``requests.csv`` (or a load sweep's ``sweep.csv``, or a training
    mechanism's ``mechanism.csv``)."""
    try:
        run = json.loads((folder / RUN_FILE).read_text())
    except (OSError, ValueError):
        return False
    return isinstance(run, dict) and "package_version" in run and (
        (folder / REQUESTS_FILE).is_file() or (folder / SWEEP_FILE).is_file()
        or (folder / MECHANISM_FILE).is_file())


def refuse_protected(folder: Path, option: str = "--out") -> Path:
    """``folder`` resolved, or OutputError if it is, or holds, a folder no run may replace:
    ``/``, the home folder, the working folder or the project."""
    target = folder.resolve()
    protected = {Path("/"): "the file system root", Path.home().resolve(): "your home folder",
                 Path.cwd().resolve(): "the working folder", REPOSITORY.resolve(): "the project"}
    for place, what in protected.items():
        if target == place or target in place.parents:
            held = "is" if target == place else "holds"
            raise OutputError(f"{option} {folder}: {held} {what}; give a folder of its own, e.g. results/run1")
    return target


def check_target(folder: Path, overwrite: bool, option: str = "--out") -> Path:
    """The resolved target, or OutputError saying why a run may not write there."""
    target = refuse_protected(folder, option)
    if target.exists() or target.is_symlink():
        if not target.is_dir() or target.is_symlink():
            raise OutputError(f"{option} {folder}: exists and is not a folder")
        if any(target.iterdir()):
            if not is_results_folder(target):
                raise OutputError(f"{option} {folder}: exists and is not a results folder of "
                                  "yafs-safetail; nothing was written (choose another folder)")
            if not overwrite:
                raise OutputError(f"{option} {folder}: holds an earlier run; pass --overwrite to "
                                  "replace it, or choose another folder")
    return target


#: The first line of every lock file and the name of the marker inside every temporary folder
#: this tool makes: only files and folders carrying them are ever removed.
LOCK_MARKER = "yafs-safetail run lock"
STAGING_MARKER = ".yafs-safetail-partial"
PREVIOUS_MARKER = ".yafs-safetail-previous"
_LOCK_ATTEMPTS = 100


@contextlib.contextmanager
def _lock(target: Path, option: str) -> Iterator[None]:
    path = target.parent / f".{target.name}.lock"
    # A few attempts: the lock file may vanish between two opens when a run ends right then.
    # The count is bounded because some folders (e.g. /proc) answer "no such file" to every
    # create, which would otherwise loop for ever.
    for _attempt in range(_LOCK_ATTEMPTS):
        try:
            try:
                descriptor = os.open(path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
                created = True
            except FileExistsError:  # another run's (live or killed), or a file of the user's
                descriptor = os.open(path, os.O_RDWR)
                created = False
        except FileNotFoundError:
            continue  # removed between the two opens by a run that just ended: try again
        except OSError as error:
            raise OSError(f"{option} {target}: cannot write in {target.parent}: {error.strerror}") from None
        handle = os.fdopen(descriptor, "r+")  # held for the whole run
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.close()
            raise OutputError(f"{option} {target}: another run is writing there now "
                              f"(it holds {path}); wait for it or choose another folder") from None
        # The lock file may have been removed by a run that just ended: lock the current one.
        try:
            same = os.stat(path).st_ino == os.fstat(handle.fileno()).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        handle.close()
    else:
        raise OSError(f"{option} {target}: cannot write in {target.parent}: "
                      f"cannot create the lock file {path.name} there")
    content = handle.read()
    # Ours to use and remove: made just now, or carrying the marker (a run that ended or was
    # killed). Anything else, even an empty file, is someone else's: leave it.
    if not created and not content.startswith(LOCK_MARKER):
        handle.close()
        raise OutputError(f"{option} {target}: {path} exists and is not a yafs-safetail lock; "
                          "move it away or choose another folder")
    try:
        handle.seek(0)
        handle.truncate()
        handle.write(f"{LOCK_MARKER}, pid {os.getpid()}\n")
        handle.flush()
        yield
    finally:
        with contextlib.suppress(OSError):
            os.unlink(path)  # ours: created by this run or left by a killed one
        handle.close()


class StagedOutput:
    """The temporary folder of one run and its target (use as a context manager).

    ``with StagedOutput(out_dir, overwrite) as staging: ...write into staging...;
    output.publish()``. Leaving the block without ``publish`` removes the temporary folder and
    keeps the target as it was.
    """

    def __init__(self, out_dir: Path, overwrite: bool = False, option: str = "--out") -> None:
        self.out_dir = Path(out_dir)
        self.overwrite = overwrite
        self.option = option
        self.target = check_target(self.out_dir, overwrite, option)
        self.staging: Path | None = None
        self._stack = contextlib.ExitStack()

    def __enter__(self) -> Path:
        parent = self.target.parent
        try:
            parent.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise OSError(f"{self.option} {self.out_dir}: cannot create {parent}: {error.strerror}") from None
        if not os.access(parent, os.W_OK | os.X_OK):
            raise OSError(f"{self.option} {self.out_dir}: {parent} is not writable")
        with self._stack:
            self._stack.enter_context(_lock(self.target, self.option))
            self._recover_previous()
            check_target(self.out_dir, self.overwrite, self.option)  # again, now that it is ours
            # Temporary folders of earlier runs on this target that were killed outright
            # (SIGKILL, power loss): this tool made them, and no run can be using them now.
            for stale in parent.glob(f".{self.target.name}.partial-*"):
                if (stale / STAGING_MARKER).is_file():
                    shutil.rmtree(stale, ignore_errors=True)
            try:
                self.staging = Path(tempfile.mkdtemp(prefix=f".{self.target.name}.partial-", dir=parent))
                (self.staging / STAGING_MARKER).touch()
            except OSError as error:
                raise OSError(f"{self.option} {self.out_dir}: cannot write in {parent}: {error.strerror}") from None
            self._stack = self._stack.pop_all()
        return self.staging

    def _recover_previous(self) -> None:
        """Undo a publish killed between its two renames: the earlier run, moved aside, goes
        back into place (nothing is lost); the aside folder of a finished publish goes."""
        target = self.target
        for aside in target.parent.glob(f".{target.name}.previous-*"):
            if not (aside / PREVIOUS_MARKER).is_file():
                continue  # not made by this tool: leave it
            earlier = aside / target.name
            if earlier.is_dir() and not (target.exists() or target.is_symlink()):
                os.replace(earlier, target)
            if earlier.exists() and not is_results_folder(target):
                # The earlier run could not go back (something else is at the target now), and
                # the publish did not finish either: keep it where it is rather than lose it.
                logging.getLogger(__name__).warning(
                    "%s: an earlier run is kept in %s (%s holds something else)", self.option,
                    aside, target)
                continue
            shutil.rmtree(aside, ignore_errors=True)

    def publish(self) -> None:
        """Rename the finished run into place; an earlier run there goes only after that."""
        assert self.staging is not None
        target = self.target
        check_target(self.out_dir, self.overwrite, self.option)
        previous = None
        if target.exists():
            previous = Path(tempfile.mkdtemp(prefix=f".{target.name}.previous-", dir=target.parent))
            # A kill before the next rename completes leaves the earlier run here; the next
            # run on this target puts it back (_recover_previous).
            (previous / PREVIOUS_MARKER).touch()
            os.replace(target, previous / target.name)
        (self.staging / STAGING_MARKER).unlink()
        # mkdtemp made the staging folder private (0700) while it was being written; the
        # results folder gets what an ordinary mkdir would give, so that colleagues sharing
        # it can read it. Set before the rename: the folder never appears private.
        os.chmod(self.staging, folder_mode())
        os.replace(self.staging, target)
        self.staging = None
        if previous is not None:
            shutil.rmtree(previous, ignore_errors=True)

    def __exit__(self, exc_type: type[BaseException] | None, error: BaseException | None,
                 traceback: object) -> None:
        try:
            if self.staging is not None:
                shutil.rmtree(self.staging, ignore_errors=True)
                self.staging = None
        finally:
            self._stack.close()
        if isinstance(error, OSError) and error.errno in DISK_FULL_ERRNOS:
            # The writer's own message names neither the folder nor what was kept.
            kept = ("the earlier results there are untouched" if is_results_folder(self.target)
                    else "nothing was left there")
            raise OutputError(f"{self.option} {self.out_dir}: no space left on the device while "
                              f"writing the results; {kept}") from None

"""An entry point run in the test's own process, as its command would run it.

A tiny run in a subprocess spends about 7 of its 10 seconds importing TensorFlow; here it is
imported once per test process. A test uses this where what it checks is the run's files and
output. What only a separate process shows (an exit by signal, a stderr empty from the first
byte, TensorFlow's own start-up notes, fork and kill) stays with ``subprocess``.
"""

from __future__ import annotations

import contextlib
import io
import logging
import os
import signal
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Done:
    """What the command ended with: the fields of ``subprocess.CompletedProcess`` tests read."""

    returncode: int
    stdout: str
    stderr: str


def run_in_process(main: Callable[[Sequence[str] | None], int | None], *args: str | Path) -> Done:
    """``main`` under ``run_cli``, as ``experiments/<script>.py`` runs it; stdout and stderr
    captured; this process's SIGTERM handler, environment and logging set-up are restored
    afterwards, so that later tests in this process see none of the command's."""
    from yafs_safetail.cli import run_cli
    from yafs_safetail.logs import PACKAGE_LOGGER

    previous_handler = signal.getsignal(signal.SIGTERM)
    previous_environment = dict(os.environ)
    root, package = logging.getLogger(), logging.getLogger(PACKAGE_LOGGER)
    previous_root_handlers, previous_package_level = list(root.handlers), package.level
    out, err = io.StringIO(), io.StringIO()
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = run_cli(main, [str(arg) for arg in args])
            except SystemExit as exit_:  # argparse's own errors (--help, a bad choice)
                code = exit_.code if isinstance(exit_.code, int) else 1
    finally:
        signal.signal(signal.SIGTERM, previous_handler)
        os.environ.clear()
        os.environ.update(previous_environment)
        for handler in [h for h in root.handlers if h not in previous_root_handlers]:
            root.removeHandler(handler)
            handler.close()
        package.setLevel(previous_package_level)
    return Done(code, out.getvalue(), err.getvalue())


def run_usecase_here(*args: str | Path) -> Done:
    """``experiments/run_usecase.py ARGS`` in this process."""
    from yafs_safetail.commands import run_usecase

    return run_in_process(run_usecase.main, *args)

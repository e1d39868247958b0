"""Logging: the phases of a run, its ``run.log``, and what the command line shows on stderr.

Every module logs through its own ``logging.getLogger(__name__)``; nothing here runs at
import. The entry points call :func:`configure_logging` once their options are parsed (argparse
errors come first, and a run logs nothing before its checks pass, so bad input stays one
``error:`` line). A :class:`Phase` logs a start line, an end line with its wall time and, when it
has at least :data:`LONG_PHASE_REQUESTS` requests, a line at every 10% of them:

    UC1 SafeTail train: 40% (4000/10000 requests, 6.4 s)

On a terminal a tqdm bar shows the same progress, so the stderr handler leaves the 10% lines
out there (they still go into ``run.log``). :func:`run_log` writes every record of the package
during a run into the run's folder.
"""

from __future__ import annotations

import contextlib
import logging
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from types import TracebackType
from typing import Any, TextIO

#: The package's logger: the parent of every module's logger.
PACKAGE_LOGGER = "yafs_safetail"
#: The YAFS core's debug lines are YAFS's own (one per deployed process and selection), about its
#: event loop rather than the run, so neither stderr nor run.log shows them.
CORE_LOGGER = "yafs_safetail.yafs"
#: A phase with at least this many requests gets a line at every 10% (a shorter one takes
#: about a second: its start and end lines say enough).
LONG_PHASE_REQUESTS = 100
#: Percentage points between two progress lines of a long phase.
PERCENT_STEP = 10
#: Set on the records of the 10% lines, so that a handler can tell them from the others.
PERCENT_ATTRIBUTE = "progress_percent"
#: The run's log file, in its results folder.
RUN_LOG_FILE = "run.log"
#: The name of the stderr handler :func:`configure_logging` installs (to replace, not add to, it).
STDERR_HANDLER = "yafs-safetail-stderr"
RUN_LOG_FORMAT = "%(asctime)s %(levelname)-7s %(name)s: %(message)s"


def verbosity_level(quiet: bool = False, verbose: bool = False) -> int:
    """The stderr level of ``--quiet`` (warnings and errors), the default (progress) and
    ``--verbose`` (debug lines too)."""
    if quiet and verbose:
        raise ValueError("--quiet and --verbose: choose one")
    return logging.WARNING if quiet else logging.DEBUG if verbose else logging.INFO


class _WithoutCoreDebug(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        from_core = record.name == CORE_LOGGER or record.name.startswith(CORE_LOGGER + ".")
        return not (from_core and record.levelno < logging.INFO)


class _WithoutPercentLines(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return not hasattr(record, PERCENT_ATTRIBUTE)


class _StderrFormatter(logging.Formatter):
    """Progress lines as they are and other levels named (``warning: ...``), like the tool's
    other messages; with ``--verbose`` every line also gets its time and module."""

    def __init__(self, verbose: bool) -> None:
        super().__init__()
        self.verbose = verbose

    def format(self, record: logging.LogRecord) -> str:
        message = record.getMessage()
        if record.exc_info:
            message += "\n" + self.formatException(record.exc_info)
        level = record.levelname.lower()
        if self.verbose:
            clock = time.strftime("%H:%M:%S", time.localtime(record.created))
            return f"{clock} {level:<7} {record.name}: {message}"
        return message if record.levelno == logging.INFO else f"{level}: {message}"


class _StderrHandler(logging.StreamHandler):
    """Writes to whatever ``sys.stderr`` is when a record comes (a test's capture, a redirection),
    never to a stream replaced since."""

    def __init__(self) -> None:
        super().__init__(sys.stderr)

    @property
    def stream(self) -> TextIO:
        return sys.stderr

    @stream.setter
    def stream(self, value: TextIO) -> None:
        pass  # always the current sys.stderr


def configure_logging(level: int, stream: TextIO | None = None) -> None:
    """Show the package's records of ``level`` and above on ``stream`` (default: the current
    ``sys.stderr``, whatever it is when a record comes).

    For entry points only, after their options are parsed. Calling it again replaces the
    handler it installed (tests call entry points in one process). Other libraries keep the
    root logger's level (warnings), whatever ``level`` is.
    """
    root = logging.getLogger()
    for handler in [h for h in root.handlers if h.name == STDERR_HANDLER]:
        root.removeHandler(handler)
    handler = _StderrHandler() if stream is None else logging.StreamHandler(stream)
    handler.name = STDERR_HANDLER
    handler.setLevel(level)
    handler.setFormatter(_StderrFormatter(verbose=level < logging.INFO))
    handler.addFilter(_WithoutCoreDebug())
    if is_terminal(sys.stderr if stream is None else stream):
        handler.addFilter(_WithoutPercentLines())  # the bars show that progress
    root.addHandler(handler)
    logging.getLogger(PACKAGE_LOGGER).setLevel(min(level, logging.INFO))


def is_terminal(stream: TextIO) -> bool:
    """True when ``stream`` is a terminal (progress bars, not 10% lines)."""
    try:
        return stream.isatty()
    except (AttributeError, ValueError):  # no isatty, or already closed
        return False


@contextlib.contextmanager
def run_log(path: Path) -> Iterator[Path]:
    """While the block runs, write every record of the package (debug included) to ``path``.

    The package logger is lowered to DEBUG for the block, whatever the entry point chose for
    stderr, so that a run's log does not depend on ``--quiet`` or ``--verbose``. Processes
    forked during the block inherit the handler and append to the same file.
    """
    package = logging.getLogger(PACKAGE_LOGGER)
    handler = logging.FileHandler(path, mode="a", encoding="utf-8")
    handler.setLevel(logging.DEBUG)
    handler.setFormatter(logging.Formatter(RUN_LOG_FORMAT))
    handler.addFilter(_WithoutCoreDebug())
    previous_level = package.level
    package.setLevel(logging.DEBUG)
    package.addHandler(handler)
    try:
        yield path
    finally:
        package.removeHandler(handler)
        package.setLevel(previous_level)
        handler.close()


class Phase:
    """One logged phase of a run (use as a context manager).

    ``LABEL: start (N requests)``, for a long phase ``LABEL: 40% (400/1000 requests, 3.2 s)`` at
    every 10%, and ``LABEL: done (N requests, 12.3 s)``; a phase left by an exception logs where it
    stopped instead. With ``bar`` a tqdm bar on stderr shows the progress as well.

    Args:
        label: names the phase in every line, e.g. ``"UC1 SafeTail train"``.
        total: the requests the phase runs (None: a phase that only takes time, no counts).
        bar: also show a tqdm progress bar on stderr.
        logger: the logger of the module the phase belongs to (default: this module's).
        unit: what ``total`` counts.
    """

    def __init__(self, label: str, total: int | None = None, *, bar: bool = False,
                 logger: logging.Logger | None = None, unit: str = "requests") -> None:
        self.label = label
        self.total = total
        self.unit = unit
        self.done = 0
        self.logger = logger or logging.getLogger(__name__)
        self._want_bar = bar and total is not None
        self._bar: Any = None
        self._lines_given = 0  # 10% lines logged so far
        self._started_s = time.perf_counter()

    @property
    def long(self) -> bool:
        return self.total is not None and self.total >= LONG_PHASE_REQUESTS

    @property
    def elapsed_s(self) -> float:
        return time.perf_counter() - self._started_s

    def __enter__(self) -> Phase:
        self._started_s = time.perf_counter()
        counted = "" if self.total is None else f" ({self.total} {self.unit})"
        self.logger.info("%s: start%s", self.label, counted)
        if self._want_bar:
            from tqdm import tqdm

            self._bar = tqdm(total=self.total, desc=self.label, unit="req", file=sys.stderr, leave=False)
        return self

    def next_line_at(self, done: int) -> int:
        """The count after ``done`` at which the next line is due (the total when none is), so
        that a simulation can pause exactly there."""
        assert self.total is not None
        if not self.long:
            return self.total
        steps = 100 // PERCENT_STEP
        next_step = done * steps // self.total + 1
        return min(self.total, -(-next_step * self.total // steps))  # ceil: the first count past it

    def update(self, done: int) -> None:
        """``done`` of the phase's requests are complete."""
        self.done = done
        if self._bar is not None:
            self._bar.update(done - self._bar.n)
        if not self.long or self.total is None or done >= self.total:
            return
        reached = done * (100 // PERCENT_STEP) // self.total
        if reached > self._lines_given:
            self._lines_given = reached
            self.logger.info("%s: %d%% (%d/%d %s, %.1f s)", self.label, done * 100 // self.total,
                             done, self.total, self.unit, self.elapsed_s,
                             extra={PERCENT_ATTRIBUTE: reached * PERCENT_STEP})

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 traceback: TracebackType | None) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None
        if exc_type is None:
            counted = "" if self.total is None else f"{self.total} {self.unit}, "
            self.logger.info("%s: done (%s%.1f s)", self.label, counted, self.elapsed_s)
        else:  # the error itself is the entry point's one line; this says how far the phase got
            counted = "" if self.total is None else f"{self.done}/{self.total} {self.unit}, "
            self.logger.info("%s: stopped (%s%.1f s)", self.label, counted, self.elapsed_s)

"""The run's figures, drawn in a process forked before TensorFlow loads while this one writes.

Drawing the figures (matplotlib's import included) and writing the results files each take a
few seconds at the end of a run; neither needs the other, so they run side by side. The process
imports the figure module at once and then waits, so its import overlaps TensorFlow's and the
simulations instead of the run's end. It draws exactly what :func:`~yafs_safetail.results.
figures.run_figures.draw_figures` draws in the main process (the same code on the same rows), and it never touches
TensorFlow: it is forked before TensorFlow is imported, as the baseline workers are.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Sequence
from multiprocessing.connection import Connection
from pathlib import Path
from typing import TYPE_CHECKING

from yafs_safetail.runs.workers import ForkedWorker, become_worker, can_fork, send_outcome

if TYPE_CHECKING:
    import pandas as pd

    from yafs_safetail.results import RunMetadata

log = logging.getLogger(__name__)


def _figures_main(channel: Connection) -> None:
    become_worker()
    with contextlib.suppress(Exception):  # the import this process is here to pay, while the run computes
        import yafs_safetail.results.figures.run_figures  # noqa: F401
    try:
        folder, requests, run, formats = channel.recv()
    except EOFError:  # the parent is gone (it never closes the pipe first): nothing to draw
        return

    def draw() -> list[Path]:
        from yafs_safetail.results.figures.run_figures import draw_figures

        return draw_figures(folder, requests, run, formats=formats)

    send_outcome(channel, draw, "figures process")


class FiguresWorker(ForkedWorker):
    """A forked process that draws one run's figures when given its rows."""

    def __init__(self) -> None:
        super().__init__(_figures_main, (), "yafs-safetail-figures", duplex=True)
        log.debug("figures process %s started", self._process.pid)

    def draw(self, folder: Path, requests: pd.DataFrame, run: RunMetadata, formats: Sequence[str]) -> None:
        """Start drawing ``folder``'s figures from the run's rows (returns at once).

        Raises:
            WorkerDied: the process has died (killed) before it was given the rows.
        """
        try:
            self._channel.send((folder, requests, run, tuple(formats)))
        except BrokenPipeError:  # its end is closed: it died, and wait() says how
            self.wait()

    def wait(self) -> list[Path]:
        """The written figure files, once drawn; re-raises the drawing's exception.

        Raises:
            WorkerDied: the process ended without a reply (killed).
        """
        return list(self._outcome(f"the figures process (pid {self._process.pid})", "the run stopped"))


def start_figures_worker(workers: int) -> FiguresWorker | None:
    """A figures process when the run may use more than one process (``--workers`` ≥ 2) and can
    fork (:func:`~yafs_safetail.runs.workers.can_fork`); else None: the main process draws them
    after writing, as before."""
    return FiguresWorker() if workers >= 2 and can_fork() else None

"""How a run stops on SIGTERM: :class:`Terminated` and the handler that raises it.

Standard library only. The command-line front (``cli.run_cli``) installs the handler in the
command's process and ``runs.engines`` in every worker it starts; both read
:func:`terminating` to tell a SIGTERM from whatever exception it surfaced as. The library's
layers below the commands import this module, never ``cli``.
"""

from __future__ import annotations

import threading
from types import FrameType


class Terminated(KeyboardInterrupt):
    """SIGTERM, turned into an exception so that every ``finally`` runs: workers stop and
    temporary folders go, exactly as for Ctrl-C."""


_terminating = threading.Event()


def raise_terminated(signum: int, frame: FrameType | None) -> None:
    """The SIGTERM handler of every process of a run (the command's and its workers')."""
    _terminating.set()
    raise Terminated()


def terminating() -> bool:
    """Whether this process has received SIGTERM since :func:`clear_terminating`."""
    return _terminating.is_set()


def clear_terminating() -> None:
    """Forget an earlier SIGTERM (a new command starts in the same process, as tests do)."""
    _terminating.clear()

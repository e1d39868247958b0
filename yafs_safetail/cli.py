"""Command-line plumbing shared by every entry point.

Bad input must end in one line naming the file, the field and what is wrong, a non-zero exit
and no traceback. Every loader in the package raises a ``ValueError`` subclass for bad input
and every writer raises ``OSError`` for an unwritable place, so one wrapper turns both into
that line. Set ``YAFS_SAFETAIL_DEBUG=1`` to see the traceback instead (for bug reports).
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from types import FrameType

EXIT_BAD_INPUT = 2
EXIT_TERMINATED = 128 + signal.SIGTERM


class Terminated(KeyboardInterrupt):
    """SIGTERM, turned into an exception so that every ``finally`` runs: workers stop and
    temporary folders go, exactly as for Ctrl-C."""


def _raise_terminated(signum: int, frame: FrameType | None) -> None:
    raise Terminated()


def run_cli(main: Callable[[Sequence[str] | None], int | None], argv: Sequence[str] | None = None) -> int:
    """Run ``main(argv)`` and turn input errors into one line on stderr and exit code 2.

    Args:
        main: the entry point; returns an exit code or None for success.
        argv: the arguments (``None``: ``sys.argv[1:]``).

    Returns:
        The process exit code.
    """
    # TensorFlow's C++ start-up notes (CPU features, oneDNN) say nothing about the run; an
    # explicit TF_CPP_MIN_LOG_LEVEL in the environment still wins.
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        code = main(argv)
    except (ValueError, OSError) as error:
        if os.environ.get("YAFS_SAFETAIL_DEBUG"):
            raise
        message = " ".join(str(error).split()) or type(error).__name__
        print(f"error: {message}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except Terminated:
        print("error: terminated; no partial results were kept", file=sys.stderr)
        return EXIT_TERMINATED
    except KeyboardInterrupt:
        print("error: interrupted; no partial results were kept", file=sys.stderr)
        return 130
    return 0 if code is None else int(code)


def main(argv: Sequence[str] | None = None) -> int:
    """``yafs-safetail``: points to the real entry points."""
    print(
        "yafs-safetail: run `python experiments/run_usecase.py --uc 1` "
        "or `python -m yafs_safetail.figures DIR`; see README.md"
    )
    return 0

"""Command-line plumbing shared by every entry point.

Bad input must end in one line naming the file, the field and what is wrong, a non-zero exit
and no traceback. Every loader in the package raises a ``ValueError`` subclass for bad input
and every writer raises ``OSError`` for an unwritable place, so one wrapper turns both into
that line. Set ``YAFS_SAFETAIL_DEBUG=1`` to see the traceback instead (for bug reports).
"""

from __future__ import annotations

import argparse
import gc
import importlib
import os
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from contextvars import ContextVar
from pathlib import Path
from typing import Any, NoReturn

from yafs_safetail import __version__
from yafs_safetail.logs import configure_logging, verbosity_level

# The argument types and the SIGTERM handling live below every package (the library imports them
# from there, never from here); the commands and the scripts outside the package import them
# from here too.
from yafs_safetail.settings.parse import (  # noqa: F401  (re-exported)
    distinct_int_list,
    int_list,
    load_list,
    non_negative_float,
    non_negative_int,
    positive_float,
    positive_float_list,
    positive_int,
    user_path,
)
from yafs_safetail.stopping import (  # noqa: F401  (re-exported)
    Terminated,
    clear_terminating,
    raise_terminated,
    terminating,
)

EXIT_BAD_INPUT = 2
EXIT_TERMINATED = 128 + signal.SIGTERM
EXIT_BROKEN_PIPE = 128 + signal.SIGPIPE


class UsageError(ValueError):
    """A bad command-line argument (argparse's own message, reported as one line)."""


#: The name of the console subcommand being run (``yafs-safetail run``), set by :func:`main`
#: while it runs; None when a script is run directly.
_command_prog: ContextVar[str | None] = ContextVar("yafs_safetail_command_prog", default=None)


#: What ``--version`` prints, on every command: the package's version, the one run.json records.
VERSION_LINE = f"yafs-safetail {__version__}"


class ArgumentParser(argparse.ArgumentParser):
    """argparse that reports bad arguments as :func:`run_cli`'s one-line error (exit 2, no
    usage dump), for every entry point.

    Run as a ``yafs-safetail`` subcommand, the parser's usage and help show that command
    (``yafs-safetail run``) instead of the script's own ``prog``, since that is what the user
    typed; run directly, a script keeps its own name. Every parser with ``--help`` also has
    ``--version``, and an option declared with ``type=Path`` (by hand or by
    ``settings.options.add_options``) reads its value through :func:`user_path`.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        command = _command_prog.get()
        if command is not None:
            self.prog = command
        # argparse looks an option's type up in this registry before calling it, so the one
        # line covers every path option of every command, and the argument groups (which
        # share the parser's registry) too.
        self.register("type", Path, user_path)
        if self.add_help:  # not the helper parsers that pick a few options out of the rest
            self.add_argument("--version", action="version", version=VERSION_LINE,
                              help="print the package's version and exit")

    def error(self, message: str) -> NoReturn:
        raise UsageError(message)


#: Options that are not settings: where a command writes, what it reads besides its settings and
#: how many processes it uses, never what it computes. A setting's option comes from its
#: declaration (``settings.options.add_options``), never from here (tests/test_option_sources.py).
PLUMBING_FLAGS = ("--out", "--overwrite", "--grid", "--apply", "--workers", "--criterion")


def add_plumbing(parser: argparse._ActionsContainer, flag: str, **keywords: Any) -> None:
    """Add one option that is not a setting (:data:`PLUMBING_FLAGS`, or a positional input such as
    a results folder).

    Raises:
        TypeError: any other option: a setting is declared (``settings.declare.setting``).
    """
    if flag.startswith("-") and flag not in PLUMBING_FLAGS:
        raise TypeError(f"{flag}: not a plumbing option; declare it as a setting (settings.declare)")
    parser.add_argument(flag, **keywords)


def add_verbosity_options(parser: argparse.ArgumentParser) -> None:
    """``--quiet`` and ``--verbose`` (mutually exclusive), for every entry point."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("-q", "--quiet", action="store_true",
                       help="warnings and errors only on stderr, no progress lines or bars; on "
                            "stdout only the results folder's path")
    group.add_argument("-v", "--verbose", action="store_true",
                       help="also debug lines: the configuration, each part's timing, worker processes")


def print_result(args: argparse.Namespace, folder: str | os.PathLike[str], report: str) -> None:
    """A command's last words on stdout, once its folder is written.

    Args:
        args: the parsed options (their ``quiet``).
        folder: where the command wrote its results.
        report: what it prints without ``--quiet`` (its table, then where it wrote).

    With ``--quiet`` only ``folder``'s path is printed, so that a script can take it as it is
    (``out=$(yafs-safetail run -q ...)``); the report is in the folder's own files anyway.
    """
    if args.quiet:
        print(folder)
    else:
        print(report, end="" if report.endswith("\n") else "\n")


def configure_verbosity(args: argparse.Namespace) -> int:
    """Set up stderr logging as ``--quiet`` / ``--verbose`` ask; returns the stderr level.

    Called by each entry point right after parsing its options, so that a bad option is still
    the only line on stderr.
    """
    level = verbosity_level(quiet=args.quiet, verbose=args.verbose)
    configure_logging(level)
    return level


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
        signal.signal(signal.SIGTERM, raise_terminated)
    clear_terminating()
    try:
        code = main(argv)
    except BrokenPipeError:
        # The reader went away (``... | head``): stop without a word and with the status a
        # Unix tool killed by SIGPIPE has, since what was left to do after the print is not
        # done. stdout is pointed at /dev/null so that Python's flush at exit does not fail
        # on the closed pipe again.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    except BaseException as error:
        # SIGTERM raised inside library code may come out as another exception (an import
        # interrupted by it becomes an ImportError): the flag says what really happened.
        # A note added on the way out (a run's kept training checkpoint) ends the same line.
        notes = "".join(f"; {note}" for note in getattr(error, "__notes__", ()))
        if isinstance(error, Terminated) or terminating():
            print(f"error: terminated; no partial results were kept{notes}", file=sys.stderr)
            return EXIT_TERMINATED
        if isinstance(error, KeyboardInterrupt):
            print(f"error: interrupted; no partial results were kept{notes}", file=sys.stderr)
            return 130
        if not isinstance(error, ValueError | OSError) or os.environ.get("YAFS_SAFETAIL_DEBUG"):
            raise
        message = " ".join(str(error).split()) or type(error).__name__
        print(f"error: {message}", file=sys.stderr)
        return EXIT_BAD_INPUT
    return 0 if code is None else int(code)


def exit_process(code: int) -> NoReturn:
    """End a command's process with ``code``, without the interpreter's last full collection.

    Only for a process that is about to end (a script's ``__main__``, the console command):
    every file is written and closed by then. With TensorFlow loaded, the collection Python runs
    while shutting down took 1.5-2 s after the last result was written; frozen objects are
    skipped by it (``gc.freeze``), and there is nothing left to release once the process ends.
    """
    gc.freeze()
    gc.disable()
    sys.exit(code)


def run_script(main: Callable[[Sequence[str] | None], int | None]) -> NoReturn:
    """What ``experiments/<script>.py`` does as ``__main__``: ``run_cli(main)``, then exit."""
    exit_process(run_cli(main))


#: ``yafs-safetail <command>``: the module under yafs_safetail/commands/ that runs it (each has
#: ``main(argv)``) and what it does. ``experiments/<module>.py`` in the checkout is the same
#: command for those that run experiments; the two that only read results folders run as
#: ``python -m yafs_safetail.commands.<module>`` too.
SCRIPT_COMMANDS = {
    "run": ("run_usecase", "train SafeTail and compare it on one use case"),
    "reproduce": ("reproduce_all", "every use case over several seeds, one report"),
    "campaign": ("campaign", "a grid of runs, each computed once, resumable"),
    "calibrate": ("calibrate", "fit the unpublished world parameters"),
    "learning-rate": ("choose_learning_rate", "choose the paper preset's learning rates by the rule"),
    "compare": ("compare_runs", "two results folders side by side, B / A with intervals"),
    "sweep": ("load_sweep", "many users: every method against the offered load"),
    "mechanism": ("training_mechanism", "many users: each SafeTail's copies and queues over its training"),
    "failure-sweep": ("failure_sweep", "servers that fail: success, p99 and energy per request"),
    "mobility-sweep": ("mobility_sweep", "a user who moves: every method's p99 and servers against speed"),
    "score": ("score_policy", "your policy in every world, beside SafeTail, with paired intervals"),
    "figures": ("figures", "redraw a results folder's figures"),
    "feasibility": ("feasibility", "what any policy could reach in the worlds of run folders"),
}
USAGE = "usage: yafs-safetail {" + ",".join(SCRIPT_COMMANDS) + "} [options]   (each takes --help)"


def invocation(script: str) -> list[str]:
    """The words that started this command, as a run records its command line: ``yafs-safetail
    run`` under the console command, otherwise ``python <script>`` (``experiments/...``)."""
    command = _command_prog.get()
    return command.split() if command is not None else ["python", script]


def _command_main(module_name: str) -> Callable[[Sequence[str] | None], int | None]:
    # Imported only now: ``yafs-safetail --help`` loads no command, and each command module
    # imports nothing heavy before its arguments are checked.
    module = importlib.import_module(f"yafs_safetail.commands.{module_name}")
    command_main: Callable[[Sequence[str] | None], int | None] = module.main
    return command_main


def _listing() -> str:
    """The usage line and one line per subcommand."""
    lines = [USAGE, f"  {'--version':<14} print the package's version ({__version__})"]
    # No script paths: an installed (wheel) user has no experiments/ folder.
    lines += [f"  {name:<14} {what}" for name, (module, what) in SCRIPT_COMMANDS.items()]
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    """``yafs-safetail COMMAND [options]``: one console command for the project's tools.

    Args:
        argv: the arguments (``None``: ``sys.argv[1:]``).

    Returns:
        The process exit code: 0 for ``--help``, 2 (a usage error, as argparse has it) without
        a command or with an unknown one, otherwise the command's own.
    """
    args = list(sys.argv[1:] if argv is None else argv)
    if args[:1] in (["-h"], ["--help"]):
        print(_listing(), end="")
        return 0
    if args[:1] == ["--version"]:
        print(VERSION_LINE)
        return 0
    if not args:
        # Nothing asked is a usage error, not a success: a script calling the command without
        # its arguments must not go on as if it had run. The listing goes to stderr, with the
        # error, so that stdout stays empty.
        print(_listing() + "error: no command given; each command takes --help", file=sys.stderr)
        return EXIT_BAD_INPUT
    command, rest = args[0], args[1:]
    if command not in SCRIPT_COMMANDS:
        print(f"error: unknown command {command!r}; {USAGE}", file=sys.stderr)
        return EXIT_BAD_INPUT
    # Every parser the command builds shows "yafs-safetail COMMAND" as its prog (ArgumentParser).
    token = _command_prog.set(f"yafs-safetail {command}")
    try:
        return run_cli(_command_main(SCRIPT_COMMANDS[command][0]), rest)
    finally:
        _command_prog.reset(token)


def console_main() -> NoReturn:
    """The ``yafs-safetail`` console command: :func:`main`, then :func:`exit_process`."""
    exit_process(main())


if __name__ == "__main__":
    # ``python -m yafs_safetail.cli`` runs this file as __main__, a second copy of the module:
    # the package's copy, the one the scripts' parsers read the command name from, must run.
    from yafs_safetail.cli import console_main as package_console_main

    package_console_main()

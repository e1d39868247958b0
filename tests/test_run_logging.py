"""Progress and logs as a user sees them: phase and 10% lines on a pipe, bars on a terminal,
``--quiet`` / ``--verbose``, ``run.log`` in every results folder (and none after a failed run),
and the one-line error contract with any verbosity.

Successful runs import TensorFlow (a few seconds each), so they are few and tiny (200 training
and 80 test requests per method).
"""

from __future__ import annotations

import fcntl
import io
import json
import logging
import os
import pty
import re
import struct
import subprocess
import sys
import termios
import threading
from pathlib import Path

import pytest

from yafs_safetail.logs import (
    PACKAGE_LOGGER,
    RUN_LOG_FILE,
    STDERR_HANDLER,
    Phase,
    configure_logging,
)
from yafs_safetail.runs.experiment import REPOSITORY, ExperimentConfig, run_experiment

SCRIPT = REPOSITORY / "experiments" / "run_usecase.py"
TINY = ["--uc", "1", "--seed", "4", "--steps-scale", "0.02", "--redundancy", "1", "--no-figures"]
PERCENT_LINE = re.compile(r"^UC1 SafeTail train: (\d+)% \((\d+)/200 requests, \d+\.\d s\)$")
PHASES = ("UC1 SafeTail setup", "UC1 SafeTail train", "UC1 SafeTail test", "UC1 other methods test",
          "UC1 writing results")


def run_script(*args: str | Path) -> subprocess.CompletedProcess[str]:
    """The script with stdout and stderr on pipes (not a terminal)."""
    env = {k: v for k, v in os.environ.items() if k != "YAFS_SAFETAIL_DEBUG"}
    return subprocess.run([sys.executable, str(SCRIPT), *map(str, args)], cwd=REPOSITORY, env=env,
                          capture_output=True, text=True, timeout=600)


def assert_one_error_line(done: subprocess.CompletedProcess[str], *fragments: str) -> None:
    assert done.returncode == 2, done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), done.stderr
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


@pytest.fixture(scope="module")
def piped(tmp_path_factory: pytest.TempPathFactory) -> tuple[subprocess.CompletedProcess[str], Path]:
    out = tmp_path_factory.mktemp("piped") / "run"
    done = run_script(*TINY, "--out", out, "--workers", "2")
    assert done.returncode == 0, done.stderr
    return done, out


def test_piped_stderr_has_a_line_per_phase_and_every_ten_percent(piped) -> None:
    done, _ = piped
    lines = done.stderr.splitlines()
    assert "\r" not in done.stderr  # no progress bar
    for phase in PHASES:
        assert any(re.match(rf"^{re.escape(phase)}[^:]*: start", line) for line in lines), phase
        assert any(re.match(rf"^{re.escape(phase)}[^:]*: done \(.*\d+\.\d s\)$", line) for line in lines), phase
    percents = [int(m.group(1)) for m in map(PERCENT_LINE.match, lines) if m]
    assert percents == [10, 20, 30, 40, 50, 60, 70, 80, 90]
    # The line at 40% counts the requests done exactly there.
    assert "UC1 SafeTail train: 40% (80/200 requests," in done.stderr
    assert "UC1 SafeTail test: start (80 requests)" in done.stderr  # short phase: no 10% lines
    assert not any(line.startswith("UC1 SafeTail test: ") and "%" in line for line in lines)
    # Default verbosity: no debug lines, and the results still go to stdout.
    assert "debug" not in done.stderr and "configuration:" not in done.stderr
    assert "| SafeTail |" in done.stdout and "results:" in done.stdout


def test_run_log_records_the_command_the_settings_and_every_phase(piped) -> None:
    done, out = piped
    log = (out / RUN_LOG_FILE).read_text()
    run = json.loads((out / "run.json").read_text())
    assert run["command"] in log and f"yafs-safetail {run['package_version']}" in log
    assert "preset paper, seed 4" in log and "200 training requests, 80 test requests per method" in log
    for phase in PHASES:
        assert re.search(rf"INFO +\S+: {re.escape(phase)}[^:]*: start", log), phase
        assert re.search(rf"INFO +\S+: {re.escape(phase)}[^:]*: done \(.*\d+\.\d s\)", log), phase
    assert re.search(r"INFO +\S+: UC1 run: done \(\d+\.\d s\)", log)
    # The whole record, whatever stderr showed: the configuration and the timings too.
    assert "DEBUG" in log and "configuration: use_case=1" in log and "time (s): setup" in log
    # Every line has a date and time.
    assert all(re.match(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3} [A-Z]+ ", line) for line in log.splitlines())


def test_quiet_prints_no_progress_but_the_run_log_is_complete(tmp_path: Path) -> None:
    out = tmp_path / "run"
    done = run_script(*TINY, "--out", out, "--workers", "1", "--quiet")
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    log = (out / RUN_LOG_FILE).read_text()
    assert "UC1 SafeTail train: 50% (100/200 requests" in log and "UC1 SafeTail test: done" in log


def test_verbose_adds_debug_lines(tmp_path: Path) -> None:
    out = tmp_path / "run"
    done = run_script(*TINY, "--out", out, "--workers", "2", "--verbose")
    assert done.returncode == 0, done.stderr
    debug = [line for line in done.stderr.splitlines() if " debug " in line]
    for what in ("configuration: use_case=1", "time (s): setup", "worker process", "Oracle test: 80 requests"):
        assert any(what in line for line in debug), what
    assert any(re.search(r"worker process \d+ started: Oracle, Rand-1", line) for line in debug)
    assert any(re.search(r"worker process \d+ ended: ", line) for line in debug)
    # Verbose lines name their time and module; the phases are still there.
    assert re.search(r"^\d\d:\d\d:\d\d info +yafs_safetail\.runs\.training: UC1 SafeTail train: done",
                     done.stderr, re.MULTILINE)
    # The YAFS core's own debug lines (its event loop) stay out.
    assert "Added control process" not in done.stderr and "Activating" not in done.stderr


def test_on_a_terminal_bars_replace_the_ten_percent_lines(tmp_path: Path) -> None:
    out = tmp_path / "run"
    controller, terminal = pty.openpty()
    # A terminal of 24 x 100 characters (a new pty has 0 columns, where tqdm draws nothing).
    fcntl.ioctl(terminal, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))
    env = {k: v for k, v in os.environ.items() if k != "YAFS_SAFETAIL_DEBUG"}
    process = subprocess.Popen([sys.executable, str(SCRIPT), *TINY, "--out", str(out), "--workers", "1"],
                               cwd=REPOSITORY, env=env, stdout=subprocess.DEVNULL, stderr=terminal)
    os.close(terminal)
    received = bytearray()

    def drain() -> None:  # a full terminal buffer would block the run
        while True:
            try:
                chunk = os.read(controller, 65536)
            except OSError:  # the run ended and closed its side
                return
            if not chunk:
                return
            received.extend(chunk)

    reader = threading.Thread(target=drain, daemon=True)
    reader.start()
    assert process.wait(timeout=600) == 0, received.decode(errors="replace")
    reader.join(timeout=30)
    os.close(controller)
    shown = received.decode(errors="replace")
    assert "UC1 SafeTail train: start (200 requests)" in shown and "UC1 SafeTail train: done" in shown
    assert re.search(r"UC1 SafeTail train: +\d+%\|.*\| *\d+/200 \[", shown)  # tqdm's bar
    assert not re.search(r"UC1 SafeTail train: \d+% \(", shown)
    assert "UC1 SafeTail train: 50% (100/200 requests" in (out / RUN_LOG_FILE).read_text()


@pytest.mark.parametrize("verbosity", [[], ["--verbose"], ["--quiet"]])
@pytest.mark.parametrize(("args", "fragments"), [
    (["--redundancy", "1,9"], ["--redundancy", "x=9"]),
    (["--topology", "/nonexistent/topology.json"], ["topology.json"]),
    (["--steps-scale", "0.01"], ["fewer than κ"]),
])
def test_bad_input_is_one_line_with_any_verbosity(tmp_path: Path, verbosity, args, fragments) -> None:
    done = run_script("--uc", "1", "--out", tmp_path / "run", *args, *verbosity)
    assert_one_error_line(done, *fragments)
    assert list(tmp_path.iterdir()) == []


def test_quiet_and_verbose_together_are_one_error_line(tmp_path: Path) -> None:
    done = run_script(*TINY, "--out", tmp_path / "run", "--quiet", "--verbose")
    assert_one_error_line(done, "--verbose", "--quiet")
    assert list(tmp_path.iterdir()) == []


def test_a_failed_run_leaves_no_run_log(tmp_path: Path) -> None:
    topology = json.loads((REPOSITORY / "topologies" / "paper_5servers.json").read_text())
    for link in topology["link"]:
        link["BW"] = 0.0005  # 4 kbit/s: no request completes before the next is due
    slow = tmp_path / "slow.json"
    slow.write_text(json.dumps(topology))
    out = tmp_path / "run"
    done = run_script(*TINY, "--topology", slow, "--placement", REPOSITORY / "placements" / "paper_5servers.json",
                      "--out", out, "--workers", "1")
    assert done.returncode == 2, done.stderr
    lines = done.stderr.splitlines()
    # The run got past its checks, so its phases were shown; the error is the last line, and once.
    assert any(line.startswith("UC1 SafeTail train: start") for line in lines)
    assert any(line.startswith("UC1 SafeTail train: stopped") for line in lines)
    assert lines[-1].startswith("error: ") and "step_interval_s=60" in lines[-1]
    assert sum(line.startswith("error: ") for line in lines) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["slow.json"]  # no folder, no staging, no log


def test_run_log_in_process_without_any_logging_set_up(tmp_path: Path) -> None:
    """A library caller (a campaign worker, a notebook) gets run.log too, and the package's
    logger is left as it was."""
    package = logging.getLogger(PACKAGE_LOGGER)
    level = package.level
    run_experiment(ExperimentConfig(use_case=1, seed=2, out_dir=tmp_path / "run", steps_scale=0.02,
                                    redundancy_levels=(1,), figures=False, progress=False, workers=1,
                                    command="in-process"))
    log = (tmp_path / "run" / RUN_LOG_FILE).read_text()
    assert "yafs-safetail" in log and ": in-process" in log and "UC1 other methods test: done" in log
    assert package.level == level and not package.handlers


def test_phase_lines_at_every_ten_percent_and_where_to_pause(caplog: pytest.LogCaptureFixture) -> None:
    logger = logging.getLogger("yafs_safetail.tests")
    with caplog.at_level(logging.INFO, logger="yafs_safetail.tests"):
        with Phase("long", 1000, logger=logger) as phase:
            pauses = []
            done = 0
            while done < 1000:
                done = phase.next_line_at(done)
                pauses.append(done)
                phase.update(done)
        with Phase("short", 99, logger=logger) as short:
            assert short.next_line_at(0) == 99
            short.update(50)
        with pytest.raises(KeyError), Phase("broken", 300, logger=logger) as broken:
            broken.update(120)
            raise KeyError("on purpose")
    assert pauses == list(range(100, 1001, 100))
    messages = [r.getMessage() for r in caplog.records]
    assert messages[0] == "long: start (1000 requests)"
    assert [m.split(" (")[0] for m in messages[1:10]] == [f"long: {p}%" for p in range(10, 100, 10)]
    assert re.match(r"^long: done \(1000 requests, \d+\.\d s\)$", messages[10])
    assert messages[11] == "short: start (99 requests)"  # below LONG_PHASE_REQUESTS: no 10% lines
    assert re.match(r"^short: done \(99 requests, \d+\.\d s\)$", messages[12])
    assert messages[13] == "broken: start (300 requests)"
    # One update past several tenths gives one line, with the share actually done.
    assert messages[14].startswith("broken: 40% (120/300 requests, ")
    assert len(messages) == 16
    assert re.match(r"^broken: stopped \(120/300 requests, \d+\.\d s\)$", messages[-1])


def test_stderr_format_per_verbosity_and_the_terminal_filter() -> None:
    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    logger = logging.getLogger("yafs_safetail.tests")
    root = logging.getLogger()
    package_level = logging.getLogger(PACKAGE_LOGGER).level
    try:
        for level, stream in ((logging.INFO, io.StringIO()), (logging.WARNING, io.StringIO()),
                              (logging.DEBUG, io.StringIO()), (logging.INFO, Terminal())):
            configure_logging(level, stream)
            assert [h.name for h in root.handlers].count(STDERR_HANDLER) == 1  # replaced, not added
            with Phase("p", 100, logger=logger) as phase:
                phase.update(50)
            logger.debug("a detail")
            logger.warning("mind this")
            logging.getLogger("yafs_safetail.yafs.core").debug("YAFS's own")
            lines = stream.getvalue().splitlines()
            if level == logging.WARNING:
                assert lines == ["warning: mind this"]
            elif level == logging.DEBUG:
                assert len(lines) == 5 and lines[3].endswith("debug   yafs_safetail.tests: a detail")
                assert re.match(r"^\d\d:\d\d:\d\d info +yafs_safetail\.tests: p: 50% \(50/100", lines[1])
            elif isinstance(stream, Terminal):  # a bar shows the progress: no 10% line
                assert [line.split(" (")[0] for line in lines] == ["p: start", "p: done", "warning: mind this"]
            else:
                assert [line.split(" (")[0] for line in lines] == ["p: start", "p: 50%", "p: done",
                                                                    "warning: mind this"]
    finally:
        for handler in [h for h in root.handlers if h.name == STDERR_HANDLER]:
            root.removeHandler(handler)
        logging.getLogger(PACKAGE_LOGGER).setLevel(package_level)


CAMPAIGN = REPOSITORY / "experiments" / "campaign.py"


def test_a_quiet_campaign_shows_only_its_failed_run(tmp_path: Path) -> None:
    # A policy that fails only when a run asks it to choose: the grid's own check (which loads
    # the class) passes, and that one run fails.
    (tmp_path / "boom.py").write_text(
        "from yafs_safetail.methods import Policy\n\n\nclass Boom(Policy):\n"
        "    def choose(self, observation):\n        raise RuntimeError('boom')\n")
    grid = tmp_path / "grid.toml"
    grid.write_text('[base]\nsteps_scale = 0.013\nfigures = false\n[axes]\n'
                    'methods = [[], ["boom.py:Boom"]]\n')
    out = tmp_path / "campaign"
    command = [sys.executable, str(CAMPAIGN), "--grid", str(grid), "--out", str(out), "--quiet"]
    done = subprocess.run(command, cwd=REPOSITORY, capture_output=True, text=True, timeout=600)
    assert done.returncode == 1, done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("warning: [campaign ") and "failed" in lines[0], done.stderr
    assert done.stdout == ""  # a campaign with a failed run has no folder to hand on
    assert "Boom.choose() raised RuntimeError" in lines[0]
    # The campaign's own log keeps every line; the finished run has its run.log.
    assert "started" in (out / "campaign.log").read_text()
    finished = [p for p in out.iterdir() if (p / "run.json").is_file()]
    assert len(finished) == 1 and (finished[0] / RUN_LOG_FILE).is_file()


@pytest.mark.parametrize("command", [["run", "--uc", "1"], ["sweep", "--out", "x"], ["figures", "DIR"],
                                     ["compare", "A", "B"]])
def test_console_subcommands_take_quiet_or_verbose_not_both(command: list[str],
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    from yafs_safetail.cli import EXIT_BAD_INPUT, main

    assert main([*command, "--quiet", "--verbose"]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and "not allowed with" in err


def test_a_quiet_sweep_prints_only_its_folder(tmp_path: Path) -> None:
    from in_process import run_in_process

    from yafs_safetail.commands import load_sweep

    out = tmp_path / "sweep"
    done = run_in_process(load_sweep.main, "--users", "5", "--loads", "0.3", "--steps-scale", "0.02",
                          "--methods", "Oracle,MinLoad-1", "--no-safetail", "--workers", "1",
                          "--out", out, "--quiet")
    assert done.returncode == 0, done.stderr
    assert done.stdout == f"{out}\n" and done.stderr == ""
    assert "| load |" in (out / "SWEEP.md").read_text()  # the table is in the folder

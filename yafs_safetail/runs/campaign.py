"""A campaign: the runs of a grid, each computed once, resumable, on any engine.

:func:`run_campaign` takes the run specs (``runs.grid``) and a campaign folder. A run whose
folder already holds a finished results folder recording the same run id (``run.json``'s
``campaign_run_id``) is done and never recomputed, so rerunning the same command on the same
folder resumes an interrupted campaign where it stopped; the folders themselves are the truth,
so a run that finished just before a kill counts even if the state file missed it. The state
file ``campaign.json`` (rewritten atomically at every change) lists every run with its status,
time and one-line error; ``campaign.log`` keeps the progress lines, which are also logged (INFO;
a failed run's line as a warning, so that ``--quiet`` still shows it). Each run writes its own
``run.log`` into its folder. A failed run is reported and the others go on; the campaign then
exits non-zero. A lock (``.campaign.lock``) keeps a
second campaign off the same folder.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import logging
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

from yafs_safetail.results import write_text_atomic

# The scripts' engine options, named here as before (engine_options.py imports nothing heavy).
from yafs_safetail.runs.engine_options import ENGINE_OPTIONS as ENGINE_OPTIONS
from yafs_safetail.runs.engine_options import add_engine_options as add_engine_options
from yafs_safetail.runs.engine_options import engine_free_command as engine_free_command
from yafs_safetail.runs.engines import RunResult, RunTask, cancel_all, check_engine, make_engine
from yafs_safetail.runs.grid import RunSpec, code_version
from yafs_safetail.runs.output import RUN_FILE, is_results_folder, refuse_protected

STATE_FILE = "campaign.json"
LOG_FILE = "campaign.log"
LOCK_FILE = ".campaign.lock"
#: Seconds between two progress lines while nothing finishes.
HEARTBEAT_S = 30.0

log = logging.getLogger(__name__)

DONE, EARLIER, FAILED, RUNNING, QUEUED = "done", "done earlier", "failed", "running", "to do"


class CampaignError(ValueError):
    """A campaign that cannot start (one line naming the folder or option)."""


@dataclass
class RunState:
    """A run's line in ``campaign.json`` and in the summary."""

    spec: RunSpec
    status: str = QUEUED
    wall_s: float = 0.0
    error: str = ""
    node: str = ""  # the Ray node that ran it (shown in the progress line; not in campaign.json)


@dataclass
class CampaignResult:
    """Every run's final state, in grid order; ``failed`` is the number that failed."""

    runs: list[RunState] = field(default_factory=list)

    @property
    def failed(self) -> int:
        return sum(run.status == FAILED for run in self.runs)


def recorded_run_id(folder: Path) -> str | None:
    """The campaign run id a finished results folder records, or None."""
    if not is_results_folder(folder):
        return None
    run = json.loads((folder / RUN_FILE).read_text())
    return run.get("campaign_run_id")


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"


class _Progress:
    """Progress lines, logged and in campaign.log (and on ``stream`` when given): done,
    running, failed, elapsed, ETA."""

    def __init__(self, states: Sequence[RunState], stream: TextIO | None, log_file: TextIO) -> None:
        self.states, self.stream, self.log_file = states, stream, log_file
        self.started = time.perf_counter()
        self.to_compute = sum(s.status == QUEUED for s in states)

    def line(self, event: str, level: int = logging.INFO) -> None:
        count = {status: sum(s.status == status for s in self.states)
                 for status in (DONE, EARLIER, FAILED, RUNNING, QUEUED)}
        elapsed_s = time.perf_counter() - self.started
        finished = count[DONE] + count[FAILED]
        left = self.to_compute - finished
        # Throughput so far, so that the workers' one-off start-up is spread over their runs.
        eta = _clock(elapsed_s / finished * left) if finished and left else ("0:00:00" if not left else "?")
        text = (f"[campaign {_clock(elapsed_s)}] {event} | {count[DONE] + count[EARLIER]}/"
                f"{len(self.states)} done ({count[EARLIER]} earlier), {count[RUNNING]} running, "
                f"{count[FAILED]} failed, {count[QUEUED]} to do | ETA {eta}")
        log.log(level, "%s", text)
        if self.stream is not None:
            print(text, file=self.stream, flush=True)
        print(f"{time.strftime('%Y-%m-%d %H:%M:%S')} {text}", file=self.log_file, flush=True)


def summary_table(result: CampaignResult) -> str:
    """The end-of-campaign table (plain text, one run a line)."""
    width = max([len("run"), *(len(s.spec.name) for s in result.runs)])
    lines = [f"{'run':<{width}}  {'id':<12}  {'status':<12}  {'time (s)':>8}  error",
             f"{'-' * width}  {'-' * 12}  {'-' * 12}  {'-' * 8}  -----"]
    for s in result.runs:
        wall = f"{s.wall_s:8.1f}" if s.status in (DONE, FAILED) else f"{'-':>8}"
        lines.append(f"{s.spec.name:<{width}}  {s.spec.run_id:<12}  {s.status:<12}  {wall}  {s.error}".rstrip())
    counts = {status: sum(s.status == status for s in result.runs) for status in (DONE, EARLIER, FAILED)}
    lines.append(f"{len(result.runs)} runs: {counts[DONE]} computed now, {counts[EARLIER]} done "
                 f"earlier (not recomputed), {counts[FAILED]} failed")
    return "\n".join(lines) + "\n"


def _write_state(out: Path, states: Sequence[RunState], command: str) -> None:
    state = {
        "code_version": code_version(),
        "command": command,
        "runs": [{"name": s.spec.name, "run_id": s.spec.run_id, "status": s.status,
                  "wall_s": round(s.wall_s, 3), "error": s.error, "settings": dict(s.spec.settings)}
                 for s in states],
    }
    write_text_atomic(out / STATE_FILE, json.dumps(state, indent=1) + "\n")


@contextlib.contextmanager
def _campaign_lock(out: Path) -> Iterator[None]:
    with open(out / LOCK_FILE, "a+") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise CampaignError(f"--out {out}: another campaign is running there now; "
                                "wait for it or choose another folder") from None
        yield


def _triage(spec: RunSpec, folder: Path, overwrite: bool) -> RunState:
    """Done earlier, to do, or failed at once (a folder the run may not replace)."""
    recorded = recorded_run_id(folder)
    if recorded == spec.run_id:
        return RunState(spec, EARLIER)
    if folder.exists() and any(folder.iterdir()) and not overwrite:
        what = (f"holds a run of another configuration (run id {recorded or 'none'}, this one "
                f"{spec.run_id}); pass --overwrite to replace it" if recorded is not None or
                is_results_folder(folder) else "exists and is not a results folder")
        return RunState(spec, FAILED, error=f"{folder}: {what}")
    return RunState(spec)


def run_campaign(specs: Sequence[RunSpec], out: Path, *, engine: str = "local",
                 workers: int | None = None, ray_address: str | None = None, command: str = "",
                 overwrite: bool = False, stream: TextIO | None = None,
                 heartbeat_s: float = HEARTBEAT_S) -> CampaignResult:
    """Run every spec not already done into ``out/<spec.name>``.

    Args:
        specs: the runs (``runs.grid.expand`` or ``load_grid``).
        out: the campaign folder.
        engine: ``"local"`` or ``"ray"``.
        workers: runs at a time (local default: as many as the usable CPUs and the available
            memory allow, ``engine_options.local_workers``; Ray: every CPU of the cluster).
        ray_address: an existing Ray cluster (``HOST:PORT``); implies the Ray engine.
        command: recorded in every run's ``run.json`` (keep engine options out of it, so the
            files do not depend on the engine: :func:`engine_free_command`).
        overwrite: replace folders that hold a run of another configuration.
        stream: also write the progress lines and the summary table here (they are logged
            either way: INFO, a failed run's line WARNING).
        heartbeat_s: seconds between progress lines while nothing finishes.

    Returns:
        Every run's state; ``failed`` > 0 means the campaign should exit non-zero.
    """
    out = Path(out)
    refuse_protected(out)
    check_engine(engine, workers, ray_address)  # before anything is written
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise OSError(f"--out {out}: cannot create it: {error.strerror}") from None
    if not specs:
        raise CampaignError("the grid holds no run")
    with _campaign_lock(out), open(out / LOG_FILE, "a") as log_file:
        states = [_triage(spec, out / spec.name, overwrite) for spec in specs]
        result = CampaignResult(states)
        _write_state(out, states, command)
        progress = _Progress(states, stream, log_file)
        queue = [s for s in states if s.status == QUEUED]
        progress.line(f"start: {len(states)} runs, {len(queue)} to compute, engine {engine}")
        for state in states:
            if state.status == FAILED:  # refused at once (a folder it may not replace)
                progress.line(f"failed {state.spec.name}: {state.error}", logging.WARNING)
        if queue:
            runner = make_engine(engine, workers, ray_address)
            log.debug("engine %s: %d run(s) at a time", engine, runner.slots)
            _execute(queue, out, runner, command, overwrite, progress, states, heartbeat_s)
        table = summary_table(result)
        log.info("%s", table.rstrip("\n"))
        if stream is not None:
            print(table, file=stream, end="", flush=True)
        print(table, file=log_file, end="", flush=True)
        return result


def _execute(queue: list[RunState], out: Path, runner: Any, command: str, overwrite: bool,
             progress: _Progress, states: Sequence[RunState], heartbeat_s: float) -> None:
    """Keep ``runner.slots`` runs under way until the queue is empty."""
    pending: dict[Any, tuple[RunState, RunTask]] = {}
    interrupted = True
    try:
        while queue or pending:
            while queue and len(pending) < runner.slots:
                state = queue.pop(0)
                task = RunTask(state.spec, str(out / state.spec.name), command, overwrite)
                state.status = RUNNING
                pending[runner.submit(task)] = (state, task)
                progress.line(f"started {state.spec.name}")
                log.debug("run %s (id %s) into %s", state.spec.name, state.spec.run_id, task.out_dir)
            _write_state(out, states, command)
            done = runner.wait(list(pending), heartbeat_s)
            if not done:
                progress.line("waiting")
            for handle in done:
                state, task = pending.pop(handle)
                outcome: RunResult = runner.result(handle, task)
                state.wall_s, state.error, state.node = outcome.wall_s, outcome.error, outcome.node
                if not outcome.error and recorded_run_id(out / state.spec.name) != state.spec.run_id:
                    state.error = "finished, but its folder does not record its run id"
                state.status = FAILED if state.error else DONE
                where = f" on node {state.node}" if state.node else ""
                progress.line(f"{state.status} {state.spec.name} ({state.wall_s:.1f} s{where})"
                              + (f": {state.error}" if state.error else ""),
                              logging.WARNING if state.error else logging.INFO)
            _write_state(out, states, command)
        interrupted = False
    finally:
        if interrupted:
            cancel_all(runner, pending)
            for state, _ in pending.values():
                state.status, state.error = QUEUED, "interrupted"
            with contextlib.suppress(OSError):
                _write_state(out, states, command)
        runner.close(interrupted)



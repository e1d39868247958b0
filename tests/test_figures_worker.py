"""The figures process (runs.figures_worker): the same files as drawing here, failures reported."""

from __future__ import annotations

import os
import signal

import numpy as np
import pytest
from results_helpers import make_requests, make_run

from yafs_safetail.results.figures import run_figures as figures
from yafs_safetail.runs.figures_worker import FiguresWorker, start_figures_worker
from yafs_safetail.runs.workers import WorkerDied


@pytest.fixture(scope="module")
def rows():
    return make_requests(np.random.default_rng(31), n_train=60, n_test=40), make_run(use_case=1, beta=20)


def test_the_process_draws_the_same_files_as_this_one(rows, tmp_path):
    requests, run = rows
    (tmp_path / "here").mkdir()
    (tmp_path / "there").mkdir()
    here = figures.draw_figures(tmp_path / "here", requests, run)
    worker = FiguresWorker()
    try:
        worker.draw(tmp_path / "there", requests, run, ("png",))
        there = worker.wait()
    finally:
        worker.stop()
    assert [p.name for p in there] == [p.name for p in here] and len(here) == len(figures.FIGURE_STEMS)
    for mine, theirs in zip(here, there, strict=True):
        assert mine.read_bytes() == theirs.read_bytes(), mine.name


def test_a_drawing_error_comes_back_as_the_same_exception(rows, tmp_path):
    requests, run = rows
    worker = FiguresWorker()
    try:
        worker.draw(tmp_path / "missing-folder", requests, run, ("png",))
        with pytest.raises(FileNotFoundError):
            worker.wait()
    finally:
        worker.stop()


@pytest.mark.parametrize("given_rows", [False, True], ids=["waited on", "given its rows"])
def test_a_killed_process_is_one_line(rows, tmp_path, given_rows):
    worker = FiguresWorker()
    try:
        os.kill(worker._process.pid, signal.SIGKILL)
        worker._process.join()
        with pytest.raises(WorkerDied, match=r"figures process \(pid \d+\) was killed by signal 9 \(SIGKILL\)"):
            if given_rows:  # as a run does: the rows first (its pipe is broken), then the wait
                worker.draw(tmp_path, *rows, ("png",))
            worker.wait()
    finally:
        worker.stop()


def test_stopping_an_idle_process_ends_it_at_once():
    worker = FiguresWorker()
    worker.stop()
    assert not worker._process.is_alive() and worker._process.exitcode == -signal.SIGTERM


def test_one_process_runs_draw_here(monkeypatch):
    assert start_figures_worker(1) is None

    class Daemonic:
        daemon = True

    monkeypatch.setattr("yafs_safetail.runs.workers.multiprocessing.current_process", Daemonic)
    assert start_figures_worker(2) is None


def test_a_figures_process_that_cannot_fork_fails_the_run_with_that_error(tmp_path, monkeypatch):
    from yafs_safetail.runs.experiment import ExperimentConfig, run_experiment

    def cannot_fork(workers):
        raise BlockingIOError(11, "fork: resource temporarily unavailable")

    monkeypatch.setattr("yafs_safetail.runs.experiment.start_figures_worker", cannot_fork)
    config = ExperimentConfig(use_case=1, seed=5, out_dir=tmp_path / "run", steps_scale=0.02, workers=2,
                              progress=False)
    with pytest.raises(BlockingIOError, match="fork: resource temporarily unavailable"):
        run_experiment(config)
    assert list(tmp_path.iterdir()) == []

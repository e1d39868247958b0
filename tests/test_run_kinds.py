"""A campaign run's kind picks what executes it, from one table (``runs.engines.RUN_KINDS``)."""

from __future__ import annotations

from yafs_safetail.runs.engines import RUN_KINDS, RunTask, execute
from yafs_safetail.runs.grid import RunSpec
from yafs_safetail.runs.sweep_config import FAILURE_POINT, LOAD_POINT


def test_every_kind_a_campaign_makes_has_a_runner():
    assert set(RUN_KINDS) == {RunSpec("x", "0", {}).kind, LOAD_POINT, FAILURE_POINT}


def test_an_unknown_kind_fails_that_run_alone_with_one_line(tmp_path):
    result = execute(RunTask(RunSpec("odd", "abc", {}, kind="notebook"), str(tmp_path / "odd")))
    assert result.error == "run odd: unknown kind 'notebook'; valid: experiment, load_point, failure_point"
    assert not (tmp_path / "odd").exists()

"""The shared command-line wrapper turns input errors into one line and a non-zero exit."""

from __future__ import annotations

import pytest

from yafs_safetail.cli import EXIT_BAD_INPUT, run_cli


def test_value_error_becomes_one_line_and_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    def failing(argv):
        raise ValueError("topologies/x.json: link[3].BW: must be >= 0, got -1")

    assert run_cli(failing, []) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err == "error: topologies/x.json: link[3].BW: must be >= 0, got -1\n"


def test_os_error_becomes_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    def failing(argv):
        raise PermissionError(13, "Permission denied", "/root/out")

    assert run_cli(failing, []) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Permission denied" in err and "/root/out" in err


def test_success_codes_pass_through() -> None:
    assert run_cli(lambda argv: None, []) == 0
    assert run_cli(lambda argv: 3, []) == 3


def test_debug_env_shows_the_real_exception(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("YAFS_SAFETAIL_DEBUG", "1")

    def failing(argv):
        raise ValueError("boom")

    with pytest.raises(ValueError, match="boom"):
        run_cli(failing, [])

"""The shared command-line wrapper turns input errors into one line and a non-zero exit."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from yafs_safetail.cli import EXIT_BAD_INPUT, SCRIPT_COMMANDS, ArgumentParser, run_cli
from yafs_safetail.edge.scenario import REPOSITORY


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


def test_console_command_lists_and_dispatches(capsys: pytest.CaptureFixture[str]) -> None:
    from yafs_safetail.cli import main

    assert main(["--help"]) == 0
    listing = capsys.readouterr().out
    assert all(f"  {name}" in listing for name in ("run", "reproduce", "calibrate", "figures"))
    with pytest.raises(SystemExit) as done:  # argparse's own --help exit, from run_usecase.py
        main(["run", "--help"])
    assert done.value.code == 0 and "--uc" in capsys.readouterr().out
    assert main(["bogus"]) == EXIT_BAD_INPUT
    assert capsys.readouterr().err.startswith("error: unknown command 'bogus'")
    assert main(["figures", "/nonexistent/run"]) == EXIT_BAD_INPUT
    assert capsys.readouterr().err == "error: /nonexistent/run: results folder not found\n"


COMMANDS = ("run", "reproduce", "calibrate", "compare", "sweep", "figures")


def test_no_command_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    from yafs_safetail.cli import main

    assert main([]) == EXIT_BAD_INPUT  # argparse's code for a usage error, as a wrong command
    out, err = capsys.readouterr()
    assert out == ""  # a usage error: the listing goes to stderr, with the error
    lines = err.splitlines()
    assert lines[0].startswith("usage: yafs-safetail ")
    assert all(any(line.startswith(f"  {name} ") for line in lines) for name in COMMANDS)
    assert lines[-1].startswith("error: no command given")
    assert sum(line.startswith("error:") for line in lines) == 1
    assert main(["-h"]) == 0 and capsys.readouterr().out.startswith("usage: yafs-safetail ")


@pytest.mark.parametrize("command", COMMANDS)
def test_each_command_names_itself_in_its_help(capsys: pytest.CaptureFixture[str], command: str) -> None:
    from yafs_safetail.cli import main

    with pytest.raises(SystemExit) as done:  # argparse's own --help exit
        main([command, "--help"])
    assert done.value.code == 0
    assert capsys.readouterr().out.startswith(f"usage: yafs-safetail {command} ")


def test_scripts_run_directly_keep_their_own_name(capsys: pytest.CaptureFixture[str]) -> None:
    import subprocess
    import sys

    from yafs_safetail.cli import main
    from yafs_safetail.commands.figures import main as figures_main

    with pytest.raises(SystemExit):
        main(["run", "--help"])  # the console command's name must not stay behind it
    capsys.readouterr()
    with pytest.raises(SystemExit):
        figures_main(["--help"])
    assert capsys.readouterr().out.startswith("usage: python -m yafs_safetail.commands.figures ")
    script = subprocess.run([sys.executable, str(REPOSITORY / "experiments" / "load_sweep.py"), "--help"],
                            capture_output=True, text=True, timeout=300)
    assert script.returncode == 0 and script.stdout.startswith("usage: load_sweep.py "), script.stderr
    # ``python -m yafs_safetail.cli`` is the console command too.
    module = subprocess.run([sys.executable, "-m", "yafs_safetail.cli", "compare", "--help"],
                            capture_output=True, text=True, timeout=300)
    assert module.returncode == 0 and module.stdout.startswith("usage: yafs-safetail compare "), module.stderr
    bare = subprocess.run([sys.executable, "-m", "yafs_safetail.cli"], capture_output=True, text=True, timeout=300)
    assert bare.returncode == EXIT_BAD_INPUT and bare.stdout == "" and "Traceback" not in bare.stderr


ENTRY_POINTS = sorted(str(path.relative_to(REPOSITORY))
                      for folder in ("experiments", "benchmarks", "investigations", "tables")
                      for path in (REPOSITORY / folder).glob("*.py"))
#: What a user cannot look up: an issue number of the project's tracker, or a file that is
#: not in the project.
UNKNOWN_REFERENCE = re.compile(r"\bissues?\s*#?\d+|facts\.md", re.IGNORECASE)


@pytest.mark.parametrize("script", ENTRY_POINTS)
def test_help_texts_refer_only_to_what_a_user_can_read(script: str) -> None:
    import subprocess
    import sys

    done = subprocess.run([sys.executable, str(REPOSITORY / script), "--help"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert not UNKNOWN_REFERENCE.findall(done.stdout), done.stdout


#: Paths an installed (wheel) user does not have: the checkout's scripts, docs and examples,
#: and the package's source files (a module is named as ``yafs_safetail.x.y``, for pydoc).
CHECKOUT_ONLY = re.compile(r"experiments/|docs/|examples/|yafs_safetail/")


@pytest.mark.parametrize("command", ["", *SCRIPT_COMMANDS])
def test_help_names_only_what_an_installed_user_has(capsys: pytest.CaptureFixture[str], command: str) -> None:
    from yafs_safetail.cli import main

    if command:
        with pytest.raises(SystemExit) as done:  # argparse's own --help exit
            main([command, "--help"])
        assert done.value.code == 0
    else:
        assert main(["--help"]) == 0
    shown = capsys.readouterr().out
    assert shown.startswith("usage: yafs-safetail") and not CHECKOUT_ONLY.findall(shown), shown


def test_sigterm_becomes_a_clean_exit(capsys: pytest.CaptureFixture[str]) -> None:
    import os
    import signal

    from yafs_safetail.cli import EXIT_TERMINATED

    def terminated(argv):
        os.kill(os.getpid(), signal.SIGTERM)
        raise AssertionError("the signal should have ended the command")

    previous = signal.getsignal(signal.SIGTERM)
    try:
        assert run_cli(terminated, []) == EXIT_TERMINATED
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert capsys.readouterr().err == "error: terminated; no partial results were kept\n"


def test_sigterm_during_library_code_that_turns_it_into_another_error(capsys: pytest.CaptureFixture[str]) -> None:
    """An import interrupted by SIGTERM can surface as an ImportError (seen with Keras): it is
    still reported as a termination, not as a traceback."""
    import os
    import signal

    from yafs_safetail.cli import EXIT_TERMINATED

    def import_interrupted(argv):
        try:
            os.kill(os.getpid(), signal.SIGTERM)
        except KeyboardInterrupt as interrupted:
            raise ImportError("To use Keras, you need to have `optree` installed") from interrupted

    previous = signal.getsignal(signal.SIGTERM)
    try:
        assert run_cli(import_interrupted, []) == EXIT_TERMINATED
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert capsys.readouterr().err == "error: terminated; no partial results were kept\n"


def test_a_reader_that_goes_away_is_not_an_error(tmp_path):
    # `yafs-safetail --help | head -1`: the pipe closes while the command still writes.
    import subprocess
    import sys

    script = ("import sys\nfrom yafs_safetail.cli import run_cli\n"
              "def main(argv):\n    for i in range(100000):\n        print('line', i)\n"
              "sys.exit(run_cli(main, []))\n")
    done = subprocess.run(f"{sys.executable} -c \"{script}\" | head -1; exit ${{PIPESTATUS[0]}}",
                          shell=True, executable="/bin/bash", capture_output=True, text=True, timeout=120)
    assert done.stdout == "line 0\n"
    assert done.stderr == "", done.stderr
    assert done.returncode == 141  # as a tool killed by SIGPIPE: what followed was not done


def test_version_is_the_packages(capsys: pytest.CaptureFixture[str]) -> None:
    from yafs_safetail import __version__
    from yafs_safetail.cli import main

    assert main(["--version"]) == 0
    assert capsys.readouterr().out == f"yafs-safetail {__version__}\n"
    with pytest.raises(SystemExit) as done:  # argparse's own exit, as for --help
        main(["compare", "--version"])
    assert done.value.code == 0 and capsys.readouterr().out == f"yafs-safetail {__version__}\n"


def test_a_tilde_in_any_path_option_is_the_home_folder(monkeypatch: pytest.MonkeyPatch, tmp_path) -> None:
    from yafs_safetail.commands import run_usecase
    from yafs_safetail.settings.experiment import ExperimentConfig

    monkeypatch.setenv("HOME", str(tmp_path))
    # Options declared in settings.experiment (through add_options) and by hand alike.
    config: ExperimentConfig = run_usecase.parse_args(
        ["--uc", "1", "--out", "~/run", "--topology", "~/t.json", "--placement", "~/p.json",
         "--policy", "~/policy.keras"])
    assert config.out_dir == tmp_path / "run"
    assert (config.topology, config.placement, config.policy) == (
        tmp_path / "t.json", tmp_path / "p.json", tmp_path / "policy.keras")
    parser = ArgumentParser()
    parser.add_argument("--grid", type=Path)
    assert parser.parse_args(["--grid=~/grid.toml"]).grid == tmp_path / "grid.toml"


def test_a_tilde_in_a_grid_files_path_is_the_home_folder(monkeypatch: pytest.MonkeyPatch, tmp_path) -> None:
    import shutil

    from yafs_safetail.defaults import DEFAULT_PLACEMENT, DEFAULT_TOPOLOGY
    from yafs_safetail.runs.grid import expand

    monkeypatch.setenv("HOME", str(tmp_path))
    shutil.copy(DEFAULT_TOPOLOGY, tmp_path / "t.json")
    shutil.copy(DEFAULT_PLACEMENT, tmp_path / "p.json")
    (spec,) = expand({"topology": "~/t.json", "placement": "~/p.json"}, {"seed": [0]})
    assert spec.settings["topology"] == str((tmp_path / "t.json").resolve())
    assert spec.settings["placement"] == str((tmp_path / "p.json").resolve())


@pytest.mark.parametrize("quiet", [False, True])
def test_a_commands_result_is_its_report_or_with_quiet_its_folder(
        quiet: bool, capsys: pytest.CaptureFixture[str]) -> None:
    import argparse

    from yafs_safetail.cli import print_result

    print_result(argparse.Namespace(quiet=quiet), Path("results/x"), "| table |\nresults: results/x")
    expected = "results/x\n" if quiet else "| table |\nresults: results/x\n"
    assert capsys.readouterr().out == expected


def test_a_tilde_in_a_methods_file_is_the_home_folder(monkeypatch: pytest.MonkeyPatch, tmp_path) -> None:
    import shutil

    from yafs_safetail.commands import run_usecase
    from yafs_safetail.runs.grid import expand

    monkeypatch.setenv("HOME", str(tmp_path))
    shutil.copy(REPOSITORY / "examples" / "custom_policy" / "nearest_free.py", tmp_path / "mine.py")
    config = run_usecase.parse_args(["--uc", "1", "--method", "Near=~/mine.py:NearestFree",
                                     "--method", "~/mine.py:NearestFree"])
    assert [m.spec for m in config.methods] == [f"Near={tmp_path}/mine.py:NearestFree",
                                                f"{tmp_path}/mine.py:NearestFree"]
    assert config.methods[0].name == "Near"
    (spec,) = expand({"methods": ["~/mine.py:NearestFree"]}, {"seed": [0]})
    assert spec.settings["methods"] == [f"{tmp_path}/mine.py:NearestFree"]

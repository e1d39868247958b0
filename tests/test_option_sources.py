"""Every setting's command-line option comes from its declaration (settings.options): no
``add_argument`` anywhere else but the mechanism itself and the two plumbing helpers, and no
plumbing option that is a setting's."""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

from yafs_safetail.cli import PLUMBING_FLAGS
from yafs_safetail.commands.training_mechanism import Measurement
from yafs_safetail.contention.config import ContentionConfig
from yafs_safetail.runs.sweep_config import FailureSweepConfig, SweepConfig
from yafs_safetail.settings.declare import has_setting, setting_of
from yafs_safetail.settings.experiment import ExperimentConfig

PACKAGE = Path(__file__).resolve().parents[1] / "yafs_safetail"
#: Where argparse options may be added: the mechanism deriving them from declarations, and the
#: helpers for what is not a setting (cli: --version, --quiet/--verbose, add_plumbing; the
#: engines' --workers/--engine/--ray-address).
ALLOWED = {"settings/options.py", "cli.py", "runs/engine_options.py"}
#: Every configuration whose fields a command turns into options.
CONFIGURATIONS = (ExperimentConfig, ContentionConfig, SweepConfig, FailureSweepConfig, Measurement)


def _calls(name: str) -> list[tuple[str, ast.Call]]:
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        relative = str(path.relative_to(PACKAGE))
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute | ast.Name):
                called = node.func.attr if isinstance(node.func, ast.Attribute) else node.func.id
                if called == name:
                    found.append((relative, node))
    return found


def test_no_option_is_added_outside_the_mechanism_and_the_plumbing_helpers() -> None:
    stray = sorted({f"{where}:{call.lineno}" for where, call in _calls("add_argument")
                    if where not in ALLOWED})
    assert stray == [], f"add_argument outside settings.options and the plumbing helpers: {stray}"


def test_plumbing_is_never_the_option_of_a_setting_that_changes_results() -> None:
    # (A run's own --out, --overwrite and --workers are declared too, as Output's runtime
    # settings; another command's folder or processes are plumbing of the same names.)
    results = [item for config in CONFIGURATIONS for item in dataclasses.fields(config)
               if has_setting(item) and setting_of(item).changes_results]
    declared = {setting_of(item).option(item.name) for item in results} - {""}
    declared |= {alias for item in results for alias in setting_of(item).deprecated}
    assert not declared & set(PLUMBING_FLAGS)
    for where, call in _calls("add_plumbing"):
        flag = call.args[1]
        assert isinstance(flag, ast.Constant), f"{where}:{call.lineno}: name the option literally"
        assert not str(flag.value).startswith("-") or flag.value in PLUMBING_FLAGS, f"{where}:{call.lineno}"
        assert flag.value not in declared, f"{where}:{call.lineno}: {flag.value} is a setting's option"


def test_a_deprecated_spelling_still_works_and_says_so(capsys) -> None:
    from yafs_safetail.commands import run_usecase

    args = run_usecase._parser().parse_args(["--uc", "1", "--learner", "value"])
    assert args.objective == "value"
    assert capsys.readouterr().err == "warning: --learner is deprecated; use --objective\n"
    assert "--learner" not in run_usecase._parser().format_help()


def test_the_same_setting_has_the_same_option_in_a_run_and_a_sweep(capsys) -> None:
    """A server's mean time to repair is --failure-mttr-s in both; the sweep's old --mttr-s still works."""
    import argparse

    from yafs_safetail.runs.sweep_config import FailureSweepConfig
    from yafs_safetail.settings.options import add_options

    parser = argparse.ArgumentParser()
    add_options(parser, FailureSweepConfig, only=("mttr_s",))
    assert parser.parse_args(["--failure-mttr-s", "30"]).mttr_s == 30.0
    assert parser.parse_args(["--mttr-s", "20"]).mttr_s == 20.0
    assert capsys.readouterr().err == "warning: --mttr-s is deprecated; use --failure-mttr-s\n"
    run_option = setting_of(dataclasses.fields(ExperimentConfig)[[f.name for f in dataclasses.fields(
        ExperimentConfig)].index("failure_mttr_s")]).option("failure_mttr_s")
    assert run_option == "--failure-mttr-s"

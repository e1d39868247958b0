"""settings.experiment: each setting declared once, and what is derived from it (options, checks, run id)."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from unittest import mock

import pytest

from yafs_safetail.methods.safetail.presets import get_preset
from yafs_safetail.runs import grid
from yafs_safetail.settings.declare import check_config, setting_of
from yafs_safetail.settings.experiment import (
    GROUPS,
    RESULT_FIELDS,
    ExperimentConfig,
    ExperimentError,
    LearnerOverrides,
    learner_overrides,
)
from yafs_safetail.settings.options import add_options, config_from_args
from yafs_safetail.worlds.recipe import learner_config


def test_every_field_is_declared_once_in_one_group_with_its_help():
    owners: dict[str, str] = {}
    for group in GROUPS:
        for item in dataclasses.fields(group):
            assert item.name not in owners, f"{item.name} in {owners.get(item.name)} and {group.__name__}"
            owners[item.name] = group.__name__
            assert setting_of(item).help.strip(), item.name
    assert sorted(owners) == sorted(f.name for f in dataclasses.fields(ExperimentConfig))


def test_the_experiment_module_still_exports_the_configuration():
    from yafs_safetail.runs import experiment

    assert experiment.ExperimentConfig is ExperimentConfig and experiment.ExperimentError is ExperimentError


def test_options_parse_back_to_the_configuration():
    parser = argparse.ArgumentParser()
    add_options(parser, ExperimentConfig)
    config = config_from_args(parser.parse_args([
        "--uc", "2", "--seed", "7", "--steps-scale", "0.5", "--redundancy", "1,2", "--no-figures",
        "--target-compute", "request", "--learning-rate", "0.001", "--out", "somewhere", "--workers", "1"]), ExperimentConfig)
    assert config == ExperimentConfig(use_case=2, seed=7, steps_scale=0.5, redundancy_levels=(1, 2),
                                      figures=False, target_compute="request", learning_rate=0.001,
                                      out_dir=Path("somewhere"), workers=1)
    assert config_from_args(parser.parse_args([]), ExperimentConfig) == ExperimentConfig()


def test_a_bad_option_is_refused_by_its_declared_check():
    parser = argparse.ArgumentParser(exit_on_error=False)
    add_options(parser, ExperimentConfig, only=("seed",))
    with pytest.raises(argparse.ArgumentError, match="expected a non-negative integer"):
        parser.parse_args(["--seed", "-1"])


@pytest.mark.parametrize("changes, option, field", [
    ({"seed": -1}, "--seed", "seed"),
    ({"steps_scale": float("nan")}, "--steps-scale", "steps_scale"),
    ({"use_case": 4}, "--uc", "use_case"),
    ({"workers": True}, "--workers", "workers"),
    ({"target_compute": "mean"}, "--target-compute", "target_compute"),
    ({"learning_rate": 0}, "--learning-rate", "learning_rate"),
])
def test_a_bad_value_is_one_line_naming_the_option_or_the_field(changes, option, field):
    config = ExperimentConfig(**changes)
    with pytest.raises(ExperimentError, match=f"^{option}: expected ") as caught:
        check_config(config)
    assert "\n" not in str(caught.value)
    with pytest.raises(ExperimentError, match=f"^{field}: expected "):
        check_config(config, style="field")


def test_optional_settings_accept_none():
    check_config(ExperimentConfig(learning_rate=None, target_latency_s=None, checkpoint_every_s=None))


def test_a_learner_override_replaces_the_preset_field_of_its_name():
    full, learner = learner_config(ExperimentConfig(preset="paper", steps_scale=0.5, learning_rate=1))
    assert learner.learning_rate == 1.0 and isinstance(learner.learning_rate, float)
    assert learner.train_steps == round(full.train_steps * 0.5)
    preset = get_preset("paper", 1, train_steps=learner.train_steps)
    assert dataclasses.replace(learner, learning_rate=preset.learning_rate) == preset  # nothing else moved
    assert learner_overrides(ExperimentConfig(learning_rate=1e-3)) == {"learning_rate": 1e-3}
    assert learner_overrides(ExperimentConfig()) == {}
    for item in dataclasses.fields(LearnerOverrides):  # each override names a LearnerConfig field
        assert hasattr(full, item.name), item.name


def test_the_run_id_hashes_the_result_fields_as_before():
    """The run ids of existing configurations do not change (values computed before runs.config)."""
    assert grid.SETTABLE_FIELDS == (*RESULT_FIELDS, "figure_formats")
    assert set(grid.RUNTIME_FIELDS) == {"out_dir", "progress", "command", "workers", "overwrite", "force",
                                        "run_id", "resume", "checkpoint_every_s", "figure_formats"}
    assert set(grid.PATH_FIELDS) == {"topology", "placement", "traces_dir", "policy", "down_intervals", "route"}
    with mock.patch.object(grid, "code_version", lambda: "0.0.0+git.test"), \
            mock.patch.object(grid, "_digest", lambda path: "digest"):
        assert grid.config_run_id(ExperimentConfig()) == "a89f6bb8a559"
        assert grid.config_run_id(ExperimentConfig(
            use_case=2, seed=4, steps_scale=0.5, learning_rate=1e-3, target_compute="request",
            figures=False)) == "7fd27f6c770f"
        # Which copies of the figures a run draws is not part of what it computes.
        assert grid.config_run_id(ExperimentConfig(figure_formats=("png", "pdf"))) == "a89f6bb8a559"

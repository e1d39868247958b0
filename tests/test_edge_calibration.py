"""World settings: the landed world is unchanged, each reading and calibrated rule does what it
says, and the calibration file is read (or refused) in one line."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from yafs_safetail.edge.calibration import (
    CALIBRATED_PARAMETERS,
    CALIBRATION_FILE,
    LANDED,
    CalibrationError,
    WorldSettings,
    load_levels,
    read_calibration,
    world_settings,
)
from yafs_safetail.edge.scenario import load_scenario
from yafs_safetail.edge.traces import scale_load_levels
from yafs_safetail.edge.usecases import get_use_case
from yafs_safetail.edge.world import build_world

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def inputs(uc1_median_inputs):
    return uc1_median_inputs


def scenario(name: str = "paper_5servers"):
    return load_scenario(ROOT / "topologies" / f"{name}.json", ROOT / "placements" / f"{name}.json")


def world(inputs, settings: WorldSettings = LANDED, name: str = "paper_5servers", steps: int = 600):
    return build_world(scenario(name), get_use_case(1), inputs, steps, seed=4, phase="test",
                       settings=settings)


def test_load_levels_at_the_maximum_load_are_the_landed_scaling(inputs):
    users = inputs.load_users
    np.testing.assert_array_equal(load_levels(users, 4.0, 4), scale_load_levels(users, 4))
    high = load_levels(users, 6.0, 4)
    assert high.max() == 4 and (high >= 4).mean() > (load_levels(users, 4.0, 4) >= 4).mean()
    assert load_levels(users, 3.0, 4).max() == 3  # never full from background users alone


def test_readings_and_rules_change_only_what_they_say(inputs):
    base = world(inputs)
    half = world(inputs, dataclasses.replace(LANDED, propagation_rtt_fraction=0.5))
    np.testing.assert_allclose(half.rtt_s, 0.5 * base.rtt_s)  # shipped links add no PR
    np.testing.assert_array_equal(half.background_users, base.background_users)
    shared = world(inputs, dataclasses.replace(LANDED, bandwidth_share_exponent=1.0))
    for level in range(base.n_contention_levels):
        np.testing.assert_allclose(shared.server_uplink_by_level_bps[:, :, level],
                                   base.server_uplink_by_level_bps[:, :, level] / (1 + level))
    fallback = world(inputs, dataclasses.replace(LANDED, fallback_compute_multiple=7.0))
    assert fallback.fallback_latency_s == pytest.approx(7.0 * inputs.median_compute_by_k_s[0])
    nu = world(inputs, dataclasses.replace(LANDED, nu=1))
    assert nu.nu == 1 and base.nu == get_use_case(1).nu
    np.testing.assert_allclose(nu.target_s - base.target_s,
                               inputs.median_compute_by_k_s[0] - base.target_compute_s)


def test_per_server_load_starts_are_independent_and_per_server_stable(inputs):
    settings = dataclasses.replace(LANDED, load_start="per_server")
    five = world(inputs, settings)
    three = world(inputs, settings, name="3servers")
    # Not one shared minute: the servers' loads are not a fixed function of one row.
    assert not np.array_equal(five.background_users, world(inputs).background_users)
    # Server 0 keeps its load stream whatever the number of servers.
    np.testing.assert_array_equal(five.background_users[:, 0], three.background_users[:, 0])


def test_settings_are_validated():
    with pytest.raises(CalibrationError, match="load_start"):
        WorldSettings(load_start="random")
    with pytest.raises(CalibrationError, match="nu"):
        WorldSettings(nu=7)
    with pytest.raises(CalibrationError, match="unknown world 'mars'"):
        world_settings("mars")


def test_the_shipped_calibration_names_every_parameter_and_its_provenance():
    data = read_calibration()
    assert set(CALIBRATED_PARAMETERS) <= set(data["parameters"])
    for key in ("consumed", "seeds", "objective", "date", "command", "git_commit", "unidentified"):
        assert key in data["provenance"], key
    assert len(data["provenance"]["consumed"]) == 16
    settings = world_settings("calibrated")
    assert settings.propagation_rtt_fraction == 0.5 and settings.name == "calibrated"
    assert world_settings("landed") == LANDED
    assert CALIBRATION_FILE.name == "calibration.json"


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (None, "calibration file not found"),
        ("{not json", "not a readable JSON file"),
        ("[]", "expected a JSON object"),
        (json.dumps({"parameters": {}, "readings": {}}), "field 'provenance'"),
        (json.dumps({"parameters": {"nu": 1}, "readings": {}, "provenance": {}}),
         "parameters.load_peak_users is missing"),
    ],
)
def test_a_bad_calibration_file_is_one_line(tmp_path, content, message):
    path = tmp_path / "calibration.json"
    if content is not None:
        path.write_text(content)
    with pytest.raises(CalibrationError, match=message) as error:
        world_settings("calibrated", path)
    assert str(path) in str(error.value) and "\n" not in str(error.value)


def test_the_first_calibration_stays_the_contention_worlds_default():
    from yafs_safetail.contention.world import ContentionConfig
    from yafs_safetail.edge.calibration import CALIBRATED_V1

    first = world_settings("calibrated-v1")
    assert first == CALIBRATED_V1 and ContentionConfig().world == "calibrated-v1"
    # The figures of docs/contention.md were measured in this world: its values must not drift.
    assert (first.load_peak_users, first.bandwidth_share_exponent, first.fallback_compute_multiple,
            first.nu, first.load_start) == (3.75, 0.0, 8.0, 2, "per_server")
    assert world_settings("calibrated") != first

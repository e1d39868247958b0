"""What every world is drawn from (edge.world_parts): one draw; one way to apply overrides
(settings.world)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from yafs_safetail.edge.calibration import CALIBRATED_V1, LANDED
from yafs_safetail.edge.world import build_world
from yafs_safetail.edge.world_parts import WorldParts
from yafs_safetail.settings.world import WorldOverrideError, apply_world_overrides
from yafs_safetail.settings.world import WorldOverrides as _Overrides


def test_draw_is_build_world_with_the_parts_settings(uc1):
    use_case, scenario, inputs = uc1
    parts = WorldParts(use_case=use_case, inputs=inputs, scenario=scenario, settings=CALIBRATED_V1)
    drawn = parts.draw(40, seed=3, phase="test:0")
    built = build_world(scenario, use_case, inputs, 40, seed=3, phase="test:0", settings=CALIBRATED_V1)
    assert drawn.settings == CALIBRATED_V1
    for name in ("input_bytes", "rtt_s", "background_users", "target_s", "compute_by_processes_s"):
        np.testing.assert_array_equal(getattr(drawn, name), getattr(built, name))


def test_overrides_apply_and_only_changes_are_recorded():
    settings, changed = apply_world_overrides(LANDED, _Overrides())
    assert settings == LANDED and changed == {}
    # load_peak_users 4 is the landed world's own value: applied, not recorded as a change.
    settings, changed = apply_world_overrides(LANDED, _Overrides(target_latency_s=1.5, load_peak_users=4.0))
    assert settings == dataclasses.replace(LANDED, target_latency_s=1.5)
    assert changed == {"target_latency_s": 1.5}


@pytest.mark.parametrize("name, value", [("target_latency_s", 0.0), ("load_peak_users", -1.0),
                                         ("target_compute", "mean"), ("target_latency_s", "soon")])
def test_a_refused_override_names_its_field(name, value):
    with pytest.raises(WorldOverrideError, match=f"^{name}: ") as caught:
        apply_world_overrides(LANDED, _Overrides(**{name: value}))
    assert (caught.value.name, caught.value.value) == (name, value)


def test_the_contention_world_takes_the_experiments_world_overrides():
    from yafs_safetail.contention.world import ContentionConfig, ContentionError, ContentionWorld

    base = ContentionConfig(n_requests=30, users=3, load=0.3, block_requests=10)
    overrides = {"target_latency_s": 1.5, "load_peak_users": 2.0, "target_compute": "trace_median"}
    world = ContentionWorld(dataclasses.replace(base, **overrides))
    assert world.settings == dataclasses.replace(CALIBRATED_V1, **overrides)
    assert [world.target_s(r) for r in range(30)] == [1.5] * 30
    plain = ContentionWorld(base, world.inputs, world.scenario)
    assert plain.settings == CALIBRATED_V1
    np.testing.assert_array_equal(plain.emit_s, world.emit_s)  # the arrivals do not move
    with pytest.raises(ContentionError, match="^load_peak_users: expected a non-negative number, got -1.0$"):
        ContentionWorld(dataclasses.replace(base, load_peak_users=-1.0), world.inputs, world.scenario)


def test_a_sweep_point_records_the_world_overrides_only_when_set():
    from yafs_safetail.contention.config import ContentionConfig
    from yafs_safetail.runs.sweep_config import SweepConfig
    from yafs_safetail.runs.sweep_points import point_specs

    plain = SweepConfig(base=ContentionConfig(users=10), loads=(0.5,))
    assert not {"target_latency_s", "load_peak_users", "target_compute"} & set(plain.point_settings(0.5))
    changed = SweepConfig(base=ContentionConfig(users=10, target_latency_s=2.0), loads=(0.5,))
    settings = changed.point_settings(0.5)
    assert settings["target_latency_s"] == 2.0
    assert SweepConfig.from_point_settings(settings).base == changed.base
    assert point_specs(plain)[0].run_id != point_specs(changed)[0].run_id

"""A user who moves, in the edge world (edge.movement): conditions follow the route, and a user
who does not move changes nothing."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from yafs_safetail.edge.calibration import LANDED
from yafs_safetail.edge.inputs import load_scenario_for
from yafs_safetail.edge.movement import MobilityPlan, MovementError, default_area_m
from yafs_safetail.edge.routes import RandomWaypoint, Route, at_rest, read_route
from yafs_safetail.edge.signal import DEFAULT_SIGNAL_RULE
from yafs_safetail.edge.world import build_world

ROOT = Path(__file__).resolve().parents[1]
CAMPUS = ROOT / "topologies" / "campus_5servers.json"
WALK = ROOT / "routes" / "campus_walk.csv"
STEP_S = 60.0


@pytest.fixture(scope="module")
def campus(uc1):
    use_case, _, inputs = uc1
    return use_case, load_scenario_for(inputs, CAMPUS, ROOT / "placements" / "campus_5servers.json"), inputs


def world(setup, mobility=None, n_steps=60, seed=3, phase="test", step_interval_s=STEP_S):
    use_case, scenario, inputs = setup
    return build_world(scenario, use_case, inputs, n_steps, seed=seed, phase=phase, settings=LANDED,
                       mobility=mobility, step_interval_s=step_interval_s)


def arrays(edge_world) -> dict[str, np.ndarray]:
    return {f.name: getattr(edge_world, f.name) for f in dataclasses.fields(edge_world)
            if isinstance(getattr(edge_world, f.name), np.ndarray)}


def test_a_user_at_rest_where_the_topology_puts_its_conditions_changes_no_draw(campus):
    still = world(campus)
    resting = world(campus, MobilityPlan(route=at_rest((0.0, 0.0))))
    for name, value in arrays(still).items():
        assert np.array_equal(value, arrays(resting)[name]), name
    assert np.all(resting.movement.conditions == np.array(still.scenario.server_conditions))
    for step in (0, 17, 59):
        a, b = still.observation(step, np.zeros(5)), resting.observation(step, np.zeros(5))
        assert np.array_equal(a.server_median_propagation_s, b.server_median_propagation_s)
        assert np.array_equal(a.user_location, b.user_location)


def test_the_campus_topology_without_movement_is_the_paper_world(campus, uc1):
    for name, value in arrays(world(uc1)).items():
        assert np.array_equal(value, arrays(world(campus))[name]), name


def test_along_the_walk_each_link_takes_the_condition_of_its_distance(campus):
    moving = world(campus, MobilityPlan(route=read_route(WALK, None)), n_steps=30)
    movement = moving.movement
    # Request 2 is sent at 120 s, at the far server (150, 0): it is near, the first server far.
    assert np.allclose(movement.user_position_m[2], [150.0, 0.0])
    assert movement.conditions[2, 4] == 1 and movement.conditions[2, 0] == 5
    assert movement.conditions[0].tolist() == [1, 2, 3, 4, 5]
    # The 600 s walk repeats: request 10 is back at the start.
    assert np.array_equal(movement.conditions[10], movement.conditions[0])
    assert len({tuple(row) for row in movement.conditions.tolist()}) > 3
    # Each RTT is drawn from its condition's pool (at the same quantile as without movement),
    # and the observation shows that pool's median.
    inputs = campus[2]
    for step, server in ((2, 4), (2, 0), (5, 1)):
        pool = inputs.rtt_pools_s[int(movement.conditions[step, server])] * LANDED.propagation_rtt_fraction
        assert pool.min() <= moving.rtt_s[step, server] <= pool.max()
        observed = moving.observation(step, np.zeros(5)).server_median_propagation_s[server]
        assert observed == pytest.approx(np.median(pool))
    assert np.allclose(moving.observation(2, np.zeros(5)).user_location, [150.0, 0.0])


def test_movement_moves_no_other_draw(campus):
    still = world(campus)
    moving = world(campus, MobilityPlan(route=read_route(WALK, None)))
    for name in ("input_bytes", "background_users", "user_uplink_bps", "compute_by_processes_s",
                 "server_uplink_by_level_bps", "target_compute_s"):
        assert np.array_equal(getattr(still, name), getattr(moving, name)), name
    assert not np.array_equal(still.rtt_s, moving.rtt_s)


def test_random_waypoint_is_drawn_per_phase_from_the_seed(campus):
    plan = MobilityPlan(random_waypoint=RandomWaypoint(default_area_m(campus[1], DEFAULT_SIGNAL_RULE), (1.0, 1.5), 30.0))
    a, b = world(campus, plan), world(campus, plan)
    assert np.array_equal(a.movement.user_position_m, b.movement.user_position_m)
    assert not np.array_equal(a.movement.user_position_m, world(campus, plan, phase="train").movement.user_position_m)
    assert not np.array_equal(a.movement.user_position_m, world(campus, plan, seed=4).movement.user_position_m)
    # One request a minute at walking speed: the user is somewhere else at every request.
    assert np.all(np.hypot(*np.diff(a.movement.user_position_m, axis=0).T)[:5] > 0)


def test_a_topology_without_server_positions_cannot_host_a_moving_user(uc1):
    with pytest.raises(MovementError, match=r"paper_5servers\.json: edge servers: a user who moves needs"):
        world(uc1, MobilityPlan(route=Route(np.zeros(1), np.zeros((1, 2)), "here")))


def test_requests_rows_say_where_the_user_was_and_each_chosen_links_condition(campus):
    from yafs_safetail.methods.baselines import RandX
    from yafs_safetail.record import MOVEMENT_COLUMNS, RECORD_COLUMNS, records_frame
    from yafs_safetail.sim.runner import simulate

    moving = world(campus, MobilityPlan(route=read_route(WALK, None)), n_steps=12)
    records = simulate(moving, RandX(5, np.random.default_rng(0), 2))
    rows = records_frame(records, "test", 256, moving.movement)
    assert tuple(rows.columns) == (*RECORD_COLUMNS, *MOVEMENT_COLUMNS)
    assert rows.loc[2, ["user_x_m", "user_y_m"]].tolist() == [150.0, 0.0]
    for record, text in zip(records, rows["conditions"], strict=True):
        assert text == ";".join(str(moving.movement.conditions[record.step, s]) for s in record.servers)
    still = records_frame(simulate(world(campus, n_steps=12), RandX(5, np.random.default_rng(0), 2)), "test", 256)
    assert tuple(still.columns) == RECORD_COLUMNS

"""The contention world's users on the move (issue 43): the single-user world's settings and
rules, each user on its own route (docs/mobility.md, docs/contention.md)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from yafs_safetail.contention.config import ContentionError
from yafs_safetail.contention.env import ContentionEnv
from yafs_safetail.contention.run import run_policy, summarise
from yafs_safetail.contention.world import ContentionConfig, ContentionWorld
from yafs_safetail.edge.movement import server_positions_m
from yafs_safetail.edge.signal import DEFAULT_SIGNAL_RULE, distances_m
from yafs_safetail.methods.registry import make_baseline
from yafs_safetail.runs.sweep_config import SweepConfig
from yafs_safetail.settings.declare import field_of, setting_of

ROOT = Path(__file__).resolve().parents[1]
CAMPUS = ROOT / "topologies" / "campus_5servers.json"
#: Small blocks, so that a run spans several (a request's user is looked up across blocks).
BASE = ContentionConfig(use_case=1, users=6, n_requests=600, seed=5, topology=CAMPUS, block_requests=200,
                        load=0.05)


def world(**changes) -> ContentionWorld:
    return ContentionWorld(dataclasses.replace(BASE, **changes))


def every_observation(w: ContentionWorld) -> list:
    return [w.observation(request, [0] * w.n_servers) for request in range(w.n_requests)]


def test_the_mobility_settings_are_the_experiments_declared_once():
    from yafs_safetail.settings.experiment import Mobility

    for name in ("mobility", "route", "speed_mps", "pause_s"):
        mine, theirs = setting_of(field_of(ContentionConfig, name)), setting_of(field_of(Mobility, name))
        assert (mine.flag, mine.check, field_of(ContentionConfig, name).default) == \
            (theirs.flag, theirs.check, field_of(Mobility, name).default)


def test_users_at_rest_have_exactly_the_draws_of_users_who_stay_put():
    """The campus topology's conditions are its positions' (speed 0,0: each user stays at the
    topology's user position), so every RTT, τ and observation is mobility off's."""
    still, resting = world(), world(mobility="random-waypoint", speed_mps=(0.0, 0.0))
    assert resting.moving_users is not None
    for index in range(3):
        assert resting.block(index) == still.block(index)
    assert [resting.target_s(r) for r in range(600)] == [still.target_s(r) for r in range(600)]
    for a, b in zip(every_observation(resting)[::37], every_observation(still)[::37], strict=True):
        for name in ("server_condition", "server_median_propagation_s", "user_location"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
    rows = [summarise(run_policy(w, make_baseline("MinProp-2", 5, np.random.default_rng(0))))
            for w in (resting, still)]
    assert rows[0] == rows[1]


def test_moving_users_links_follow_their_own_distances():
    moving = world(mobility="random-waypoint", speed_mps=(8.0, 14.0), pause_s=0.0)
    assert moving.moving_users is not None
    seen = every_observation(moving)
    conditions = np.asarray([o.server_condition for o in seen])
    where_m = np.asarray([o.user_location for o in seen])
    servers_m = server_positions_m(moving.scenario)
    # Each request's conditions are its user's distances then, by the single-user world's rule.
    assert np.array_equal(conditions, DEFAULT_SIGNAL_RULE.condition(distances_m(where_m, servers_m)))
    users = moving.user[:moving.n_requests]
    for user in range(moving.config.users):
        mine = conditions[users == user]
        assert len({tuple(row) for row in mine}) > 1, f"user {user}'s links never change"
    # Two users are in different places, each on its own route.
    routes = moving.moving_users.routes
    assert not np.array_equal(routes[0].xy_m, routes[1].xy_m)
    first = {int(u): where_m[int(np.flatnonzero(users == u)[-1])] for u in range(2)}
    assert not np.array_equal(first[0], first[1])
    # ρ^μ_i and τ follow the conditions: on a server, one condition has one median.
    medians = np.asarray([o.server_median_propagation_s for o in seen])
    for server in range(5):
        for c in np.unique(conditions[:, server]).tolist():
            assert len(np.unique(medians[conditions[:, server] == c, server])) == 1
        assert len(np.unique(medians[:, server])) == len(np.unique(conditions[:, server]))
    still = world()
    assert any(moving.target_s(r) != still.target_s(r) for r in range(50))


def test_moving_users_move_no_other_draw():
    still, moving = world(), world(mobility="random-waypoint")
    assert np.array_equal(still.emit_s, moving.emit_s) and np.array_equal(still.user, moving.user)
    a, b = still.block(1), moving.block(1)
    assert (a.work_s, a.input_transfer_s, a.input_bytes) == (b.work_s, b.input_transfer_s, b.input_bytes)
    assert a.propagation_s != b.propagation_s


def test_the_same_seed_moves_the_users_the_same_way():
    runs = [summarise(run_policy(world(mobility="random-waypoint"), make_baseline("MinLoad-2", 5,
                                                                                  np.random.default_rng(1))))
            for _ in range(2)]
    assert runs[0] == runs[1]
    one, other = world(mobility="random-waypoint"), world(mobility="random-waypoint", seed=6)
    assert not np.array_equal(one.moving_users.routes[0].xy_m, other.moving_users.routes[0].xy_m)


def test_a_users_route_does_not_depend_on_how_many_users_there_are():
    few, many = world(mobility="random-waypoint", users=2), world(mobility="random-waypoint", users=9)
    shortest = min(len(few.moving_users.routes[0].xy_m), len(many.moving_users.routes[0].xy_m))
    assert np.array_equal(few.moving_users.routes[0].xy_m[:shortest], many.moving_users.routes[0].xy_m[:shortest])


def test_every_user_follows_the_route_file():
    walking = world(mobility="route", route=ROOT / "routes" / "campus_walk.csv")
    routes = walking.moving_users.routes
    assert all(route is routes[0] for route in routes)
    seen = every_observation(walking)
    assert len({tuple(o.user_location) for o in seen}) > 1


def test_the_environment_shows_each_users_moving_links():
    env = ContentionEnv(use_case=1, users=4, n_requests=300, topology=str(CAMPUS), load=0.05,
                        mobility="random-waypoint", speed_mps=(8.0, 14.0), pause_s=0.0)
    observation, _ = env.reset(seed=3)
    locations, conditions = [], []
    for _ in range(120):
        locations.append(tuple(observation["user_location"]))
        conditions.append(tuple(observation["server_condition"]))
        observation, _, terminated, truncated, _ = env.step(0)
        assert not (terminated or truncated)
    assert len(set(locations)) > 50 and len(set(conditions)) > 1


@pytest.mark.parametrize(("changes", "message"), [
    (dict(mobility="random-waypoint", topology=ROOT / "topologies" / "paper_5servers.json"),
     r"^mobility random-waypoint: .*paper_5servers\.json: edge servers: a user who moves needs every edge "
     r"server's position"),
    (dict(mobility="route"), r"^mobility route: needs route FILE$"),
    (dict(pause_s=5.0), r"^pause_s: only with mobility random-waypoint$"),
    (dict(mobility="random-waypoint", user_conditions="generated"),
     r"^user_conditions generated: only with mobility off"),
])
def test_settings_that_do_not_go_together_are_one_line(changes, message):
    with pytest.raises(ContentionError, match=message) as raised:
        world(**changes)
    assert "\n" not in str(raised.value)


def test_a_sweep_point_records_how_the_users_move_only_when_they_do():
    still = SweepConfig(base=dataclasses.replace(BASE, users=3), loads=(0.1,), safetail=False, methods=("Oracle",))
    assert "mobility" not in still.point_settings(0.1)
    moving = dataclasses.replace(still, base=dataclasses.replace(still.base, mobility="random-waypoint",
                                                                 speed_mps=(8.0, 14.0)))
    settings = moving.point_settings(0.1)
    assert settings["mobility"] == "random-waypoint" and settings["speed_mps"] == [8.0, 14.0]
    back = SweepConfig.from_point_settings(settings).base
    assert (back.mobility, back.route, back.speed_mps, back.pause_s) == ("random-waypoint", None, (8.0, 14.0), 30.0)


@pytest.mark.parametrize(("changes", "message"), [
    (dict(mobility="random-waypoint", topology=ROOT / "topologies" / "paper_5servers.json"),
     r"^--mobility random-waypoint: .*paper_5servers\.json: edge servers: a user who moves needs"),
    (dict(route=ROOT / "routes" / "campus_walk.csv"), r"^--route: only with --mobility route$"),
    (dict(speed_mps=(8.0, 14.0)), r"^--speed-mps: only with --mobility random-waypoint$"),
])
def test_a_sweep_refuses_mobility_options_that_do_not_go_together_before_any_point(changes, message):
    from yafs_safetail.commands.sweeps import check_mobility

    with pytest.raises(ContentionError, match=message):
        check_mobility(dataclasses.replace(BASE, **changes))
    check_mobility(dataclasses.replace(BASE, mobility="route", route=ROOT / "routes" / "campus_walk.csv"))

"""Positions, the distance-to-condition rule and routes (edge.positions, edge.signal, edge.routes)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from yafs_safetail.edge.positions import (
    EARTH_RADIUS_M,
    Origin,
    PositionError,
    project_m,
)
from yafs_safetail.edge.routes import (
    RandomWaypoint,
    RouteError,
    project_route_m,
    random_waypoint,
    read_route,
)
from yafs_safetail.edge.signal import DEFAULT_SIGNAL_RULE, SignalRule, distances_m
from yafs_safetail.edge.topology_io import ScenarioError, load_topology

ORIGIN = Origin(41.39, 2.11)


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# ----------------------------------------------------------------------------- positions


def test_projection_puts_the_origin_at_zero_and_a_degree_of_latitude_at_its_arc() -> None:
    assert np.allclose(project_m(ORIGIN.lat_deg, ORIGIN.lon_deg, ORIGIN), [0.0, 0.0])
    north = project_m(ORIGIN.lat_deg + 1.0, ORIGIN.lon_deg, ORIGIN)
    assert north[0] == pytest.approx(0.0)
    assert np.allclose(project_route_m(np.array([[ORIGIN.lat_deg + 1.0, ORIGIN.lon_deg + 0.5]]), ORIGIN),
                       [project_m(ORIGIN.lat_deg + 1.0, ORIGIN.lon_deg + 0.5, ORIGIN)])
    assert north[1] == pytest.approx(EARTH_RADIUS_M * math.pi / 180.0)


def test_projection_agrees_with_the_great_circle_distance_over_a_few_kilometres() -> None:
    lat, lon = ORIGIN.lat_deg + 0.02, ORIGIN.lon_deg + 0.03  # about 2.2 km north, 2.5 km east
    x_m, y_m = project_m(lat, lon, ORIGIN)
    phi1, phi2 = math.radians(ORIGIN.lat_deg), math.radians(lat)
    haversine = 2 * EARTH_RADIUS_M * math.asin(math.sqrt(
        math.sin((phi2 - phi1) / 2) ** 2
        + math.cos(phi1) * math.cos(phi2) * math.sin(math.radians(lon - ORIGIN.lon_deg) / 2) ** 2))
    assert math.hypot(x_m, y_m) == pytest.approx(haversine, rel=1e-3)


def test_a_longitude_across_the_antimeridian_is_taken_the_short_way() -> None:
    origin = Origin(0.0, 179.999)
    assert project_m(0.0, -179.999, origin)[0] == pytest.approx(EARTH_RADIUS_M * math.radians(0.002))


@pytest.mark.parametrize("lat, lon", [(91.0, 0.0), (0.0, 181.0), (math.nan, 0.0)])
def test_an_origin_off_the_globe_is_refused(lat: float, lon: float) -> None:
    with pytest.raises(PositionError):
        Origin(lat, lon)


def test_distances_are_per_user_position_and_server() -> None:
    got = distances_m(np.array([[0.0, 0.0], [3.0, 4.0]]), np.array([[0.0, 0.0], [6.0, 8.0]]))
    assert np.allclose(got, [[0.0, 10.0], [5.0, 5.0]])


# ----------------------------------------------------------------------------- signal


def test_the_default_rule_changes_condition_at_about_10_21_46_and_100_metres() -> None:
    edges = DEFAULT_SIGNAL_RULE.distance_edges_m()
    assert [round(e, 1) for e in edges] == [10.0, 21.5, 46.2, 99.6]
    assert DEFAULT_SIGNAL_RULE.condition(np.array([0.0, 9.0, 15.0, 30.0, 70.0, 500.0])).tolist() == [1, 1, 2, 3, 4, 5]


def test_a_distance_exactly_on_an_edge_keeps_the_better_condition() -> None:
    edges = DEFAULT_SIGNAL_RULE.distance_edges_m()
    # The received power at each edge distance equals the band edge up to rounding: nudge in.
    assert DEFAULT_SIGNAL_RULE.condition(np.array(edges) * (1 - 1e-12)).tolist() == [1, 2, 3, 4]
    assert DEFAULT_SIGNAL_RULE.condition(np.array(edges) * (1 + 1e-12)).tolist() == [2, 3, 4, 5]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(0.0, 1e5, allow_nan=False), min_size=2, max_size=30))
def test_the_condition_never_improves_with_distance(distances: list[float]) -> None:
    ordered = np.sort(np.asarray(distances))
    conditions = DEFAULT_SIGNAL_RULE.condition(ordered)
    assert np.all(np.diff(conditions) >= 0)
    assert set(conditions.tolist()) <= {1, 2, 3, 4, 5}


def test_band_edges_must_decrease() -> None:
    with pytest.raises(ValueError, match="band_edges_dbm"):
        SignalRule(band_edges_dbm=(-50.0, -40.0, -70.0, -80.0))


# ----------------------------------------------------------------------------- routes


def test_a_csv_route_in_metres_is_interpolated_and_held_at_its_ends(tmp_path: Path) -> None:
    route = read_route(write(tmp_path, "r.csv", "time_s,x_m,y_m\n10,0,0\n20,100,0\n# a comment\n40,100,50\n"), None)
    got = route.positions_m([0.0, 10.0, 15.0, 30.0, 99.0])
    assert np.allclose(got, [[0, 0], [0, 0], [50, 0], [100, 25], [100, 50]])
    assert route.length_m == pytest.approx(150.0)


def test_a_csv_route_in_degrees_lands_on_the_topology_plane(tmp_path: Path) -> None:
    text = f"time_s,lat,lon\n0,{ORIGIN.lat_deg},{ORIGIN.lon_deg}\n60,{ORIGIN.lat_deg + 0.001},{ORIGIN.lon_deg}\n"
    route = read_route(write(tmp_path, "r.csv", text), ORIGIN)
    assert np.allclose(route.xy_m[0], [0, 0])
    assert route.xy_m[1][1] == pytest.approx(111.2, abs=0.1)


GPX = """<?xml version="1.0"?>
<gpx version="1.1" creator="test" xmlns="http://www.topografix.com/GPX/1/1">
 <trk><trkseg>
  <trkpt lat="41.39" lon="2.11"><time>2026-11-27T10:00:00Z</time></trkpt>
  <trkpt lat="41.391" lon="2.11"><time>2026-11-27T10:01:30Z</time></trkpt>
  {extra}
 </trkseg></trk>
</gpx>
"""


def test_a_gpx_track_counts_time_from_its_first_point(tmp_path: Path) -> None:
    route = read_route(write(tmp_path, "r.gpx", GPX.format(extra="")), ORIGIN)
    assert route.times_s.tolist() == [0.0, 90.0]
    assert route.xy_m[1][1] == pytest.approx(111.2, abs=0.1)


@pytest.mark.parametrize("name, text, origin, message", [
    ("r.txt", "time_s,x_m,y_m\n0,0,0\n", None, r"r\.txt: file: expected a \.csv or \.gpx route"),
    ("r.csv", "", None, r"r\.csv: header: empty"),
    ("r.csv", "t,x,y\n0,0,0\n", None, r"r\.csv: header: got 't,x,y'"),
    ("r.csv", "time_s,x_m,y_m\n", None, r"r\.csv: point 1: the route has no points"),
    ("r.csv", "time_s,x_m,y_m\n0,0,0\n5,a,0\n", None, r"r\.csv: point 2: x_m is not a number: 'a'"),
    ("r.csv", "time_s,x_m,y_m\n0,0,0\n5,0\n", None, r"r\.csv: point 2: expected 3 values, got 2"),
    ("r.csv", "time_s,x_m,y_m\n0,0,0\n5,inf,0\n", None, r"r\.csv: point 2: x_m is not finite"),
    ("r.csv", "time_s,x_m,y_m\n10,0,0\n5,1,0\n", None, r"r\.csv: point 2: time 5 s is before the previous point's \(10 s\)"),
    ("r.csv", "time_s,x_m,y_m\n10,0,0\n10,1,0\n", None, r"r\.csv: point 2: at the previous point's time .* jump"),
    ("r.csv", "time_s,x_m,y_m\n-1,0,0\n", None, r"r\.csv: point 1: time -1 s is before the run starts"),
    ("r.csv", "time_s,lat,lon\n0,41.39,2.11\n", None, r"r\.csv: point 1: the route is in degrees .* in metres"),
    ("r.csv", "time_s,lat,lon\n0,41.39,2.11\n1,95,2.11\n", ORIGIN, r"r\.csv: point 2: latitude 95\.0 is not in \[-90, 90\]"),
    ("r.gpx", "<gpx><trk>", ORIGIN, r"r\.gpx: line 1, column 10: not well-formed XML"),
    ("r.gpx", "<gpx/>", ORIGIN, r"r\.gpx: trkpt: the GPX file has no track points"),
    ("r.gpx", GPX.format(extra='<trkpt lat="41.4" lon="2.11"/>'), ORIGIN, r"r\.gpx: point 3: no <time>"),
    ("r.gpx", GPX.format(extra='<trkpt lat="x" lon="2.11"><time>2026-11-27T10:02:00Z</time></trkpt>'), ORIGIN,
     r"r\.gpx: point 3: lat is not a number: 'x'"),
    ("r.gpx", GPX.format(extra='<trkpt lat="41.4" lon="2.11"><time>noon</time></trkpt>'), ORIGIN,
     r"r\.gpx: point 3: time 'noon' is not an ISO 8601 time"),
])
def test_a_bad_route_names_the_file_the_point_and_the_problem(tmp_path: Path, name: str, text: str,
                                                               origin: Origin | None, message: str) -> None:
    with pytest.raises(RouteError, match=message) as caught:
        read_route(write(tmp_path, name, text), origin)
    assert "\n" not in str(caught.value)


def test_a_missing_route_file_is_one_line(tmp_path: Path) -> None:
    with pytest.raises(RouteError, match=r"nope\.csv: file: cannot be read \(FileNotFoundError"):
        read_route(tmp_path / "nope.csv", None)


# ----------------------------------------------------------------------------- random waypoint

AREA = (-50.0, -50.0, 150.0, 100.0)


def test_random_waypoint_is_the_same_route_for_the_same_seed_and_another_for_another() -> None:
    model = RandomWaypoint(AREA, (1.0, 1.5), pause_s=5.0)
    first = random_waypoint(model, (0.0, 0.0), 3600.0, np.random.default_rng(3))
    again = random_waypoint(model, (0.0, 0.0), 3600.0, np.random.default_rng(3))
    other = random_waypoint(model, (0.0, 0.0), 3600.0, np.random.default_rng(4))
    assert np.array_equal(first.xy_m, again.xy_m) and np.array_equal(first.times_s, again.times_s)
    assert not np.array_equal(first.xy_m[1:3], other.xy_m[1:3])


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), slowest=st.floats(0.1, 20.0), spread=st.floats(1.0, 3.0),
       pause_s=st.floats(0.0, 60.0))
def test_random_waypoint_moves_within_its_area_at_speeds_within_its_range(
        seed: int, slowest: float, spread: float, pause_s: float) -> None:
    model = RandomWaypoint(AREA, (slowest, slowest * spread), pause_s=pause_s)
    route = random_waypoint(model, (0.0, 0.0), 1800.0, np.random.default_rng(seed))
    assert route.times_s[-1] >= 1800.0
    assert np.all(np.diff(route.times_s) >= 0)
    x, y = route.xy_m[1:, 0], route.xy_m[1:, 1]
    assert np.all((AREA[0] <= x) & (x <= AREA[2]) & (AREA[1] <= y) & (y <= AREA[3]))
    legs_m = np.hypot(*np.diff(route.xy_m, axis=0).T)
    legs_s = np.diff(route.times_s)
    moving = legs_m > 0
    speeds = legs_m[moving] / legs_s[moving]
    assert np.all(speeds >= slowest * (1 - 1e-9)) and np.all(speeds <= slowest * spread * (1 + 1e-9))


def test_random_waypoint_at_rest_draws_nothing_and_stays() -> None:
    rng = np.random.default_rng(0)
    route = random_waypoint(RandomWaypoint(AREA, (0.0, 0.0)), (3.0, 4.0), 600.0, rng)
    assert np.allclose(route.positions_m([0.0, 300.0, 1e6]), [[3, 4]] * 3)
    assert rng.random() == np.random.default_rng(0).random()


@pytest.mark.parametrize("kwargs, field", [
    ({"speed_mps": (0.0, 2.0)}, "speed_mps"),
    ({"speed_mps": (3.0, 2.0)}, "speed_mps"),
    ({"pause_s": -1.0}, "pause_s"),
    ({"area_m": (10.0, 0.0, 0.0, 10.0)}, "area_m"),
])
def test_random_waypoint_refuses_parameters_that_make_no_sense(kwargs: dict, field: str) -> None:
    values = {"area_m": AREA, "speed_mps": (1.0, 2.0), "pause_s": 0.0, **kwargs}
    with pytest.raises(ValueError, match=field):
        RandomWaypoint(**values)


def test_an_area_of_one_point_ends_the_route_there() -> None:
    route = random_waypoint(RandomWaypoint((5.0, 5.0, 5.0, 5.0), (1.0, 1.0)), (0.0, 0.0), 1e6,
                            np.random.default_rng(1))
    assert np.allclose(route.positions_m([1e7]), [[5.0, 5.0]])


# ----------------------------------------------------------------------------- topology positions


def topology(**placed: dict) -> dict:
    """The paper topology's shape: user 0, access point 1, servers 2..4, positions as given."""
    entities = [{"id": 0, "type": "user"}, {"id": 1, "type": "access_point"}]
    entities += [{"id": node, "type": "edge_server"} for node in (2, 3, 4)]
    for key, values in placed.items():
        entities[int(key[1:])].update(values)
    links = [{"s": 0, "d": 1, "BW": 2.5, "PR": 0.0}]
    links += [{"s": 1, "d": node, "BW": 2.5, "PR": 0.0, "condition": node - 1} for node in (2, 3, 4)]
    return {"entity": entities, "link": links}


def test_a_topology_without_positions_reads_as_before() -> None:
    read = load_topology(topology())
    assert read.server_positions_m == {} and read.origin is None and read.user_location == (0.0, 0.0)


def test_a_topology_in_metres_places_the_user_and_every_server() -> None:
    read = load_topology(topology(e0={"x": 1.0, "y": 2.0}, e2={"x": 10.0, "y": 0.0}, e3={"x": 0.0, "y": 30.0},
                                  e4={"x": -60.0, "y": 0.0}))
    assert read.user_location == (1.0, 2.0) and read.origin is None
    assert read.server_positions_m == {2: (10.0, 0.0), 3: (0.0, 30.0), 4: (-60.0, 0.0)}


def test_a_topology_in_degrees_is_projected_around_its_first_placed_entity() -> None:
    read = load_topology(topology(e0={"lat": 41.39, "lon": 2.11}, e2={"lat": 41.3901, "lon": 2.11},
                                  e3={"lat": 41.39, "lon": 2.1101}, e4={"lat": 41.3899, "lon": 2.11}))
    assert read.origin == Origin(41.39, 2.11)
    assert read.user_location == (0.0, 0.0)
    assert read.server_positions_m[2][1] == pytest.approx(11.12, abs=0.01)
    assert read.server_positions_m[3][0] == pytest.approx(8.34, abs=0.01)


@pytest.mark.parametrize("placed, message", [
    ({"e2": {"x": 1.0, "lat": 2.0}}, r"entity\[2\]: mixes metres \(x, y\) and degrees"),
    ({"e0": {"x": 0.0}, "e2": {"lat": 41.0, "lon": 2.0}, "e3": {"lat": 41.0, "lon": 2.0},
      "e4": {"lat": 41.0, "lon": 2.0}}, r"entity\[2\]: gives degrees but entity\[0\] gives metres"),
    ({"e2": {"x": 1.0, "y": 0.0}, "e3": {"x": 2.0, "y": 0.0}}, r"entity\[4\]: has no position while other edge servers"),
    ({"e2": {"x": 1.0}, "e3": {"x": 2.0, "y": 0.0}, "e4": {"x": 3.0, "y": 0.0}}, r"entity\[2\]\.y: missing; x and y go together"),
    ({"e2": {"lat": 91.0, "lon": 0.0}}, r"entity\[2\]: latitude 91\.0 is not in \[-90, 90\]"),
    ({"e3": {"x": "near", "y": 0.0}}, r"entity\[3\]\.x: not a finite number: 'near'"),
])
def test_a_bad_position_names_the_file_the_entity_and_the_problem(placed: dict, message: str) -> None:
    with pytest.raises(ScenarioError, match=r"<topology dict>: " + message):
        load_topology(topology(**placed))

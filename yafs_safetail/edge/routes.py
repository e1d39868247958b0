"""How the user moves: a route of timed points, read from a file or drawn by random waypoint.

A :class:`Route` is the user's position over the run's clock (seconds from the first request's
send time), in metres on the topology's plane (``edge.positions``); between two points the user
moves in a straight line at constant speed, before the first point it is at the first, after
the last it stays at the last. Two ways to get one, chosen by name (:data:`MOBILITY_MODELS`):

* ``route``: a file the user gives (:func:`read_route`), a CSV (``time_s,x_m,y_m`` or
  ``time_s,lat,lon``, a header row first) or a GPX track (``trkpt`` with ``lat``, ``lon`` and
  ``time``; times counted from the first point);
* ``random-waypoint`` (:func:`random_waypoint`): from the user's topology position, a
  destination drawn uniformly in an area, a speed drawn uniformly in a range, a pause, again
  (Johnson & Maltz, 1996). The slowest speed must be above zero (Yoon, Liu & Noble, "Random
  waypoint considered harmful", INFOCOM 2003: with speeds down to zero the mean speed decays
  towards zero as the run goes on); a range of exactly (0, 0) is the user at rest.

A bad file gives one line naming the file, the point and what is wrong (:class:`RouteError`).
"""

from __future__ import annotations

import csv
import datetime
import math
import xml.etree.ElementTree as ElementTree
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from yafs_safetail.edge.positions import Origin, PositionError, check_degrees, project_m

MOBILITY_MODELS = ("off", "random-waypoint", "route")
ROUTE_SUFFIXES = (".csv", ".gpx")
METRE_COLUMNS = ("time_s", "x_m", "y_m")
DEGREE_COLUMNS = ("time_s", "lat", "lon")


class RouteError(ValueError):
    """A route file that cannot be used: ``<file>: <point or field>: <what is wrong>``."""

    def __init__(self, source: str, where: str, problem: str) -> None:
        super().__init__(f"{source}: {where}: {problem}")


@dataclass(frozen=True)
class Route:
    """Timed points of the user's path.

    Attributes:
        times_s: when the user is at each point, non-decreasing (equal times are not allowed
            between different positions: that would be a jump).
        xy_m: the points, shape (k, 2), metres on the topology's plane.
        source: where the route came from, for messages and run.json.
    """

    times_s: np.ndarray
    xy_m: np.ndarray
    source: str

    def positions_m(self, at_s: np.ndarray | Sequence[float]) -> np.ndarray:
        """The user's position at each time of ``at_s``: shape (m, 2)."""
        at = np.asarray(at_s, dtype=float)
        if len(self.times_s) == 1:
            return np.broadcast_to(self.xy_m[0], (*at.shape, 2)).copy()
        return np.stack([np.interp(at, self.times_s, self.xy_m[:, axis]) for axis in (0, 1)], axis=-1)

    @property
    def length_m(self) -> float:
        """The path's length."""
        return float(np.hypot(*np.diff(self.xy_m, axis=0).T).sum()) if len(self.xy_m) > 1 else 0.0


def at_rest(xy_m: tuple[float, float], source: str = "at rest") -> Route:
    """The user staying at ``xy_m``."""
    return Route(np.zeros(1), np.asarray([xy_m], dtype=float), source)


def read_route(path: Path, origin: Origin | None) -> Route:
    """A route file (.csv or .gpx) as metres on the topology's plane.

    Args:
        path: the file.
        origin: the topology's origin when it places things in degrees; None when it uses
            metres (then a route in degrees cannot be placed, and is refused).

    Raises:
        RouteError: a missing or unreadable file, an unknown suffix, a bad point.
    """
    source = str(path)
    if path.suffix.lower() not in ROUTE_SUFFIXES:
        raise RouteError(source, "file", f"expected a {' or '.join(ROUTE_SUFFIXES)} route, got {path.suffix or 'no suffix'!r}")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise RouteError(source, "file", f"cannot be read ({error.__class__.__name__}: {error})") from None
    if path.suffix.lower() == ".csv":
        times, coordinates, degrees = _csv_points(source, text)
    else:
        times, coordinates, degrees = _gpx_points(source, text)
    if degrees and origin is None:
        raise RouteError(source, "point 1", "the route is in degrees (lat, lon) but the topology places "
                         "its user and servers in metres (x, y); give both in the same units")
    xy_m = project_route_m(coordinates, origin) if degrees and origin else coordinates
    _check_times(source, times, xy_m)
    return Route(times, np.asarray(xy_m, dtype=float), source)


def project_route_m(lat_lon_deg: np.ndarray, origin: Origin) -> np.ndarray:
    """``edge.positions.project_m`` of every (lat, lon) row: shape (k, 2) metres (a route is
    read once, so one point at a time costs nothing that matters)."""
    return np.asarray([project_m(float(lat), float(lon), origin) for lat, lon in lat_lon_deg],
                      dtype=float).reshape(-1, 2)


def _number(source: str, where: str, name: str, text: str | None) -> float:
    try:
        value = float(text if text is not None else "")
    except ValueError:
        raise RouteError(source, where, f"{name} is not a number: {text!r}") from None
    if not math.isfinite(value):
        raise RouteError(source, where, f"{name} is not finite: {text!r}")
    return value


def _csv_points(source: str, text: str) -> tuple[np.ndarray, np.ndarray, bool]:
    rows = [row for row in csv.reader(text.splitlines()) if row and not row[0].lstrip().startswith("#")]
    if not rows:
        raise RouteError(source, "header", f"empty; expected {','.join(METRE_COLUMNS)} or {','.join(DEGREE_COLUMNS)}")
    header = tuple(cell.strip() for cell in rows[0])
    if header not in (METRE_COLUMNS, DEGREE_COLUMNS):
        raise RouteError(source, "header", f"got {','.join(header)!r}; expected "
                         f"{','.join(METRE_COLUMNS)} or {','.join(DEGREE_COLUMNS)}")
    degrees = header == DEGREE_COLUMNS
    if len(rows) < 2:
        raise RouteError(source, "point 1", "the route has no points")
    times, coordinates = [], []
    for index, row in enumerate(rows[1:], start=1):
        where = f"point {index}"
        if len(row) != len(header):
            raise RouteError(source, where, f"expected {len(header)} values, got {len(row)}")
        values = [_number(source, where, name, cell.strip()) for name, cell in zip(header, row, strict=True)]
        if degrees:
            _check_point_degrees(source, where, values[1], values[2])
        times.append(values[0])
        coordinates.append(values[1:])
    return np.asarray(times), np.asarray(coordinates, dtype=float), degrees


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _gpx_points(source: str, text: str) -> tuple[np.ndarray, np.ndarray, bool]:
    try:
        root = ElementTree.fromstring(text)
    except ElementTree.ParseError as error:
        line, column = error.position
        raise RouteError(source, f"line {line}, column {column}", "not well-formed XML") from None
    points = [element for element in root.iter() if _local(element.tag) == "trkpt"]
    if not points:
        raise RouteError(source, "trkpt", "the GPX file has no track points (trk/trkseg/trkpt)")
    stamps, coordinates = [], []
    for index, point in enumerate(points, start=1):
        where = f"point {index}"
        lat = _number(source, where, "lat", point.get("lat"))
        lon = _number(source, where, "lon", point.get("lon"))
        _check_point_degrees(source, where, lat, lon)
        time_text = next((child.text for child in point if _local(child.tag) == "time"), None)
        if time_text is None:
            raise RouteError(source, where, "no <time>: a route is a list of timed points")
        try:
            stamp = datetime.datetime.fromisoformat(time_text.strip())
        except ValueError:
            raise RouteError(source, where, f"time {time_text.strip()!r} is not an ISO 8601 time") from None
        if stamp.tzinfo is None:
            stamp = stamp.replace(tzinfo=datetime.UTC)
        stamps.append(stamp)
        coordinates.append((lat, lon))
    times = np.asarray([(stamp - stamps[0]).total_seconds() for stamp in stamps])
    return times, np.asarray(coordinates, dtype=float), True


def _check_point_degrees(source: str, where: str, lat: float, lon: float) -> None:
    try:
        check_degrees(lat, lon)
    except PositionError as error:
        raise RouteError(source, where, str(error)) from None


def _check_times(source: str, times: np.ndarray, xy_m: np.ndarray) -> None:
    seconds = [float(t) for t in times]
    if seconds[0] < 0:
        raise RouteError(source, "point 1", f"time {seconds[0]:g} s is before the run starts (0 s)")
    for index in range(1, len(seconds)):
        if seconds[index] < seconds[index - 1]:
            raise RouteError(source, f"point {index + 1}", f"time {seconds[index]:g} s is before the previous "
                             f"point's ({seconds[index - 1]:g} s)")
        if seconds[index] == seconds[index - 1] and not np.array_equal(xy_m[index], xy_m[index - 1]):
            raise RouteError(source, f"point {index + 1}", f"at the previous point's time ({seconds[index]:g} s) "
                             "but somewhere else: the user would jump")


@dataclass(frozen=True)
class RandomWaypoint:
    """The random-waypoint model's parameters.

    Attributes:
        area_m: (x_min, y_min, x_max, y_max), where destinations are drawn.
        speed_mps: (slowest, fastest); (0, 0) is at rest, otherwise 0 < slowest <= fastest.
        pause_s: the stop at each destination.
    """

    area_m: tuple[float, float, float, float]
    speed_mps: tuple[float, float]
    pause_s: float = 0.0

    def __post_init__(self) -> None:
        x_min, y_min, x_max, y_max = self.area_m
        if not all(math.isfinite(v) for v in self.area_m) or x_min > x_max or y_min > y_max:
            raise ValueError(f"area_m: expected finite x_min <= x_max and y_min <= y_max, got {self.area_m!r}")
        slowest, fastest = self.speed_mps
        if (slowest, fastest) != (0.0, 0.0) and not (0.0 < slowest <= fastest and math.isfinite(fastest)):
            raise ValueError(f"speed_mps: expected 0 < slowest <= fastest (or 0, 0 for at rest), got {self.speed_mps!r}")
        if not (math.isfinite(self.pause_s) and self.pause_s >= 0.0):
            raise ValueError(f"pause_s: expected a non-negative number, got {self.pause_s!r}")

    @property
    def at_rest(self) -> bool:
        return self.speed_mps == (0.0, 0.0)


def random_waypoint(model: RandomWaypoint, start_xy_m: tuple[float, float], duration_s: float,
                    rng: np.random.Generator) -> Route:
    """A random-waypoint route from ``start_xy_m`` covering at least ``duration_s``.

    Each leg draws, in this order, a destination (x then y, uniform in the area) and a speed
    (uniform in the range); the user arrives, pauses, and the next leg starts. At rest, no
    number is drawn.
    """
    start = np.asarray(start_xy_m, dtype=float)
    if model.at_rest:
        return at_rest((float(start[0]), float(start[1])), "random-waypoint at rest")
    x_min, y_min, x_max, y_max = model.area_m
    times, points = [0.0], [start]
    while times[-1] < duration_s:
        destination = np.array([rng.uniform(x_min, x_max), rng.uniform(y_min, y_max)])
        speed_mps = rng.uniform(*model.speed_mps)
        leg_s = float(np.hypot(*(destination - points[-1]))) / speed_mps
        times.append(times[-1] + leg_s)
        points.append(destination)
        if model.pause_s > 0:
            times.append(times[-1] + model.pause_s)
            points.append(destination)
        if x_min == x_max and y_min == y_max:
            break  # an area of one point: the user goes there and stays
    return Route(np.asarray(times), np.asarray(points), "random-waypoint")

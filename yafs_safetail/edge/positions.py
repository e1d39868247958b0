"""Where things are: coordinates in a topology or a route, in metres on one local plane.

A topology may place its user and edge servers in metres (``"x"``, ``"y"``) or in degrees
(``"lat"``, ``"lon"``), never both in one file. Degrees are projected onto a local plane
around one origin (:class:`Origin`, the first entity with degrees in the file) by the
equirectangular projection: x east, y north, in metres. Over the few kilometres an edge
scenario spans, its distance error is below 0.1% (the projection keeps north-south distances
exact and scales east-west ones by cos(latitude), which varies by less than that over a few
kilometres away from the poles), which is far below what changes a link's condition.

Every function here is pure and light (no file, no NumPy): ``edge.topology_io`` and
``edge.routes`` read the files and name the entry that is wrong.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: The mean Earth radius (IUGG), the sphere the projection assumes.
EARTH_RADIUS_M = 6_371_008.8
METRE_KEYS = ("x", "y")
DEGREE_KEYS = ("lat", "lon")


class PositionError(ValueError):
    """A coordinate that cannot be read; the caller adds the file and the entry."""


@dataclass(frozen=True)
class Origin:
    """The point of the local plane at (0, 0) m, in degrees."""

    lat_deg: float
    lon_deg: float

    def __post_init__(self) -> None:
        check_degrees(self.lat_deg, self.lon_deg)


def check_degrees(lat_deg: float, lon_deg: float) -> None:
    """Raises PositionError unless -90 <= lat <= 90 and -180 <= lon <= 180 (both finite)."""
    if not (math.isfinite(lat_deg) and -90.0 <= lat_deg <= 90.0):
        raise PositionError(f"latitude {lat_deg!r} is not in [-90, 90]")
    if not (math.isfinite(lon_deg) and -180.0 <= lon_deg <= 180.0):
        raise PositionError(f"longitude {lon_deg!r} is not in [-180, 180]")


def project_m(lat_deg: float, lon_deg: float, origin: Origin) -> tuple[float, float]:
    """Degrees to metres (x east, y north) on the plane around ``origin``.

    Longitudes are taken the short way round from the origin's (a route across the
    antimeridian stays continuous). Plain floats, no NumPy: a topology is read before a run's
    arguments are checked (``edge.routes`` projects a whole route at once).
    """
    east_deg = (lon_deg - origin.lon_deg + 180.0) % 360.0 - 180.0
    x_m = EARTH_RADIUS_M * math.radians(east_deg) * math.cos(math.radians(origin.lat_deg))
    y_m = EARTH_RADIUS_M * math.radians(lat_deg - origin.lat_deg)
    return x_m, y_m

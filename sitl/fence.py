"""ArduPlane's geofence on the built-in SITL, sans I/O: the items of the mission protocol's
fence list (MAV_MISSION_TYPE_FENCE) as areas, and which of them a position breaches.

As ArduPilot's ``AC_PolyFence_loader`` and ``AC_Fence``: an inclusion polygon or circle
must contain the vehicle, an exclusion one must not; a polygon is its vertices in order,
each item of it carrying the vertex count in param1; a circle's radius is param1 (metres);
fences have no floor and no ceiling (FENCE_ALT_MAX and _MIN are other fence types, not
simulated).  Distances in a local flat frame round the position checked: fences span
kilometres, not hundreds of them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from gcs_ppf.mavlink.enums import (
    MAV_MISSION_ACCEPTED,
    MAV_MISSION_INVALID_PARAM1,
    MAV_MISSION_INVALID_PARAM5_X,
    MAV_MISSION_INVALID_PARAM6_Y,
    MAV_MISSION_UNSUPPORTED,
    MAV_MISSION_UNSUPPORTED_FRAME,
)
from sitl.mission_protocol import GLOBAL_FRAMES, MissionItem

RETURN_POINT = 5000
POLYGON_INCLUSION = 5001
POLYGON_EXCLUSION = 5002
CIRCLE_INCLUSION = 5003
CIRCLE_EXCLUSION = 5004
FENCE_COMMANDS = frozenset(
    {RETURN_POINT, POLYGON_INCLUSION, POLYGON_EXCLUSION, CIRCLE_INCLUSION, CIRCLE_EXCLUSION}
)
EARTH_RADIUS_M = 6_378_137.0
BREACH_BOUNDARY = 4
"""FENCE_BREACH_BOUNDARY of FENCE_STATUS: a polygon's or circle's."""


@dataclass(frozen=True)
class Area:
    """One fence: a polygon (``vertices``, lat/lon degrees) or a circle (``center``,
    ``radius_m``), to stay inside (``inclusion``) or out of."""

    inclusion: bool
    vertices: tuple[tuple[float, float], ...] = ()
    center: tuple[float, float] | None = None
    radius_m: float = 0.0


def validate_item(item: MissionItem) -> int:
    """MAV_MISSION_RESULT of storing ``item`` in the fence list."""
    if item.command not in FENCE_COMMANDS:
        return MAV_MISSION_UNSUPPORTED
    if item.frame not in GLOBAL_FRAMES:
        return MAV_MISSION_UNSUPPORTED_FRAME
    if item.command in (POLYGON_INCLUSION, POLYGON_EXCLUSION) and not (
        math.isfinite(item.param1) and item.param1 >= 3
    ):
        return MAV_MISSION_INVALID_PARAM1
    if item.command in (CIRCLE_INCLUSION, CIRCLE_EXCLUSION) and not (
        math.isfinite(item.param1) and item.param1 > 0
    ):
        return MAV_MISSION_INVALID_PARAM1
    if not -900_000_000 <= item.x <= 900_000_000:
        return MAV_MISSION_INVALID_PARAM5_X
    if not -1_800_000_000 <= item.y <= 1_800_000_000:
        return MAV_MISSION_INVALID_PARAM6_Y
    return MAV_MISSION_ACCEPTED


def areas(items: Sequence[MissionItem]) -> list[Area] | None:
    """The fences of a stored list; None when a polygon's vertices do not come as many in a
    row as each of them says (ArduPilot refuses such a list whole)."""
    out: list[Area] = []
    k = 0
    while k < len(items):
        it = items[k]
        if it.command in (CIRCLE_INCLUSION, CIRCLE_EXCLUSION):
            center = (it.x * 1e-7, it.y * 1e-7)
            out.append(Area(it.command == CIRCLE_INCLUSION, center=center, radius_m=it.param1))
            k += 1
        elif it.command in (POLYGON_INCLUSION, POLYGON_EXCLUSION):
            n = int(it.param1)
            run = items[k : k + n]
            if len(run) < n or any(v.command != it.command or int(v.param1) != n for v in run):
                return None
            vertices = tuple((v.x * 1e-7, v.y * 1e-7) for v in run)
            out.append(Area(it.command == POLYGON_INCLUSION, vertices=vertices))
            k += n
        else:  # the return point
            k += 1
    return out


def _local_m(lat0: float, lon0: float, lat: float, lon: float) -> tuple[float, float]:
    """East and north metres of (lat, lon) from (lat0, lon0), flat."""
    east = math.radians(lon - lon0) * EARTH_RADIUS_M * math.cos(math.radians(lat0))
    return east, math.radians(lat - lat0) * EARTH_RADIUS_M


def contains(area: Area, lat: float, lon: float) -> bool:
    """Whether the area holds the position (a polygon by the even-odd rule)."""
    if area.center is not None:
        e, n = _local_m(lat, lon, *area.center)
        return math.hypot(e, n) <= area.radius_m
    points = [_local_m(lat, lon, a, b) for a, b in area.vertices]
    inside = False
    for (x1, y1), (x2, y2) in zip(points, points[1:] + points[:1], strict=True):
        if (y1 > 0.0) != (y2 > 0.0) and x1 - y1 * (x2 - x1) / (y2 - y1) > 0.0:
            inside = not inside
    return inside


def breached(fences: Sequence[Area], lat: float, lon: float) -> list[Area]:
    """The fences the position breaches: outside an inclusion one, inside an exclusion one."""
    return [a for a in fences if contains(a, lat, lon) != a.inclusion]

"""The leader's route from a QGroundControl ``.plan``'s mission items (CONVENTIONS §3's
``route`` and ``target``).

Each ``MAV_CMD_NAV_WAYPOINT`` (16) item is a waypoint, in order: its acceptance radius is
the item's param2 (0: the route's default, 100 m), its position the item's lat/lon and
altitude (``frame`` 3, above the plan's home, or 0, above mean sea level) in the mission's
ICS.  ``MAV_CMD_NAV_LOITER_TURNS`` (18) and ``_LOITER_TIME`` (19) are waypoints with a
loiter: param1 turns or seconds, param3 the radius (negative: anticlockwise; 0:
ArduPlane's default WP_LOITER_RAD, 60 m).  The last is the target (a loiter there is
refused: the formation's end is ``at_end``), the others the route.  Items that are not
places to fly through — takeoff, land, RTL, unlimited loiters, ``DO_`` commands — are
left out and named; a ``ComplexItem`` (a survey, a corridor) and terrain-relative
altitudes are refused.  Every error names the item (``mission.items[k]``); nothing is
half read.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from gcs_ppf.geodesy import geodetic_to_enu
from gcs_ppf.mission import Loiter, Origin, Waypoint

NAV_WAYPOINT = 16
NAV_LOITER_TURNS = 18
NAV_LOITER_TIME = 19
DEFAULT_LOITER_RADIUS_M = 60.0
"""ArduPlane's WP_LOITER_RAD default: a loiter item's radius when its param3 is 0."""
FRAME_GLOBAL = 0  # altitude above mean sea level
FRAME_RELATIVE = 3  # altitude above the plan's home
DEFAULT_ACCEPTANCE_M = 100.0


class RouteImportError(ValueError):
    """A plan whose route cannot be read; the message names the item and the field."""


@dataclass(frozen=True)
class PlanRoute:
    """The route (all waypoints but the last), the target (the last), and the commands of
    the items left out (item index, MAV_CMD number)."""

    route: list[Waypoint]
    target: tuple[float, float, float]
    left_out: list[tuple[int, int]]


def _number(where: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise RouteImportError(f"{where}: a number expected, got {value!r}")
    return float(value)


def route_from_plan(doc: Any, origin: Origin) -> PlanRoute:
    """The leader's route and target from a ``.plan`` document, in ``origin``'s ICS."""
    if not isinstance(doc, dict) or doc.get("fileType") != "Plan":
        raise RouteImportError('fileType: not a QGroundControl plan (fileType "Plan")')
    mission = doc.get("mission")
    if not isinstance(mission, dict) or not isinstance(mission.get("items"), list):
        raise RouteImportError("mission.items: a list of mission items expected")
    items, home = mission["items"], mission.get("plannedHomePosition")
    points: list[Waypoint] = []
    left_out: list[tuple[int, int]] = []
    for k, item in enumerate(items):
        where = f"mission.items[{k}]"
        if not isinstance(item, dict) or item.get("type") != "SimpleItem":
            kind = item.get("type") if isinstance(item, dict) else item
            raise RouteImportError(f"{where}.type: {kind!r} is not a SimpleItem waypoint")
        command = item.get("command")
        if command not in (NAV_WAYPOINT, NAV_LOITER_TURNS, NAV_LOITER_TIME):
            left_out.append((k, int(command) if isinstance(command, int) else -1))
            continue
        params = item.get("params")
        if not isinstance(params, list) or len(params) != 7:
            raise RouteImportError(f"{where}.params: the 7 parameters of the command expected")
        lat = _number(f"{where}.params[4]", params[4])
        lon = _number(f"{where}.params[5]", params[5])
        alt = _number(f"{where}.params[6]", params[6])
        frame = item.get("frame")
        if frame == FRAME_RELATIVE:
            if not isinstance(home, list) or len(home) != 3:
                raise RouteImportError(
                    "mission.plannedHomePosition: [lat, lon, alt] needed for altitudes above home"
                )
            alt += _number("mission.plannedHomePosition[2]", home[2])
        elif frame != FRAME_GLOBAL:
            raise RouteImportError(
                f"{where}.frame: {frame!r}; only 3 (above home) and 0 (above mean sea level)"
            )
        if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
            raise RouteImportError(f"{where}.params: latitude {lat}, longitude {lon} off the Earth")
        x, y, z = geodetic_to_enu(lat, lon, alt, origin)
        if command == NAV_WAYPOINT:
            radius = _number(f"{where}.params[1]", params[1] if params[1] is not None else 0.0)
            accept = radius if radius > 0 else DEFAULT_ACCEPTANCE_M
            points.append(Waypoint(position=(x, y, z), acceptance_radius=accept))
        else:
            points.append(Waypoint(position=(x, y, z), loiter=_loiter(where, command, params)))
    if not points:
        raise RouteImportError("mission.items: no waypoint (MAV_CMD_NAV_WAYPOINT) in the plan")
    if points[-1].loiter is not None:
        raise RouteImportError(
            "mission.items: the last place is a loiter; the target is flown to, and the "
            "formation's end is the mission's at_end"
        )
    return PlanRoute(points[:-1], points[-1].position, left_out)


def _loiter(where: str, command: int, params: list[Any]) -> Loiter:
    """A loiter item's circles: param1 turns (18) or seconds (19), param3 the radius."""
    amount = _number(f"{where}.params[0]", params[0])
    if amount <= 0:
        what = "turns" if command == NAV_LOITER_TURNS else "seconds"
        raise RouteImportError(f"{where}.params[0]: {what} must be > 0, got {amount:g}")
    radius = _number(f"{where}.params[2]", params[2] if params[2] is not None else 0.0)
    size = abs(radius) if radius != 0 else DEFAULT_LOITER_RADIUS_M
    if command == NAV_LOITER_TURNS:
        return Loiter(radius_m=size, turns=amount, clockwise=radius >= 0)
    return Loiter(radius_m=size, time_s=amount, clockwise=radius >= 0)

"""A mission's zones as ArduPlane fence items (MAV_MISSION_TYPE_FENCE), and back.

ArduPlane's fences are footprints with no floor and no ceiling: an exclusion polygon or
circle keeps a vehicle out at every height, an inclusion one keeps it inside.  So an
inclusion zone is uploaded as its footprint always (inside the zone is inside the
footprint: the fence forbids nothing the zone allows); an exclusion zone only when it is
unbounded both ways (no floor, no ceiling), unless ``footprints`` is asked for, because the
planner may fly over a zone with a ceiling, or under one with a floor, where its footprint
fence would send the vehicle home.  Spheres (``obstacles``) are not fences.  Pure.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_ppf.geodesy import enu_to_geodetic
from gcs_ppf.mavlink.ardupilot import AUTOPILOT_COMPONENT_ID
from gcs_ppf.mission import CylinderZone, Mission, PolygonZone

POLYGON_INCLUSION = 5001
POLYGON_EXCLUSION = 5002
CIRCLE_INCLUSION = 5003
CIRCLE_EXCLUSION = 5004
FRAME_GLOBAL = 0
MISSION_TYPE_FENCE = 1


@dataclass(frozen=True)
class FenceItem:
    """One fence item as MISSION_ITEM_INT carries it: ``param1`` is a polygon's vertex
    count or a circle's radius (m); the vertex or centre in degE7."""

    command: int
    lat_e7: int
    lon_e7: int
    param1: float


def _latlon(mission: Mission, x: float, y: float) -> tuple[float, float]:
    lat, lon, _ = enu_to_geodetic(x, y, 0.0, mission.origin)
    return lat, lon


def _e7(lat: float, lon: float) -> tuple[int, int]:
    return round(lat * 1e7), round(lon * 1e7)


def fence_items(mission: Mission, footprints: bool = False) -> tuple[list[FenceItem], list[str]]:
    """The mission's zones as fence items, and why each zone left out was (its index)."""
    items: list[FenceItem] = []
    left_out: list[str] = []
    for k, zone in enumerate(mission.zones):
        bounded = zone.floor is not None or zone.ceiling is not None
        if not zone.inclusion and bounded and not footprints:
            left_out.append(
                f"zones[{k}]: an exclusion zone with a floor or a ceiling (a fence has neither: "
                "its footprint is uploaded only with fence_footprints)"
            )
            continue
        if isinstance(zone, CylinderZone):
            if zone.center_latlon is not None:
                lat, lon = zone.center_latlon
            else:
                assert zone.center is not None
                lat, lon = _latlon(mission, *zone.center)
            command = CIRCLE_INCLUSION if zone.inclusion else CIRCLE_EXCLUSION
            items.append(FenceItem(command, *_e7(lat, lon), float(zone.radius)))
        elif isinstance(zone, PolygonZone):
            if zone.vertices_latlon is not None:
                corners = [tuple(p) for p in zone.vertices_latlon]
            else:
                assert zone.vertices is not None
                corners = [_latlon(mission, x, y) for x, y in zone.vertices]
            command = POLYGON_INCLUSION if zone.inclusion else POLYGON_EXCLUSION
            n = float(len(corners))
            items += [FenceItem(command, *_e7(lat, lon), n) for lat, lon in corners]
    return items, left_out


def same(sent: list[FenceItem], read: list[FenceItem]) -> bool:
    """The items read back are those sent (positions to the degE7, radii to the cm)."""
    return len(sent) == len(read) and all(
        (a.command, a.lat_e7, a.lon_e7) == (b.command, b.lat_e7, b.lon_e7)
        and abs(a.param1 - b.param1) < 0.01
        for a, b in zip(sent, read, strict=True)
    )


# The fence list's half of the mission protocol, as messages to vehicle ``vid``.
def count(vid: int, n: int) -> Any:
    return mavlink2.MAVLink_mission_count_message(
        vid, AUTOPILOT_COMPONENT_ID, n, MISSION_TYPE_FENCE
    )


def item(vid: int, seq: int, it: FenceItem) -> Any:
    return mavlink2.MAVLink_mission_item_int_message(
        vid, AUTOPILOT_COMPONENT_ID, seq, FRAME_GLOBAL, it.command, 0, 1, it.param1, 0.0, 0.0,
        0.0, it.lat_e7, it.lon_e7, 0.0, MISSION_TYPE_FENCE,
    )  # fmt: skip


def request_list(vid: int) -> Any:
    return mavlink2.MAVLink_mission_request_list_message(
        vid, AUTOPILOT_COMPONENT_ID, MISSION_TYPE_FENCE
    )


def request(vid: int, seq: int) -> Any:
    return mavlink2.MAVLink_mission_request_int_message(
        vid, AUTOPILOT_COMPONENT_ID, seq, MISSION_TYPE_FENCE
    )


def ack(vid: int) -> Any:
    return mavlink2.MAVLink_mission_ack_message(vid, AUTOPILOT_COMPONENT_ID, 0, MISSION_TYPE_FENCE)


def item_of(msg: Any) -> FenceItem:
    """A MISSION_ITEM_INT of the fence list as a FenceItem."""
    return FenceItem(int(msg.command), int(msg.x), int(msg.y), float(msg.param1))


def result_name(result: int) -> str:
    """MAV_MISSION_RESULT's name (``MAV_MISSION_UNSUPPORTED``)."""
    entry = mavlink2.enums["MAV_MISSION_RESULT"].get(result)
    return entry.name if entry is not None else str(result)

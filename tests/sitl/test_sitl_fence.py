"""The SITL's fence, sans I/O: fence items as areas, breaches, the fence list's protocol,
and the geofence bits of SYS_STATUS."""

from __future__ import annotations

import pytest

from gcs_ppf.mavlink import enums
from sitl import fence
from sitl import messages as mb
from sitl import mission_protocol as mp

GCS = (255, 190)
LAT, LON = 47.3977420, 8.5455940


def item(command: int, lat: float, lon: float, param1: float = 0.0) -> mp.MissionItem:
    return mp.MissionItem(0, command, 0, 1, param1, 0, 0, 0, round(lat * 1e7), round(lon * 1e7), 0)


def square(command: int, half_deg: float = 0.01) -> list[mp.MissionItem]:
    """A square round (LAT, LON), 2·``half_deg`` a side."""
    d = half_deg
    corners = [(LAT - d, LON - d), (LAT - d, LON + d), (LAT + d, LON + d), (LAT + d, LON - d)]
    return [item(command, a, b, 4) for a, b in corners]


def test_polygons_and_circles_breached_as_arduplane_keeps_them() -> None:
    keep_in = square(fence.POLYGON_INCLUSION)
    no_fly = item(fence.CIRCLE_EXCLUSION, LAT, LON + 0.005, 100.0)  # 376 m east
    areas = fence.areas([*keep_in, no_fly, item(fence.RETURN_POINT, LAT, LON)])
    assert areas is not None
    assert [a.inclusion for a in areas] == [True, False]
    assert fence.breached(areas, LAT, LON) == []  # inside the square, outside the circle
    assert fence.breached(areas, LAT, LON + 0.005) == [areas[1]]  # in the no-fly circle
    assert fence.breached(areas, LAT + 0.02, LON) == [areas[0]]  # out of the square


def test_a_polygon_whose_vertices_do_not_add_up_is_refused_whole() -> None:
    assert fence.areas(square(fence.POLYGON_EXCLUSION)[:3]) is None
    five = [item(fence.POLYGON_EXCLUSION, LAT + k * 1e-3, LON, 5) for k in range(4)]
    assert fence.areas(five) is None


@pytest.mark.parametrize(
    ("bad", "result"),
    [
        (item(16, LAT, LON), enums.MAV_MISSION_UNSUPPORTED),
        (item(fence.POLYGON_INCLUSION, LAT, LON, 2), enums.MAV_MISSION_INVALID_PARAM1),
        (item(fence.CIRCLE_EXCLUSION, LAT, LON, 0), enums.MAV_MISSION_INVALID_PARAM1),
        (mp.MissionItem(0, fence.CIRCLE_EXCLUSION, 0, 1, 50, 0, 0, 0, 10**9, 0, 0),
         enums.MAV_MISSION_INVALID_PARAM5_X),
    ],
)  # fmt: skip
def test_fence_items_validated(bad: mp.MissionItem, result: int) -> None:
    assert fence.validate_item(bad) == result


def test_the_fence_list_round_trips_without_a_home_item() -> None:
    server = mp.MissionServer(mp.MISSION_TYPE_FENCE, fence.validate_item)
    items = [*square(fence.POLYGON_EXCLUSION), item(fence.CIRCLE_INCLUSION, LAT, LON, 5000)]
    res = server.on_count(GCS, len(items), mp.MISSION_TYPE_FENCE, 0.0)
    for seq, it in enumerate(items):
        assert res.replies[-1].get_type() == "MISSION_REQUEST_INT"
        assert res.replies[-1].mission_type == mp.MISSION_TYPE_FENCE
        res = server.on_item(GCS, seq, it, mp.MISSION_TYPE_FENCE, 0.1)
    assert res.replies[-1].type == enums.MAV_MISSION_ACCEPTED
    assert res.mission_changed
    assert server.on_request_list(GCS, mp.MISSION_TYPE_FENCE).replies[0].count == 5
    first = server.on_request(GCS, 0, mp.MISSION_TYPE_FENCE, items[0], as_int=True).replies[0]
    assert (first.command, first.x, first.param1) == (items[0].command, items[0].x, 4.0)
    # the mission list is not the fence's: a mission upload is refused by this server
    assert server.on_count(GCS, 2, 0, 0.0).replies[0].type == enums.MAV_MISSION_UNSUPPORTED
    assert server.on_clear_all(GCS, mp.MISSION_TYPE_FENCE).mission_changed
    assert server.items == []


def test_sys_status_geofence_healthy_unless_breached() -> None:
    none = mb.sys_status()
    assert not none.onboard_control_sensors_present & mb.GEOFENCE
    assert none.onboard_control_sensors_health & mb.GEOFENCE  # MAVProxy: no "fence breach"
    on = mb.sys_status(fence_present=True, fence_enabled=True, fence_breached=True)
    assert on.onboard_control_sensors_present & on.onboard_control_sensors_enabled & mb.GEOFENCE
    assert not on.onboard_control_sensors_health & mb.GEOFENCE

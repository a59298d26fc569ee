"""Zones from operators' files: GeoJSON and QGroundControl .plan (gcs_ppf.zone_import), a
.plan's waypoints as the leader's route (gcs_ppf.plan_route), and ``gcs-ppf zones import``."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gcs_ppf.cli import main
from gcs_ppf.geodesy import enu_to_geodetic
from gcs_ppf.mission import CylinderZone, Mission, PolygonZone, load_mission_file
from gcs_ppf.plan_route import RouteImportError, route_from_plan
from gcs_ppf.planning.zones import zones_from_mission
from gcs_ppf.zone_import import ZoneImportError, import_zones
from tests.conftest import EXAMPLES

TABLE3 = load_mission_file(EXAMPLES / "paper_table3.json")


def lonlat(x: float, y: float) -> list[float]:
    """GeoJSON's (lon, lat) of an ICS point of Table 3's origin."""
    lat, lon, _ = enu_to_geodetic(x, y, 0.0, TABLE3.origin)
    return [lon, lat]


def square(x: float, y: float, half: float) -> list[list[float]]:
    corners = [
        (x - half, y - half),
        (x + half, y - half),
        (x + half, y + half),
        (x - half, y + half),
    ]
    ring = [lonlat(*c) for c in corners]
    return [*ring, ring[0]]


BOW_TIE = [lonlat(0, 0), lonlat(100, 100), lonlat(100, 0), lonlat(0, 100), lonlat(0, 0)]
"""A ring that crosses itself."""


def feature(geometry: dict[str, Any], **properties: Any) -> dict[str, Any]:
    return {"type": "Feature", "geometry": geometry, "properties": properties}


def collection(*features: dict[str, Any]) -> str:
    return json.dumps({"type": "FeatureCollection", "features": list(features)})


def test_geojson_polygons_multipolygons_and_points_become_zones_where_they_lie() -> None:
    """A square of 400 m at (3000, 3000) with a band, a MultiPolygon of two, a Point with a
    radius as an inclusion cylinder: each zone's footprint lands where it was drawn."""
    text = collection(
        feature({"type": "Polygon", "coordinates": [square(3000, 3000, 200)]},
                name="block", floor=-100, ceiling=450),
        feature({"type": "MultiPolygon",
                 "coordinates": [[square(5000, 2000, 100)], [square(5000, 2600, 100)]]}),
        feature({"type": "Point", "coordinates": lonlat(4000, 4000)}, radius=2500, inclusion=True),
    )  # fmt: skip
    zones = import_zones(text, "zones.geojson")
    assert [type(z) for z in zones] == [PolygonZone, PolygonZone, PolygonZone, CylinderZone]
    block = zones[0]
    assert (block.name, block.floor, block.ceiling, block.inclusion) == (
        "block",
        -100.0,
        450.0,
        False,
    )
    cylinder = zones[3]
    assert isinstance(cylinder, CylinderZone)
    assert cylinder.inclusion is True
    assert cylinder.radius == 2500.0
    arrays = zones_from_mission(TABLE3.model_copy(update={"zones": zones}))
    first = arrays.verts[arrays.vstart[0] : arrays.vstart[1]]
    assert np.allclose(first, [[2800, 2800], [3200, 2800], [3200, 3200], [2800, 3200]], atol=0.01)
    assert np.allclose(arrays.geom[3, :2], [4000, 4000], atol=0.01)
    assert arrays.geom[1, 1] == pytest.approx(2000, abs=0.01)
    assert arrays.geom[2, 1] == pytest.approx(2600, abs=0.01)


def test_a_qgroundcontrol_plan_s_fence_polygons_and_circles_are_zones() -> None:
    plan = {
        "fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
        "mission": {"items": [], "version": 2}, "rallyPoints": {"points": [], "version": 2},
        "geoFence": {"version": 2,
                     "polygons": [{"inclusion": False, "version": 1,
                                   "polygon": [[47.41, 8.55], [47.41, 8.56], [47.415, 8.56]]}],
                     "circles": [{"circle": {"center": [47.4, 8.55], "radius": 300},
                                  "inclusion": True, "version": 1}]},
    }  # fmt: skip
    poly, circle = import_zones(json.dumps(plan), "fence.plan")
    assert isinstance(poly, PolygonZone)
    assert poly.vertices_latlon == [(47.41, 8.55), (47.41, 8.56), (47.415, 8.56)]
    assert poly.inclusion is False
    assert poly.floor is None  # QGroundControl's fences have no height band
    assert poly.ceiling is None
    assert isinstance(circle, CylinderZone)
    assert (circle.center_latlon, circle.radius, circle.inclusion) == ((47.4, 8.55), 300.0, True)


@pytest.mark.parametrize(
    ("features", "named"),
    [
        ([feature({"type": "Point", "coordinates": [8.5, 47.4]})],
         "features[0].properties.radius: a Point needs a radius"),
        ([feature({"type": "Polygon", "coordinates": [square(0, 0, 50)]}),
          feature({"type": "Polygon", "coordinates": [square(0, 0, 50)]}, ceiling="high")],
         "features[1].properties.ceiling: a number of metres, got 'high'"),
        ([feature({"type": "Polygon", "coordinates": [square(0, 0, 50), square(0, 0, 10)]})],
         "features[0].geometry.coordinates: holes are not supported"),
        ([feature({"type": "LineString", "coordinates": [[8.5, 47.4], [8.6, 47.4]]})],
         "features[0].geometry: LineString is not a zone"),
        ([feature({"type": "Polygon", "coordinates": [BOW_TIE]})],
         "features[0]: vertices_latlon: not a simple polygon"),
        ([feature({"type": "Point", "coordinates": [8.5, 47.4]}, radius=-5)],
         "features[0]: radius: Input should be greater than 0"),
    ],
)  # fmt: skip
def test_a_file_that_cannot_be_read_names_the_feature_and_the_field(
    features: list[dict[str, Any]], named: str
) -> None:
    with pytest.raises(ZoneImportError) as err:
        import_zones(collection(*features), "zones.geojson")
    assert str(err.value).startswith(f"zones.geojson: {named}")


def test_not_json_and_no_zones_are_refused_by_name() -> None:
    with pytest.raises(ZoneImportError, match=r"x\.geojson is not JSON \(line 1, column 2"):
        import_zones("{nope", "x.geojson")
    with pytest.raises(ZoneImportError, match=r"x\.geojson: no zones in it"):
        import_zones(collection(), "x.geojson")
    plan = {"fileType": "Plan", "geoFence": {"circles": [{"circle": {"center": [47.4, 8.5]}}]}}
    with pytest.raises(ZoneImportError, match=r"geoFence\.circles\[0\]: radius"):
        import_zones(json.dumps(plan), "f.plan")


def test_the_command_adds_the_zones_to_a_mission_or_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    good = tmp_path / "zones.geojson"
    block = {"type": "Polygon", "coordinates": [square(3000, 3000, 200)]}
    good.write_text(collection(feature(block, name="block", ceiling=450)))
    assert main(["zones", "import", str(good)]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed[0]["name"] == "block"
    assert printed[0]["kind"] == "polygon"
    out = tmp_path / "table3-block.json"
    args = ["zones", "import", str(good), "--mission", str(EXAMPLES / "paper_table3.json")]
    assert main([*args, "--out", str(out)]) == 0
    mission = Mission.model_validate_json(out.read_text())
    assert [z.name for z in mission.zones] == ["block"]
    assert len(mission.obstacles) == len(TABLE3.obstacles)
    bad = tmp_path / "bad.geojson"
    bad.write_text(collection(feature({"type": "Point", "coordinates": [8.5, 47.4]})))
    never = tmp_path / "never.json"
    assert main(["zones", "import", str(bad), "--mission", args[4], "--out", str(never)]) == 2
    assert "features[0].properties.radius" in capsys.readouterr().err
    assert not never.exists()
    # a zone over a vehicle's start: the whole mission refused, nothing written
    start = TABLE3.vehicles[0].position
    over = tmp_path / "over.geojson"
    over.write_text(collection(feature({"type": "Point", "coordinates": lonlat(start[0], start[1])},
                                       radius=300)))  # fmt: skip
    assert main(["zones", "import", str(over), "--mission", args[4], "--out", str(never)]) == 2
    assert "with what" in capsys.readouterr().err
    assert not never.exists()


def item(
    command: int,
    x: float = 0.0,
    y: float = 0.0,
    z: float = 0.0,
    radius: float = 0.0,
    frame: int = 3,
) -> dict[str, Any]:
    """A .plan SimpleItem at ICS (x, y, z) of Table 3's origin, its altitude above a home at
    the origin's altitude (frame 3) or above mean sea level (frame 0)."""
    lat, lon, alt = enu_to_geodetic(x, y, z, TABLE3.origin)
    alt = alt - TABLE3.origin.alt if frame == 3 else alt
    params = [0, radius, 0, None, lat, lon, alt]
    return {"type": "SimpleItem", "command": command, "frame": frame, "params": params}


def plan(*items: dict[str, Any]) -> dict[str, Any]:
    home = [TABLE3.origin.lat, TABLE3.origin.lon, TABLE3.origin.alt]
    mission = {"items": list(items), "plannedHomePosition": home, "version": 2}
    return {"fileType": "Plan", "version": 1, "mission": mission}


def test_a_plans_waypoints_are_the_route_and_the_last_the_target() -> None:
    """Takeoff, three waypoints (one above mean sea level, one with its own radius) and a
    speed change: the route is the first two, the target the third, in the ICS."""
    msl = item(16, 6000, 2000, 400, radius=60, frame=0)
    doc = plan(item(22, z=50), item(16, 3000, 2000, 300), item(178), msl, item(16, 6000, 7000, 300))
    flown = route_from_plan(doc, TABLE3.origin)
    assert [w.position for w in flown.route] == [
        pytest.approx((3000, 2000, 300), abs=0.01),
        pytest.approx((6000, 2000, 400), abs=0.01),
    ]
    assert [w.acceptance_radius for w in flown.route] == [100.0, 60.0]
    assert flown.target == pytest.approx((6000, 7000, 300), abs=0.01)
    assert flown.left_out == [(0, 22), (2, 178)]


def test_a_plans_loiter_items_are_waypoints_with_a_loiter() -> None:
    """LOITER_TURNS (18) and LOITER_TIME (19): param1 turns or seconds, param3 the radius,
    negative anticlockwise, 0 ArduPlane's WP_LOITER_RAD (60 m); an unlimited loiter (17) is
    left out."""
    turns = {
        **item(18, 3000, 2000, 300),
        "params": [2, 0, -800, None, *item(18, 3000, 2000, 300)["params"][4:]],
    }
    timed = {
        **item(19, 4000, 3000, 300),
        "params": [45, 0, 0, None, *item(19, 4000, 3000, 300)["params"][4:]],
    }
    flown = route_from_plan(plan(turns, item(17), timed, item(16, 6000, 7000, 300)), TABLE3.origin)
    first, second = (w.loiter for w in flown.route)
    assert first is not None
    assert (first.turns, first.time_s, first.radius_m, first.clockwise) == (2, None, 800, False)
    assert second is not None
    assert (second.turns, second.time_s, second.radius_m, second.clockwise) == (None, 45, 60, True)
    assert flown.left_out == [(1, 17)]


@pytest.mark.parametrize(
    ("items", "named"),
    [
        ([item(22)], "mission.items: no waypoint"),
        ([item(16, 10, 10, 300, frame=10)], "mission.items[0].frame: 10"),
        ([item(16), {**item(18), "params": [1, 0, 0, None, *item(18)["params"][4:]]}],
         "mission.items: the last place is a loiter"),
        ([{**item(18), "params": [0, 0, 0, None, *item(18)["params"][4:]]}, item(16)],
         "mission.items[0].params[0]: turns must be > 0"),
        ([item(16), {"type": "ComplexItem", "complexItemType": "survey"}],
         "mission.items[1].type: 'ComplexItem'"),
        ([{**item(16), "params": [0, 0, 0, None, "north", 8.5, 100]}],
         "mission.items[0].params[4]: a number expected"),
    ],
)  # fmt: skip
def test_a_route_that_cannot_be_read_names_the_item(
    items: list[dict[str, Any]], named: str
) -> None:
    with pytest.raises(RouteImportError, match=re.escape(named)):
        route_from_plan(plan(*items), TABLE3.origin)


def test_the_command_takes_a_plans_route_into_the_mission(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    file = tmp_path / "route.plan"
    doc = plan(item(22, z=50), item(16, 4000, 1000, 300), item(16, 6000, 7000, 300))
    file.write_text(json.dumps(doc))
    out = tmp_path / "table3-route.json"
    args = ["zones", "import", str(file), "--mission", str(EXAMPLES / "paper_table3.json")]
    assert main([*args, "--out", str(out), "--route"]) == 0
    assert "a route of 2 waypoints (left out: items[0] (MAV_CMD 22))" in capsys.readouterr().err
    mission = Mission.model_validate_json(out.read_text())
    assert len(mission.route) == 1
    assert mission.route[0].position == pytest.approx((4000, 1000, 300), abs=0.01)
    assert mission.target == pytest.approx((6000, 7000, 300), abs=0.01)
    assert mission.zones == []
    assert main(["zones", "import", str(file), "--route"]) == 2  # --route needs --mission

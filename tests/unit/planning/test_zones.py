"""The compiled zone geometry (gcs_ppf.planning.zones) against shapely's
(gcs_ppf.mission.zone_clearance), and the zone kinds' validation."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st
from pydantic import ValidationError

from gcs_ppf.mission import (
    Mission,
    MissionError,
    PolygonZone,
    load_mission,
    zone_clearance,
    zone_footprint,
)
from gcs_ppf.planning.planner import advance
from gcs_ppf.planning.scene import scene_from_mission
from gcs_ppf.planning.zones import pocket_hull, zone_clearances, zone_distance, zones_of

U_SHAPE = [(0, 0), (600, 0), (600, 600), (400, 600), (400, 200), (200, 200), (200, 600), (0, 600)]


def mission(zones: list[dict[str, object]]) -> Mission:
    return Mission.model_validate(
        {
            "target": [5000.0, 5000.0, 300.0],
            "vehicles": [{"id": 1, "role": "leader", "position": [-3000.0, -3000.0, 300.0]}],
            "zones": zones,
        }
    )


ZONES: list[dict[str, object]] = [
    {"kind": "polygon", "vertices": U_SHAPE, "floor": 0.0, "ceiling": 400.0},
    {"kind": "cylinder", "center": [1500.0, 300.0], "radius": 250.0, "ceiling": 800.0},
    {"kind": "polygon", "vertices": [[-4000, -4000], [6000, -4000], [6000, 6000], [-4000, 6000]],
     "floor": 50.0, "ceiling": 2000.0, "inclusion": True},
]  # fmt: skip


@given(
    st.floats(-4500, 6500),
    st.floats(-4500, 6500),
    st.floats(-200, 2500),
)
def test_the_compiled_distance_is_shapelys(x: float, y: float, z: float) -> None:
    m = mission(ZONES)
    arrays = zones_of(m.zones, m.origin)
    got = zone_clearances(np.array([[x, y, z]]), arrays)[0]
    for k, zone in enumerate(m.zones):
        want = zone_clearance(zone, zone_footprint(zone, m.origin), (x, y, z))
        assert got[k] == pytest.approx(want, abs=1e-6)


@given(st.floats(-300, 900), st.floats(-300, 900), st.floats(-100, 600))
@example(0.0, -5e-324, -5e-324)  # subnormal off a wall and the floor at once: drawn in CI
@example(-5e-324, -5e-324, 200.0)  # subnormal off a corner, both ways: drawn here
def test_the_nearest_surface_point_is_the_distance_back_along_the_normal(
    x: float, y: float, z: float
) -> None:
    m = mission(ZONES[:1])
    kind, geom, vstart, verts = zones_of(m.zones, m.origin).arrays
    d, nx, ny, nz = zone_distance(0, x, y, z, kind, geom, vstart, verts)
    assert math.isclose(nx * nx + ny * ny + nz * nz, 1.0, rel_tol=1e-9)
    # The nearest surface point, d back along the normal, is on the surface.
    back = zone_distance(0, x - d * nx, y - d * ny, z - d * nz, kind, geom, vstart, verts)[0]
    assert back == pytest.approx(0.0, abs=1e-6)


def test_inside_and_outside_of_a_u() -> None:
    m = mission(ZONES[:1])
    kind, geom, vstart, verts = zones_of(m.zones, m.origin).arrays
    assert zone_distance(0, 300.0, 500.0, 200.0, kind, geom, vstart, verts)[0] == pytest.approx(
        100.0
    )  # in the pocket, 100 m from either arm
    assert zone_distance(0, 100.0, 300.0, 200.0, kind, geom, vstart, verts)[0] == pytest.approx(
        -100.0
    )  # inside an arm
    d, _, _, nz = zone_distance(0, 300.0, 100.0, 500.0, kind, geom, vstart, verts)
    assert d == pytest.approx(100.0)  # over its base
    assert nz == pytest.approx(1.0)
    d = zone_distance(0, 300.0, 300.0, 500.0, kind, geom, vstart, verts)[0]
    assert d == pytest.approx(math.hypot(100.0, 100.0))  # over the pocket: the arms' edges


def test_only_an_exclusion_polygon_with_pockets_has_a_hull() -> None:
    m = mission(ZONES)
    z = zones_of(m.zones, m.origin)
    hull_vstart, hull_verts = z.planning_arrays[4:]
    assert hull_vstart.tolist() == [0, 4, 4, 4]  # the U's; the cylinder, the inclusion none
    assert sorted(map(tuple, hull_verts.tolist())) == [(0, 0), (0, 600), (600, 0), (600, 600)]
    assert pocket_hull([(0.0, 0.0), (600.0, 0.0), (600.0, 600.0), (0.0, 600.0)]) == []
    kind, geom, vstart, verts = z.arrays  # the geometry every check uses is the zone's own
    assert zone_distance(0, 300.0, 500.0, 200.0, kind, geom, vstart, verts)[0] == 100.0


def test_a_formation_flying_at_a_u_goes_round_it_not_into_its_pocket() -> None:
    """``examples/scene_u_pocket.json``: a U 1.4 km wide opening towards the formation.
    Repelled by the nearest wall only, the plan flew into the pocket, from wall to wall,
    and through its corner 114 m deep; repelled by the hull from outside, it keeps every
    zone's safe distance."""
    root = Path(__file__).resolve().parents[3]
    m = load_mission((root / "examples" / "scene_u_pocket.json").read_text())
    scene = scene_from_mission(m)
    result = advance(scene, m.planner.dt, 30_000, record_every=10)
    assert result.arrived
    pos = result.trajectory.pos.reshape(-1, 3)
    clear = zone_clearances(pos, scene.zones).min()
    assert clear >= m.limits.safe_distance_obstacle, clear


@pytest.mark.parametrize(
    ("zone", "field"),
    [
        ({"kind": "polygon", "vertices": [[0, 0], [10, 10], [10, 0], [0, 10]]}, "vertices"),
        ({"kind": "polygon", "vertices": [[0, 0], [10, 0], [20, 0]]}, "vertices"),
        ({"kind": "polygon", "vertices": [[0, 0], [10, 0], [10, 0], [0, 10]]}, "vertices"),
        ({"kind": "polygon", "vertices": [[0, 0], [1, 0]]}, "vertices"),
        ({"kind": "polygon", "vertices": U_SHAPE, "floor": 10.0, "ceiling": 5.0}, "ceiling"),
        ({"kind": "cylinder", "center": [0, 0], "radius": -1.0}, "radius"),
        ({"kind": "cylinder", "radius": 10.0}, "center"),
        ({"kind": "cylinder", "center_latlon": [95.0, 0.0], "radius": 10.0}, "center_latlon"),
        ({"kind": "cone", "center": [0, 0], "radius": 10.0}, "zones[0]"),
    ],
)
def test_bad_zones_name_their_field(zone: dict[str, object], field: str) -> None:
    doc = {"target": [0, 0, 0], "vehicles": [{"id": 1, "role": "leader", "position": [99, 0, 0]}]}
    with pytest.raises(MissionError) as info:
        load_mission(json.dumps({**doc, "zones": [zone]}))
    assert info.value.field.startswith("zones[0]")
    assert info.value.field.endswith(field) or field in info.value.message


def test_a_start_inside_a_zone_is_refused() -> None:
    with pytest.raises(ValidationError, match=r"vehicles\[0\].position: inside zones\[0\]"):
        mission([{"kind": "cylinder", "center": [-3000.0, -3000.0], "radius": 100.0}])
    with pytest.raises(ValidationError, match=r"target: outside zones\[0\]"):
        mission([{"kind": "cylinder", "center": [-3000.0, -3000.0], "radius": 1000.0,
                  "inclusion": True}])  # fmt: skip


def test_latlon_corners_are_converted_about_the_origin() -> None:
    m = mission([])
    o = m.origin
    zone = PolygonZone(
        kind="polygon",
        vertices_latlon=[(o.lat, o.lon), (o.lat + 0.01, o.lon), (o.lat, o.lon + 0.01)],
    )
    pts = zone_footprint(zone, o)
    assert pts[0] == pytest.approx((0.0, 0.0), abs=1e-6)
    assert pts[1][1] == pytest.approx(1112.0, rel=0.01)  # 0.01° of latitude north
    assert pts[2][0] == pytest.approx(751.0, rel=0.01)  # 0.01° of longitude at 47.4° N

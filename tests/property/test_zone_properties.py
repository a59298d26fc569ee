"""Properties of PPF plans among zones: the feasible scenes of scenes.py with each sphere
replaced by a vertical cylinder or an extruded polygon (star-shaped, so convex or not)
inside it, with a height band; feasible as for spheres, measured from the zones' surfaces
(every start and the target outside each zone's influence at v_max, and the zones'
influence regions apart, so a vehicle answers to one zone at a time)."""

from __future__ import annotations

import math

from hypothesis import assume, given
from hypothesis import strategies as st

from gcs_ppf.mission import Mission, zone_clearance, zone_footprint
from gcs_ppf.offline.plan import plan_mission
from tests.checks import assert_within_kinematic_limits
from tests.property.scenes import feasible_missions

INFLUENCE_STEPS_M = 3.0 * 300.0 * 0.01  # a few steps of travel at v_max (the kernel's)


def _influence(mission: Mission) -> float:
    lim = mission.limits
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    return lim.v_max / omega + lim.safe_distance_obstacle + INFLUENCE_STEPS_M


@st.composite
def zone_missions(draw: st.DrawFn, max_wingmen: int = 3) -> Mission:
    """A feasible scene of spheres, each replaced by a zone inside it."""
    base = draw(feasible_missions(max_wingmen=max_wingmen, max_obstacles=3))
    assume(base.obstacles)
    zones: list[dict[str, object]] = []
    for o in base.obstacles:
        half = o.radius / math.sqrt(2.0)  # the zone fits inside the sphere
        cx, cy, cz = o.center
        band = {"floor": cz - half, "ceiling": cz + half}
        if draw(st.booleans()):
            zones.append({"kind": "cylinder", "center": [cx, cy], "radius": half, **band})
            continue
        n = draw(st.integers(3, 8))
        gaps = [draw(st.floats(0.5, 1.0)) for _ in range(n)]
        total, angle, vertices = sum(gaps), 0.0, []
        for g in gaps:
            r = half * draw(st.floats(0.6, 1.0))
            vertices.append([cx + r * math.cos(angle), cy + r * math.sin(angle)])
            angle += 2.0 * math.pi * g / total
        zones.append({"kind": "polygon", "vertices": vertices, **band})
    doc = base.model_dump()
    doc["obstacles"], doc["zones"] = [], zones
    mission = Mission.model_validate(doc)
    reach = _influence(mission)
    points = [v.position for v in mission.vehicles] + [mission.target]
    for zone in mission.zones:
        footprint = zone_footprint(zone, mission.origin)
        assume(all(zone_clearance(zone, footprint, p) > reach for p in points))
    for a, za in enumerate(doc["zones"]):
        for zb in doc["zones"][:a]:
            ca, cb = _centre(za), _centre(zb)
            apart = math.dist(ca[:2], cb[:2]) - _radius(za) - _radius(zb)
            assume(apart > 2.0 * reach)
    return mission


def _centre(zone: dict[str, object]) -> tuple[float, float]:
    if zone["kind"] == "cylinder":
        c = zone["center"]
        assert isinstance(c, list)
        return (float(c[0]), float(c[1]))
    v = zone["vertices"]
    assert isinstance(v, list)
    return (sum(p[0] for p in v) / len(v), sum(p[1] for p in v) / len(v))


def _radius(zone: dict[str, object]) -> float:
    if zone["kind"] == "cylinder":
        r = zone["radius"]
        assert isinstance(r, float)
        return r
    c, v = _centre(zone), zone["vertices"]
    assert isinstance(v, list)
    return max(math.dist(c, p) for p in v)


@given(zone_missions())
def test_among_zones_no_step_exceeds_a_kinematic_limit(mission: Mission) -> None:
    assert_within_kinematic_limits(plan_mission(mission).metrics, mission.limits)


@given(zone_missions())
def test_every_zone_surface_is_kept_at_the_safe_distance(mission: Mission) -> None:
    m = plan_mission(mission).metrics
    assert m["min_obstacle_clearance_m"] >= mission.limits.safe_distance_obstacle
    if m["min_separation_m"] is not None:
        assert m["min_separation_m"] >= mission.limits.safe_distance_uav
    assert m["collisions"] == 0

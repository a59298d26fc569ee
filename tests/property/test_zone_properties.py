"""Properties of PPF plans among zones: the feasible scenes with each sphere replaced by a
vertical cylinder or an extruded polygon (star-shaped, so convex or not) inside it, with a
height band (the sweep's ``zones`` family); feasible as for spheres, measured from the
zones' surfaces (every start and the target outside each zone's influence at v_max, and
the zones' influence regions apart, so a vehicle answers to one zone at a time)."""

from __future__ import annotations

from hypothesis import assume, given
from hypothesis import strategies as st

from gcs_ppf.mission import Mission
from gcs_ppf.offline.plan import plan_mission
from gcs_ppf.offline.sweep.families import ZONES
from gcs_ppf.offline.sweep.spec import SceneSpec
from tests.checks import assert_within_kinematic_limits
from tests.property.scenes import missions


@st.composite
def zone_missions(draw: st.DrawFn, max_wingmen: int = 3) -> Mission:
    """A scene of the sweep's ``zones`` family (up to three zones)."""
    spec = ZONES.model_copy(
        update={
            "fleet": ZONES.fleet.model_copy(update={"wingmen": (0, max_wingmen)}),
            "obstacles": ZONES.obstacles.model_copy(update={"count": (1, 3)}),
        }
    )
    mission = draw(missions(SceneSpec.model_validate(spec.model_dump())))
    assume(mission.zones)
    return mission


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

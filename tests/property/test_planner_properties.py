"""Properties of PPF plans over random feasible scenes (see scenes.py for 'feasible')."""

from __future__ import annotations

from hypothesis import given

from gcs_ppf.mission import Mission
from gcs_ppf.offline.plan import plan_mission
from tests.checks import assert_within_kinematic_limits
from tests.property.scenes import feasible_missions


@given(feasible_missions())
def test_no_step_exceeds_a_kinematic_limit(mission: Mission) -> None:
    assert_within_kinematic_limits(plan_mission(mission).metrics, mission.limits)


@given(feasible_missions())
def test_safety_distances_hold(mission: Mission) -> None:
    m = plan_mission(mission).metrics
    if m["min_obstacle_clearance_m"] is not None:
        assert m["min_obstacle_clearance_m"] >= mission.limits.safe_distance_obstacle
    if m["min_separation_m"] is not None:
        assert m["min_separation_m"] >= mission.limits.safe_distance_uav
    assert m["collisions"] == 0


@given(feasible_missions(max_wingmen=0))
def test_a_lone_leader_reaches_its_target(mission: Mission) -> None:
    assert plan_mission(mission).metrics["reached"]


@given(feasible_missions(ground=True))
def test_the_ground_is_kept_at_the_safe_distance(mission: Mission) -> None:
    m = plan_mission(mission).metrics
    assert m["min_ground_clearance_m"] >= mission.limits.safe_distance_obstacle
    if m["min_obstacle_clearance_m"] is not None:
        assert m["min_obstacle_clearance_m"] >= mission.limits.safe_distance_obstacle
    if m["min_separation_m"] is not None:
        assert m["min_separation_m"] >= mission.limits.safe_distance_uav
    assert m["collisions"] == 0

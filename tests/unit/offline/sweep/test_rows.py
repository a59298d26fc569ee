"""A scene's row: its figures are the plan's metrics, its outcome the first that applies."""

from __future__ import annotations

import math
from typing import Any

import pytest

from gcs_ppf.offline.plan import plan_mission
from gcs_ppf.offline.sweep.families import FEASIBLE
from gcs_ppf.offline.sweep.rows import Outcome, outcome, plan_scene, straight_line_time_s
from gcs_ppf.offline.sweep.scenes import draw_scene
from gcs_ppf.offline.sweep.spec import Box, FleetSpec, SceneSpec

SAFE: dict[str, Any] = {
    "reached": True,
    "min_obstacle_clearance_m": 30.0,
    "min_ground_clearance_m": None,
    "min_separation_m": 60.0,
}


@pytest.mark.parametrize(
    ("changes", "expected"),
    [
        ({}, Outcome.REACHED),
        ({"reached": False}, Outcome.NOT_REACHED),
        ({"min_separation_m": 49.0, "reached": False}, Outcome.SEPARATION),
        ({"min_ground_clearance_m": 10.0, "min_separation_m": 49.0}, Outcome.GROUND),
        ({"min_obstacle_clearance_m": 24.0, "min_ground_clearance_m": 10.0}, Outcome.CLEARANCE),
        ({"min_obstacle_clearance_m": None, "min_separation_m": None}, Outcome.REACHED),
    ],
)
def test_the_outcome_is_the_first_that_applies(changes: dict[str, Any], expected: Outcome) -> None:
    assert outcome({**SAFE, **changes}, FEASIBLE_MISSION) == expected


FEASIBLE_MISSION = draw_scene(FEASIBLE, 0, 1)


def test_the_straight_line_is_flown_at_v_max_to_the_accuracy_sphere() -> None:
    m = FEASIBLE_MISSION
    gap = math.dist(m.leader.position, m.target) - m.limits.target_accuracy
    assert straight_line_time_s(m) == pytest.approx(gap / m.limits.v_max)


def test_a_row_holds_the_plans_metrics() -> None:
    row = plan_scene(FEASIBLE, 0, 1)
    m = plan_mission(FEASIBLE_MISSION).metrics
    assert (row.family, row.index, row.seed) == ("feasible", 1, 0)
    assert row.vehicles == len(FEASIBLE_MISSION.vehicles)
    assert row.obstacles == len(FEASIBLE_MISSION.obstacles)
    assert row.reached == m["reached"]
    assert row.flight_time_s == m["flight_time_s"]
    assert row.min_separation_m == m["min_separation_m"]
    assert row.min_obstacle_clearance_m == m["min_obstacle_clearance_m"]
    assert row.collisions == m["collisions"]
    assert row.outcome == outcome(m, FEASIBLE_MISSION)
    assert row.planning_wall_time_s is not None
    assert row.planning_wall_time_s > 0.0


def test_a_scene_that_cannot_be_drawn_is_an_error_row() -> None:
    cramped = SceneSpec(
        name="cramped",
        fleet=FleetSpec(
            wingmen=(4, 4),
            start_box=Box(center_m=(-6000.0, 0.0, 0.0), half_size_m=(100.0, 100.0, 0.0)),
        ),
    )
    row = plan_scene(cramped, 0, 2)
    assert row.outcome == Outcome.ERROR
    assert "cramped: no valid scene" in row.error
    assert row.vehicles is None
    assert row.flight_time_s is None
    assert not row.reached

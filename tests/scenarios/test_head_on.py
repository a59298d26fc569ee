"""CONVENTIONS §2 erratum 4: head-on approaches at v_min and v_max keep the safe distance."""

from __future__ import annotations

import pytest

from gcs_ppf.mission import Mission
from gcs_ppf.offline.plan import plan_mission


def head_on(radius: float, speed: float, offset: float, obstacle_speed: float = 0.0) -> Mission:
    start = -(radius + 3000.0)
    return Mission.model_validate(
        {
            "limits": {"v_init": speed},
            "planner": {"max_time": 200.0},
            "target": [radius + 3000.0, 0.0, 0.0],
            "vehicles": [{"id": 1, "role": "leader", "position": [start, offset, 0.0], "yaw": 0.0}],
            "obstacles": [
                {"center": [0.0, 0.0, 0.0], "radius": radius, "velocity": [-obstacle_speed, 0, 0]}
            ],
        }
    )


@pytest.mark.parametrize("speed", [100.0, 300.0])
@pytest.mark.parametrize("radius", [50.0, 350.0, 850.0])
@pytest.mark.parametrize("offset", [0.0, 1.0, 30.0, 200.0])
def test_head_on_keeps_the_safe_distance(speed: float, radius: float, offset: float) -> None:
    mission = head_on(radius, speed, offset)
    run = plan_mission(mission)
    m = run.metrics
    assert m["min_obstacle_clearance_m"] >= mission.limits.safe_distance_obstacle
    assert m["reached"]


@pytest.mark.parametrize("obstacle_speed", [50.0, 150.0])
def test_head_on_against_a_moving_obstacle(obstacle_speed: float) -> None:
    mission = head_on(350.0, 300.0, 0.0, obstacle_speed)
    m = plan_mission(mission).metrics
    assert m["min_obstacle_clearance_m"] >= mission.limits.safe_distance_obstacle


def test_the_leader_avoids_nobody_but_a_wingman_avoids_the_leader() -> None:
    """Priorities: two vehicles head-on; only the wingman gives way, and they stay apart."""
    mission = Mission.model_validate(
        {
            "planner": {"max_time": 60.0},
            "limits": {"v_init": 300.0},
            "target": [6000.0, 0.0, 0.0],
            "vehicles": [
                {"id": 1, "role": "leader", "position": [0.0, 0.0, 0.0], "yaw": 0.0},
                {
                    "id": 2,
                    "role": "wingman",
                    "position": [4000.0, 0.0, 0.0],
                    "yaw": 3.14159,
                    "slot": [-2000.0, 0.0, 0.0],
                },
            ],
        }
    )
    run = plan_mission(mission)
    assert run.metrics["min_separation_m"] >= mission.limits.safe_distance_uav
    assert not run.trajectory.avoiding[:, 0].any()
    assert run.trajectory.avoiding[:, 1].any()

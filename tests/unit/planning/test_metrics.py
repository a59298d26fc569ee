"""Plan metrics computed from the trajectory alone (CONVENTIONS §4), here the ground."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from gcs_ppf.mission import Mission, load_mission_file
from gcs_ppf.offline.plan import flight_context, plan_mission
from gcs_ppf.planning.metrics import (
    FlightContext,
    compute_metrics,
    direction_vectors,
    formation_share,
    local_target_points,
)
from gcs_ppf.planning.planner import Trajectory
from gcs_ppf.planning.scene import scene_from_mission
from tests.conftest import EXAMPLES

LOW_FLIGHT = Mission.model_validate({
    "ground": 0.0,
    "planner": {"max_time": 30.0},
    "target": [5000.0, 0.0, 40.0],
    "vehicles": [{"id": 1, "role": "leader", "position": [0.0, 0.0, 400.0], "pitch": -0.5}],
})  # fmt: skip


def test_ground_clearance_is_the_lowest_height_and_a_dip_below_it_is_a_collision() -> None:
    plan = plan_mission(LOW_FLIGHT)
    tr = plan.trajectory
    lowest = float(tr.pos[:, 0, 2].min())
    assert plan.metrics["min_ground_clearance_m"] == pytest.approx(lowest)
    assert plan.metrics["collisions"] == 0
    sunk = replace(tr, pos=tr.pos - np.array([0.0, 0.0, lowest - 10.0]))  # 10 m up at worst
    context = flight_context(LOW_FLIGHT, scene_from_mission(LOW_FLIGHT))
    m = compute_metrics(sunk, context)
    assert m["min_ground_clearance_m"] == pytest.approx(10.0)
    assert m["collisions"] == 1
    assert m["per_vehicle"]["1"]["collisions"] == 1


def test_no_ground_no_ground_clearance() -> None:
    free = plan_mission(LOW_FLIGHT.model_copy(update={"ground": None}))
    assert free.metrics["min_ground_clearance_m"] is None


def table3_flown_by_formula() -> tuple[Trajectory, FlightContext]:
    """examples/paper_table3.json's five vehicles flown 60 s by a formula, not the planner
    (weaving yaw and pitch, varying speed; wingman 2 starts at the ground, wingman 4 is in
    its slot from 20 s on), and its context with the ground at 0 and the first obstacle
    moving: every branch of the metrics."""
    mission = load_mission_file(EXAMPLES / "paper_table3.json")
    scene = scene_from_mission(mission)
    t = (np.arange(1201) * 0.05).astype(np.float64)
    i = np.arange(5)[None, :]
    yaw = scene.fleet.yaw[None, :] + 0.6 * np.sin(0.15 * t[:, None] + i)
    pitch = 0.08 * np.sin(0.2 * t[:, None] + 0.5 * i)
    speed = 150.0 + 40.0 * np.sin(0.1 * t[:, None] + i)
    step = 0.05 * speed[:-1, :, None] * direction_vectors(pitch[:-1], yaw[:-1])
    pos = scene.fleet.pos[None] + np.concatenate([np.zeros((1, 5, 3)), np.cumsum(step, axis=0)])
    k, n = yaw.shape
    trajectory = Trajectory(
        ids=scene.fleet.ids, t=t, pos=pos, pitch=pitch, yaw=yaw, speed=speed,
        state=np.ones((k, n), dtype=np.int8), avoiding=np.zeros((k, n), dtype=bool),
        formed=np.zeros((k, n), dtype=bool),
    )  # fmt: skip
    late = t >= 20.0  # (the trajectory holds ``pos`` itself)
    pos[late, 3] = local_target_points(trajectory, scene.fleet.slot)[late, 3]
    moving = scene.obstacles.velocity.copy()
    moving[0] = (-20.0, 5.0, 0.0)
    context = replace(
        flight_context(mission, scene),
        obstacles=replace(scene.obstacles, velocity=moving),
        ground=0.0,
    )
    return trajectory, context


#: compute_metrics of table3_flown_by_formula() as the code before the split into named metric
#: functions computed it (planning_wall_time_s=2.5).
FORMULA_METRICS: dict[str, Any] = {
    "reached": False,
    "flight_time_s": None,
    "formation_time_s": None,
    "formation_share_after_forming": None,
    "min_separation_m": 141.42135623730894,
    "min_obstacle_clearance_m": 226.4739195447005,
    "min_ground_clearance_m": -8.539764169267022,
    "collisions": 3,
    "max_pitch_rate_rad_s": 0.015999932939008088,
    "max_yaw_rate_rad_s": 0.08999978377914758,
    "min_speed_m_s": 110.00011414449128,
    "max_speed_m_s": 189.9999873172734,
    "max_accel_m_s2": 3.99999489404388,
    "max_decel_m_s2": 3.999994186781347,
    "planning_wall_time_s": 2.5,
    "real_time_factor": 24.0,
    "simulated_time_s": 60.0,
    "leader_distance_to_target_m": 5360.919315910801,
}
FORMULA_SMOOTHNESS: dict[str, Any] = {
    "heading_change_deg_per_km": 20.706902817769112,
    "max_step_turn_deg": 0.26187114008014284,
    "wingman_offset_rms_m": 9647.14751114963,
    "wingman_hold_heading_change_deg_per_km": 23.714679310738685,
}
FORMULA_PER_VEHICLE: dict[str, dict[str, Any]] = {
    "2": {
        "role": "wingman",
        "max_pitch_rate_rad_s": 0.015999932939008088,
        "max_yaw_rate_rad_s": 0.08999978377914758,
        "min_speed_m_s": 110.00011414449128,
        "max_speed_m_s": 189.9999873172734,
        "max_accel_m_s2": 3.999994894042743,
        "max_decel_m_s2": 3.9999941867812936,
        "min_separation_m": 220.5692161335457,
        "min_obstacle_clearance_m": 1455.5470085267789,
        "min_ground_clearance_m": -8.539764169267022,
        "collisions": 3,
        "path_length_m": 8914.744682996045,
        "heading_change_deg_per_km": 22.616964897028097,
        "max_step_turn_deg": 0.26166832112250654,
        "local_target_offset_rms_m": 12346.365133869285,
        "formation_time_s": None,
    },
    "4": {
        "role": "wingman",
        "max_pitch_rate_rad_s": 0.01599993293900525,
        "max_yaw_rate_rad_s": 0.08999974151109826,
        "min_speed_m_s": 110.00011414449128,
        "max_speed_m_s": 189.99997925861456,
        "max_accel_m_s2": 3.999994894042743,
        "max_decel_m_s2": 3.999994186781347,
        "min_separation_m": 141.42135623730894,
        "min_obstacle_clearance_m": 595.5061869265526,
        "min_ground_clearance_m": 285.632232940455,
        "collisions": 0,
        "path_length_m": 12721.747554015796,
        "heading_change_deg_per_km": 15.60264373559972,
        "max_step_turn_deg": 0.26116084550933827,
        "local_target_offset_rms_m": 0.0,
        "formation_time_s": 20.0,
    },
}


def _agrees(got: dict[str, Any], want: dict[str, Any]) -> bool:
    """The same keys in the same order; floats to 1e-12 relative (numpy's SIMD maths may
    differ in the last bit between CPUs), everything else (ints, None, flags) exactly."""
    if list(got) != list(want):
        return False
    return all(
        type(g) is type(w)
        and (g == pytest.approx(w, rel=1e-12) if isinstance(w, float) else g == w)
        for g, w in zip(got.values(), want.values(), strict=True)
    )


def test_metrics_of_a_table3_flight_are_those_computed_before_the_split() -> None:
    trajectory, context = table3_flown_by_formula()
    m = compute_metrics(trajectory, context, planning_wall_time_s=2.5)
    assert list(m) == [*FORMULA_METRICS, "smoothness", "per_vehicle"]
    assert _agrees({k: m[k] for k in FORMULA_METRICS}, FORMULA_METRICS)
    assert _agrees(m["smoothness"], FORMULA_SMOOTHNESS)
    assert list(m["per_vehicle"]) == ["1", "2", "3", "4", "5"]
    for vid, row in FORMULA_PER_VEHICLE.items():
        got = {k: v for k, v in m["per_vehicle"][vid].items() if k != "nearest_keep_out"}
        assert _agrees(got, row), vid


def test_each_vehicle_s_nearest_keep_out_is_the_sphere_it_came_closest_to() -> None:
    """Against every sphere's distance over the whole flight, counted here apart."""
    trajectory, context = table3_flown_by_formula()
    m = compute_metrics(trajectory, context)
    obs = context.obstacles
    centres = obs.center[None] + trajectory.t[:, None, None] * obs.velocity[None]  # [K,M,3]
    labels = set()
    for i, vid in enumerate(trajectory.ids.tolist()):
        gaps = [
            float(np.min(np.linalg.norm(trajectory.pos[:, i] - centres[:, j], axis=-1)))
            - float(obs.radius[j])
            for j in range(obs.radius.shape[0])
        ]
        row = m["per_vehicle"][str(vid)]
        assert row["nearest_keep_out"] == f"obstacles[{int(np.argmin(gaps))}]"
        assert row["min_obstacle_clearance_m"] == pytest.approx(min(gaps))
        labels.add(row["nearest_keep_out"])
    assert len(labels) > 1  # not one answer for all


def test_a_zone_nearer_than_every_sphere_is_the_nearest_keep_out() -> None:
    """Two vehicles flying east, one 100 m beside a cylinder zone, the other 300 m beside a
    sphere: each one's nearest keep-out is its own; a fleet without keep-outs has none."""
    mission = Mission.model_validate({
        "target": [9000.0, 0.0, 500.0],
        "obstacles": [{"center": [4000.0, 1300.0, 500.0], "radius": 200.0}],
        "zones": [{"kind": "cylinder", "center": [4000.0, -1200.0], "radius": 100.0,
                   "floor": 0.0, "ceiling": 2000.0}],
        "vehicles": [
            {"id": 1, "role": "leader", "position": [0.0, -1000.0, 500.0]},
            {"id": 2, "role": "wingman", "position": [0.0, 1000.0, 500.0],
             "slot": [0.0, 2000.0, 0.0]},
        ],
    })  # fmt: skip
    scene = scene_from_mission(mission)
    t = (np.arange(161) * 0.5).astype(np.float64)  # 80 s, 8 km east
    pos = scene.fleet.pos[None] + t[:, None, None] * np.array([100.0, 0.0, 0.0])
    k, n = pos.shape[:2]
    trajectory = Trajectory(
        ids=scene.fleet.ids, t=t, pos=pos, pitch=np.zeros((k, n)), yaw=np.zeros((k, n)),
        speed=np.full((k, n), 100.0), state=np.ones((k, n), dtype=np.int8),
        avoiding=np.zeros((k, n), dtype=bool), formed=np.zeros((k, n), dtype=bool),
    )  # fmt: skip
    m = compute_metrics(trajectory, flight_context(mission, scene))
    assert m["per_vehicle"]["1"]["nearest_keep_out"] == "zones[0]"
    assert m["per_vehicle"]["1"]["min_obstacle_clearance_m"] == pytest.approx(100.0)
    assert m["per_vehicle"]["2"]["nearest_keep_out"] == "obstacles[0]"
    assert m["per_vehicle"]["2"]["min_obstacle_clearance_m"] == pytest.approx(100.0)
    bare = mission.model_copy(update={"obstacles": [], "zones": []})
    m = compute_metrics(trajectory, flight_context(bare, scene_from_mission(bare)))
    assert m["per_vehicle"]["1"]["nearest_keep_out"] is None


def test_the_share_in_formation_counts_from_the_first_forming() -> None:
    t = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 6.0])
    # leader, two wingmen: formed at t = 1, broken over [3, 4), formed again from 4 to 6
    in_place = np.array([[1, 0, 0], [1, 1, 1], [1, 1, 1], [1, 1, 0], [1, 1, 1], [1, 1, 1]],
                        dtype=bool)  # fmt: skip
    assert formation_share(t, in_place) == pytest.approx(4.0 / 5.0)
    assert formation_share(t, np.zeros((6, 3), dtype=bool)) is None

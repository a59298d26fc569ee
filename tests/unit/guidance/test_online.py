"""Online planning from telemetry: guided points ahead on the planned path."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from gcs_ppf.frames import local_target_point
from gcs_ppf.guidance.airframe import OnlineLimits
from gcs_ppf.guidance.online import (
    VehicleState,
    clearance,
    guidance,
    home_ground,
    nearest_keep_outs,
    planned_turn_rate,
    scene_now,
    separations,
    state_from_velocity,
)
from gcs_ppf.mission import Mission
from gcs_ppf.planning.planner import advance
from gcs_ppf.planning.scene import Obstacles, Scene, obstacles_from_mission
from gcs_ppf.planning.zones import zones_from_mission


def test_state_from_ned_velocity() -> None:
    s = state_from_velocity((1.0, 2.0, 3.0), vn_m_s=100.0, ve_m_s=0.0, vd_m_s=-10.0)
    assert s.yaw_rad == pytest.approx(math.pi / 2)  # north is +90° from east
    assert s.pitch_rad == pytest.approx(math.atan2(10.0, 100.0))  # climbing
    assert s.speed_m_s == pytest.approx(math.hypot(100.0, 10.0))


def test_a_position_is_carried_on_along_its_velocity_by_its_age() -> None:
    s = state_from_velocity((1.0, 2.0, 3.0), vn_m_s=100.0, ve_m_s=50.0, vd_m_s=-10.0, age_s=0.1)
    assert s.pos_m == pytest.approx((1.0 + 5.0, 2.0 + 10.0, 3.0 + 1.0))
    assert s.speed_m_s == pytest.approx(math.sqrt(100.0**2 + 50.0**2 + 10.0**2))


def test_a_turning_vehicle_is_carried_on_along_its_arc() -> None:
    """Heading north at 100 m/s, turning right (clockwise) at 0.1 rad/s: a quarter of the
    circle later it is heading east, one radius east and one radius north of where it was."""
    turn = -0.1
    r = 100.0 / abs(turn)
    quarter = (math.pi / 2) / abs(turn)
    s = state_from_velocity((0.0, 0.0, 0.0), 100.0, 0.0, 0.0, age_s=quarter, turn_rate_rad_s=turn)
    assert s.pos_m == pytest.approx((r, r, 0.0))
    assert s.yaw_rad == pytest.approx(0.0, abs=1e-9)


def _states_at_start(mission: Mission) -> dict[int, VehicleState]:
    out = {}
    for v in mission.vehicles:
        speed = v.speed or mission.limits.v_init
        vn = speed * math.sin(v.yaw) * math.cos(v.pitch)
        ve = speed * math.cos(v.yaw) * math.cos(v.pitch)
        vd = -speed * math.sin(v.pitch)
        out[v.id] = state_from_velocity(v.position, vn, ve, vd)
    return out


def test_guided_points_lie_ahead_on_the_plan(table3: Mission) -> None:
    states = _states_at_start(table3)
    ids = {v.id for v in table3.vehicles}
    scene = scene_now(table3, states, ids, obstacles_from_mission(table3))
    g = guidance(scene, lookahead_s=3.0, dt=0.02, carrot_m=1000.0)
    assert g.ids == [1, 2, 3, 4, 5]
    start = scene.fleet.pos
    ahead = np.linalg.norm(g.guided_point_m - start, axis=1)
    assert np.all(ahead > 1000.0 - 3.0 * 300.0)  # the carrot, beyond 3 s of flight
    assert np.all(ahead <= 1000.0 + 3.0 * 300.0 + 1e-6)
    plan = advance(scene, 0.02, 150).trajectory  # the same 3 s of PPF
    assert np.allclose(g.guided_point_m[:, 2], plan.pos[-1, :, 2])  # planned altitude
    bearing = g.guided_point_m[:, :2] - plan.pos[-1, :, :2]
    assert np.allclose(np.arctan2(bearing[:, 1], bearing[:, 0]), plan.yaw[-1])
    lead = 0.5 / 0.02 - 1  # course and climb rate as planned 0.5 s on
    assert np.allclose(g.course_rad, plan.yaw[round(lead)])
    climb = np.abs(plan.speed[round(lead)] * np.sin(plan.pitch[round(lead)]))
    assert np.allclose(g.climb_rate_m_s, climb + 1.0)
    yaws = np.concatenate([scene.fleet.yaw[None], plan.yaw])  # the turn rate there
    j = round(lead) + 1
    change = np.remainder(yaws[j + 12] - yaws[j - 12] + np.pi, 2 * np.pi) - np.pi
    assert np.allclose(g.turn_rate_rad_s[1:], change[1:] / (24 * 0.02))
    assert g.speed_ahead_m_s is not None
    # the speed to command: as planned 1 s on (the autopilot's speed response)
    assert np.allclose(g.speed_ahead_m_s, plan.speed[round(1.0 / 0.02) - 1])
    assert g.state[0] == "s3"  # the leader waits for its wingmen
    assert np.all(g.speed_m_s >= 100.0 - 1e-9)
    assert g.local_target_distance_m[0] is None


def test_a_lost_wingman_is_left_out(table3: Mission) -> None:
    states = _states_at_start(table3)
    scene = scene_now(table3, states, {1, 2, 3, 4}, obstacles_from_mission(table3))
    assert scene.fleet.active.tolist() == [True, True, True, True, False]
    g = guidance(scene, lookahead_s=1.0, dt=0.02)
    assert np.allclose(g.guided_point_m[4], scene.fleet.pos[4])


def test_pitch_limits_reach_the_planned_scene(table3: Mission) -> None:
    states = _states_at_start(table3)
    ids = {v.id for v in table3.vehicles}
    free = scene_now(table3, states, ids, obstacles_from_mission(table3))
    assert free.limits.max_climb_angle == math.pi / 2
    envelope = OnlineLimits(max_climb_angle=0.3, max_dive_angle=0.4)
    limited = scene_now(table3, states, ids, obstacles_from_mission(table3), envelope=envelope)
    assert (limited.limits.max_climb_angle, limited.limits.max_dive_angle) == (0.3, 0.4)


def test_separation_and_clearance(table3: Mission) -> None:
    pos = np.array([[0.0, 0.0, 0.0], [30.0, 40.0, 0.0], [1000.0, 0.0, 0.0]])
    assert separations(pos) == pytest.approx(50.0)
    assert separations(pos[:1]) is None
    obstacles = obstacles_from_mission(table3)
    assert clearance(np.array([[3000.0, 3000.0, 500.0]]), obstacles) == pytest.approx(50.0)


def no_obstacles() -> Obstacles:
    return Obstacles(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)))


def test_clearance_counts_the_zones_too_and_the_scene_keeps_them(table3: Mission) -> None:
    doc = table3.model_dump()
    doc["zones"] = [{"kind": "cylinder", "center": [4000.0, 1000.0], "radius": 200.0}]
    mission = Mission.model_validate(doc)
    zones = zones_from_mission(mission)
    obstacles = obstacles_from_mission(mission)
    near_zone = np.array([[4000.0, 1230.0, 300.0]])  # 30 m from the cylinder's wall
    assert clearance(near_zone, obstacles, zones) == pytest.approx(30.0)
    spheres_only = clearance(near_zone, obstacles)
    assert spheres_only is not None
    assert spheres_only > 1000.0  # the spheres alone are far
    assert clearance(near_zone, no_obstacles(), zones) == pytest.approx(30.0)
    assert clearance(near_zone, no_obstacles()) is None
    states = _states_at_start(mission)
    scene = scene_now(mission, states, {v.id for v in mission.vehicles}, obstacles)
    assert scene.zones.arrays[1].tolist() == zones.arrays[1].tolist()


def test_each_vehicles_nearest_keep_out_is_named_as_the_mission_lists_it(table3: Mission) -> None:
    """The flown status's ``nearest_keep_out``, as the offline metrics name it: the sphere
    or zone nearer than every other, and the distance to its surface."""
    doc = table3.model_dump()
    doc["zones"] = [
        {"kind": "cylinder", "center": [9000.0, 9000.0], "radius": 100.0},
        {"kind": "cylinder", "center": [4000.0, 1000.0], "radius": 200.0},
    ]
    mission = Mission.model_validate(doc)
    zones, obstacles = zones_from_mission(mission), obstacles_from_mission(mission)
    positions = np.array(
        [[4000.0, 1230.0, 300.0], [3000.0, 3000.0, 500.0], [4500.0, 6000.0, 1000.0]]
    )
    near = nearest_keep_outs(positions, obstacles, zones)
    assert [name for name, _ in near] == ["zones[1]", "obstacles[0]", "obstacles[3]"]
    assert [d for _, d in near] == pytest.approx([30.0, 50.0, 50.0])  # 900 above the 850
    assert clearance(positions, obstacles, zones) == pytest.approx(30.0)
    assert nearest_keep_outs(positions[:1], no_obstacles()) == [(None, None)]


def test_the_ground_is_the_missions_or_else_under_the_vehicles_homes(table3: Mission) -> None:
    states = _states_at_start(table3)
    ids = {v.id for v in table3.vehicles}
    obstacles = obstacles_from_mission(table3)
    assert scene_now(table3, states, ids, obstacles).limits.ground == -math.inf
    homes = home_ground([(300.0, 310.0), (200.0, 190.0)])  # one home at −10, one at 10
    assert homes == pytest.approx(10.0)  # the higher one
    assert home_ground([]) is None
    assert scene_now(table3, states, ids, obstacles, 0.0, homes).limits.ground == homes
    own = table3.model_copy(update={"ground": -50.0})
    assert scene_now(own, states, ids, obstacles, 0.0, homes).limits.ground == -50.0


def test_the_planned_turn_rate_is_the_yaw_change_around_the_lead() -> None:
    t = np.arange(1, 101, dtype=np.float64) * 0.02
    yaw = np.stack([0.3 * t, -0.1 * t, np.full_like(t, 3.1)], axis=1)
    yaw[:, 2] += np.where(t > 0.6, 0.1, 0.0)  # crosses ±π within the window
    yaw = np.remainder(yaw + np.pi, 2 * np.pi) - np.pi
    rate = planned_turn_rate(np.array([0.0, 0.0, 3.1]), t, yaw, 24, 0.5)
    assert rate[:2] == pytest.approx([0.3, -0.1])
    assert rate[2] == pytest.approx(0.1 / 0.48)  # over 0.26–0.74 s, wrapped, not −2π
    edge = planned_turn_rate(np.array([0.0, 0.0, 3.1]), t, yaw, 0, 0.5)  # clipped at t = 0
    assert edge[0] == pytest.approx(0.3)
    assert planned_turn_rate(np.zeros(1), t[:1], yaw[:1, :1], 0, 0.0) == pytest.approx([0.0])


def test_a_plan_ending_on_the_arrival_instant_has_no_nan_turn() -> None:
    """The leader arriving at a step's very start (fraction 0) records the step's time again:
    a window over those two records has no span (0 / 0 gave NaN turn rates, with a
    RuntimeWarning in the service's log at most arrivals)."""
    t = np.array([0.02, 0.04, 0.04])
    yaw = np.array([[0.1], [0.2], [0.2]])
    rate = planned_turn_rate(np.array([0.0]), t, yaw, 2, 0.0)
    assert np.isfinite(rate).all()
    assert rate == pytest.approx([0.0])


def test_the_airframes_envelope_tightens_the_planned_scene(table3: Mission) -> None:
    states = _states_at_start(table3)
    ids = {v.id for v in table3.vehicles}
    obstacles = obstacles_from_mission(table3)
    env = OnlineLimits(v_min=120.0, v_max=250.0, max_yaw_rate=0.2, max_climb_angle=0.25,
                       max_dive_angle=0.3)  # fmt: skip
    lim = scene_now(table3, states, ids, obstacles, envelope=env).limits
    assert (lim.v_min, lim.v_max, lim.max_yaw_rate) == (120.0, 250.0, 0.2)
    assert (lim.max_climb_angle, lim.max_dive_angle) == (0.25, 0.3)
    assert lim.max_pitch_rate == table3.limits.max_pitch_rate
    loose = OnlineLimits(v_min=50.0, v_max=400.0, max_yaw_rate=2.0)  # the mission's bind
    lim = scene_now(table3, states, ids, obstacles, envelope=loose).limits
    assert (lim.v_min, lim.v_max) == (table3.limits.v_min, table3.limits.v_max)
    assert lim.max_yaw_rate == table3.limits.max_yaw_rate
    # an ArduPlane's 10–30 m/s never meets the paper's 100–300: it flies what it can
    small = scene_now(table3, states, ids, obstacles, envelope=OnlineLimits(10.0, 30.0))
    assert (small.limits.v_min, small.limits.v_max) == (10.0, 30.0)
    assert np.all(small.fleet.speed <= 30.0)
    unknown = scene_now(table3, states, ids, obstacles, envelope=OnlineLimits())
    assert unknown.limits == scene_now(table3, states, ids, obstacles).limits


def test_the_flight_path_is_planned_from_the_averaged_vertical_speed_when_given() -> None:
    """Carried on along the velocity it reports, pitched as its averaged vertical speed."""
    s = state_from_velocity((0.0, 0.0, 100.0), 20.0, 0.0, -3.0, age_s=1.0,
                            flight_path_vd_m_s=-1.0)  # fmt: skip
    assert s.pos_m[2] == pytest.approx(103.0)  # climbing 3 m/s now
    assert s.pitch_rad == pytest.approx(math.atan2(1.0, 20.0))
    plain = state_from_velocity((0.0, 0.0, 100.0), 20.0, 0.0, -3.0, age_s=1.0)
    assert plain.pitch_rad == pytest.approx(math.atan2(3.0, 20.0))


def test_a_leader_planned_ahead_of_its_course_has_its_slots_where_its_course_puts_them(
    table3: Mission,
) -> None:
    """Planned from a course 4° to the left of the one it flies (``speed_reference``), the
    leader's slots are laid out from the course flown: its wingmen are planned to the same
    points, however the plan turns it."""
    flown = {vid: replace(s, pitch_rad=0.0) for vid, s in _states_at_start(table3).items()}
    ahead = math.radians(4.0)
    leader = flown[1]
    planned = {**flown, 1: replace(leader, yaw_rad=leader.yaw_rad + ahead, course_ahead_rad=ahead)}
    ids = set(flown)
    as_flown = scene_now(table3, flown, ids, obstacles_from_mission(table3))
    as_planned = scene_now(table3, planned, ids, obstacles_from_mission(table3))
    assert as_planned.fleet.yaw[0] == pytest.approx(as_flown.fleet.yaw[0] + ahead)

    def points(scene: Scene) -> np.ndarray:
        f = scene.fleet
        return np.array(
            [local_target_point(f.pos[0], 0.0, float(f.yaw[0]), f.slot[i]) for i in range(5)]
        )

    assert np.allclose(points(as_planned), points(as_flown))
    assert not np.allclose(as_planned.fleet.slot, as_flown.fleet.slot)  # turned to get there
    assert np.allclose(
        np.linalg.norm(as_planned.fleet.slot, axis=1), np.linalg.norm(as_flown.fleet.slot, axis=1)
    )

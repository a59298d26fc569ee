"""The PPF kernel's equation groups, one at a time."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gcs_ppf.mission import Mission, load_mission_file
from gcs_ppf.planning.planner import advance
from gcs_ppf.planning.ppf.kernel import (
    MAX_AVOID_PITCH,
    S2_LOCAL_MINIMUM,
    KernelLimits,
    away_from_obstacles,
    braking_speed,
    influence_radius,
    lowest_climb,
    obstacles_first,
    to_vcs,
    trend,
)
from gcs_ppf.planning.scene import scene_from_mission

OMEGA = math.pi / 6


def solo(
    position: list[float],
    yaw: float,
    target: list[float],
    obstacles: list[dict[str, Any]],
    **extra: Any,
) -> Mission:
    vehicle = {"id": 1, "role": "leader", "position": position, "yaw": yaw}
    return Mission.model_validate(
        {
            "target": target,
            "vehicles": [{**vehicle, **extra.pop("vehicle", {})}],
            "obstacles": obstacles,
            **extra,
        }
    )


def printed_eq10(r_o: float, speed: float, r_v: float) -> float:
    rv = speed / OMEGA + r_v
    return math.sqrt((r_o + rv) ** 2 - r_o**2)


def test_printed_eq10_starts_avoidance_inside_large_obstacles() -> None:
    """Erratum 4: as printed, R < R_o for Table 3's big obstacles at 100 m/s."""
    assert printed_eq10(850.0, 100.0, 25.0) < 850.0
    assert printed_eq10(650.0, 100.0, 25.0) < 650.0
    assert influence_radius(100.0, OMEGA, 850.0 + 25.0) > 875.0


@pytest.mark.parametrize("speed", [100.0, 300.0])
@pytest.mark.parametrize("keep_out", [75.0, 875.0])
def test_influence_radius_is_where_a_full_turn_just_clears(speed: float, keep_out: float) -> None:
    """Fig. 2 geometry: from R, heading at the centre, a full-rate turn's circle passes the
    centre at exactly ``keep_out``."""
    r = influence_radius(speed, OMEGA, keep_out)
    rho = speed / OMEGA
    angles = np.linspace(0.0, math.pi, 200_001)
    # vehicle at (-r, 0) heading +x, turning left on a circle centred at (-r, rho)
    x = -r + rho * np.sin(angles)
    y = rho - rho * np.cos(angles)
    assert np.hypot(x, y).min() == pytest.approx(keep_out, rel=1e-6)


def test_trend_is_a_saturated_sign() -> None:
    step = OMEGA * 0.01
    assert trend(1.0, OMEGA, 0.01) == 1.0
    assert trend(-0.2, OMEGA, 0.01) == -1.0
    assert trend(step / 2, OMEGA, 0.01) == pytest.approx(0.5)
    assert trend(0.0, OMEGA, 0.01) == 0.0


@pytest.mark.parametrize(("v0", "d"), [(100.0, 0.0), (100.0, 500.0), (220.0, 37.0)])
def test_braking_speed_matches_eq21_22(v0: float, d: float) -> None:
    a = 40.0
    vi = braking_speed(v0, d, a)
    dt_prime = (vi - v0) / a  # Eq. 21
    dd_prime = vi * dt_prime - a * dt_prime**2 / 2  # Eq. 22
    assert dd_prime == pytest.approx(d, abs=1e-9)


def test_to_vcs_is_eq16_to_18() -> None:
    pitch, yaw = 0.3, -1.1
    f = np.array([1.0, 2.0, 3.0])
    a_fv = np.array(
        [[math.cos(pitch), 0, math.sin(pitch)], [0, 1, 0], [-math.sin(pitch), 0, math.cos(pitch)]]
    )
    b_fv = np.array(
        [[math.cos(yaw), math.sin(yaw), 0], [-math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]]
    )
    got = to_vcs(f[0], f[1], f[2], math.cos(pitch), math.sin(pitch), math.cos(yaw), math.sin(yaw))
    assert np.allclose(got, a_fv @ b_fv @ f)


def test_target_left_turns_left_and_target_above_pitches_up() -> None:
    """Erratum 2: f_ψ follows F_v^y (left wing), f_θ follows F_v^z (up)."""
    left = advance(scene_from_mission(solo([0, 0, 0], 0.0, [1000, 1000, 0], [])), 0.01, 1)
    assert left.scene.fleet.yaw[0] == pytest.approx(OMEGA * 0.01)
    assert left.scene.fleet.pitch[0] == pytest.approx(0.0)
    up = advance(scene_from_mission(solo([0, 0, 0], 0.0, [1000, 0, 1000], [])), 0.01, 1)
    assert up.scene.fleet.pitch[0] == pytest.approx(OMEGA * 0.01)
    assert up.scene.fleet.yaw[0] == pytest.approx(0.0)


def test_exact_head_on_enters_s2_and_pulls_up() -> None:
    """Eq. 20: repulsion antiparallel to the velocity; F_add along +z_v pulls the nose up
    (while the vehicle turns round: the wanted direction is behind it), no steeper than
    MAX_AVOID_PITCH."""
    mission = solo(
        [-1200.0, 0.0, 0.0], 0.0, [3000.0, 0.0, 0.0], [{"center": [0.0, 0.0, 0.0], "radius": 850.0}]
    )
    run = advance(scene_from_mission(mission), 0.01, 500)
    tr = run.trajectory
    entered = int(np.argmax(tr.state[:, 0] == S2_LOCAL_MINIMUM))
    assert entered > 0
    assert tr.pitch[entered, 0] > 0.0
    assert tr.pitch[-1, 0] > 0.5
    # The limit is on the wanted direction; pitch follows its elevation in the VCS, which
    # drifts from the ICS elevation by a little while the vehicle also yaws.
    assert tr.pitch.max() <= MAX_AVOID_PITCH + math.radians(2.0)


def test_advance_does_not_mutate_its_input() -> None:
    scene = scene_from_mission(solo([0, 0, 0], 0.0, [5000, 0, 0], []))
    before = scene.fleet.pos.copy()
    advance(scene, 0.01, 10)
    assert np.array_equal(scene.fleet.pos, before)


def _limits(mission: Mission) -> KernelLimits:
    return scene_from_mission(mission).limits


@pytest.mark.parametrize("speed", [100.0, 300.0])
def test_lowest_climb_is_the_steepest_dive_a_full_rate_pull_up_levels_out_of(
    speed: float,
) -> None:
    """Pulling up at ω_θ from the allowed angle, on an arc of radius ρ at the fastest speed
    reachable meanwhile, loses exactly the height available; below the keep-out it climbs."""
    lim = _limits(solo([0, 0, 0], 0.0, [1000, 0, 0], []))
    v = min(speed + lim.accel * (math.pi / 2) / lim.max_pitch_rate, lim.v_max)
    rho = v / lim.max_pitch_rate
    for height in (0.0, 10.0, 0.3 * rho, 0.9 * rho):
        gamma = math.asin(lowest_climb(height, speed, lim))
        assert gamma <= 0.0
        assert rho * (1.0 - math.cos(gamma)) == pytest.approx(height, abs=1e-6)
    assert lowest_climb(rho, speed, lim) == -1.0
    assert lowest_climb(math.inf, speed, lim) == -1.0
    assert 0.0 < lowest_climb(-30.0, speed, lim) < lowest_climb(-60.0, speed, lim)


def _dive(ground: float | None, speed: float, pitch: float) -> Any:
    """A leader at 400 m diving at a target deep under the ground (the kernel takes any
    arrays; a mission would refuse such a target)."""
    mission = solo(
        [0.0, 0.0, 400.0],
        0.0,
        [9000.0, 0.0, 300.0],
        [],
        vehicle={"pitch": pitch, "speed": speed},
        **({} if ground is None else {"ground": ground}),
    )
    scene = replace(scene_from_mission(mission), target=np.array([9000.0, 0.0, -5000.0]))
    return advance(scene, 0.01, 3000).trajectory


@pytest.mark.parametrize("speed", [100.0, 300.0])
@pytest.mark.parametrize("pitch", [-math.pi / 3, -math.pi / 4, -0.2, 0.3])
def test_a_dive_levels_out_above_the_ground(speed: float, pitch: float) -> None:
    """Diving at a target under the ground, the leader levels out no lower than the safe
    distance above it and flies on there; in free space the same dive goes through it."""
    tr = _dive(0.0, speed, pitch)
    assert tr.pos[:, 0, 2].min() >= 25.0
    assert tr.pos[-1, 0, 2] <= 25.0 + 3 * 0.01 * 300.0 + 1.0  # it stays low, not climbing
    assert _dive(None, speed, pitch).pos[:, 0, 2].min() < 0.0


def test_a_wingman_whose_slot_is_under_the_ground_stays_above_it() -> None:
    mission = Mission.model_validate({
        "ground": 0.0,
        "target": [20000.0, 0.0, 150.0],
        "vehicles": [
            {"id": 1, "role": "leader", "position": [0.0, 0.0, 150.0]},
            {"id": 2, "role": "wingman", "position": [-300.0, 300.0, 150.0],
             "slot": [-100.0, 100.0, -200.0]},
        ],
    })  # fmt: skip
    run = advance(scene_from_mission(mission), 0.01, 4000)
    assert run.trajectory.pos[:, 1, 2].min() >= 25.0
    free = advance(scene_from_mission(mission.model_copy(update={"ground": None})), 0.01, 4000)
    assert free.trajectory.pos[:, 1, 2].min() < 0.0


def test_a_vehicle_inside_the_ground_keep_out_climbs_out() -> None:
    """Put 5 m above the ground (as a vehicle that sank there would be), it climbs back."""
    scene = scene_from_mission(solo([0.0, 0.0, 100.0], 0.0, [9000.0, 0.0, 30.0], [], ground=0.0))
    scene.fleet.pos[0, 2] = 5.0
    tr = advance(scene, 0.01, 1000).trajectory
    assert np.all(np.diff(tr.pos[:, 0, 2]) >= 0.0)
    assert tr.pos[-1, 0, 2] >= 25.0


def test_an_obstacle_standing_on_the_ground_is_passed_beside_or_above() -> None:
    """Head-on at a sphere whose bottom touches the ground: the way under is closed."""
    mission = solo(
        [-3000.0, 0.0, 300.0],
        0.0,
        [3000.0, 0.0, 300.0],
        [{"center": [0.0, 0.0, 300.0], "radius": 300.0}],
        ground=0.0,
        vehicle={"pitch": -0.1},
    )
    tr = advance(scene_from_mission(mission), 0.01, 6000).trajectory
    assert tr.pos[:, 0, 2].min() >= 25.0
    clear = np.linalg.norm(tr.pos[:, 0] - np.array([0.0, 0.0, 300.0]), axis=1) - 300.0
    assert clear.min() >= 25.0
    assert np.linalg.norm(tr.pos[-1, 0] - np.array([3000.0, 0.0, 300.0])) <= 10.0


def test_a_turn_never_closes_further_on_a_repelling_obstacle_if_the_other_way_does_not() -> None:
    lim = _limits(solo([0, 0, 0], 0.0, [1000, 0, 0], []))
    north_east = (-1.0, -1.0, 0.0)  # repulsion of an obstacle to the north-east
    assert away_from_obstacles(0.0, 0.0, 0.0, 1.0, *north_east, lim, 0.01) == -1.0  # left: into it
    assert away_from_obstacles(0.0, 0.0, 0.0, -1.0, *north_east, lim, 0.01) == -1.0
    assert away_from_obstacles(0.0, math.pi, 0.0, 1.0, *north_east, lim, 0.01) == 1.0  # not closing
    assert away_from_obstacles(0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, lim, 0.01) == 1.0  # no obstacle


def test_a_wingman_between_a_mate_and_an_obstacle_turns_away_from_the_obstacle() -> None:
    """Flown closed loop (tests/integration, a sphere put in the path): wingman 3 closing on
    the obstacle, wingman 2 (higher priority) off to its right and converging.  The mate's
    repulsion added to the obstacle's pointed behind the vehicle, and Eq. 19's sense of
    turn took it left, through the obstacle (60 m from its surface against a 125 m
    keep-out: the service's 100 m planning margin).  The state is the one telemetry gave."""
    mission = Mission.model_validate({
        "ground": 0.0,
        "target": [6000.0, 7000.0, 300.0],
        "vehicles": [
            {"id": 1, "role": "leader", "position": [3674.2, 3353.9, 300.0], "yaw": 1.0731},
            {"id": 2, "role": "wingman", "position": [3658.9, 3326.6, 149.4], "pitch": 0.0235,
             "yaw": 1.0987, "speed": 118.6, "slot": [-100.0, 100.0, 0.0]},
            {"id": 3, "role": "wingman", "position": [3279.7, 3386.5, 147.2], "pitch": -0.0766,
             "yaw": 0.9828, "speed": 146.9, "slot": [-200.0, 200.0, 0.0]},
        ],
        "obstacles": [{"center": [3300.0, 3900.0, 300.0], "radius": 300.0}],
    })  # fmt: skip
    scene = scene_from_mission(mission)
    scene = replace(scene, limits=scene.limits._replace(safe_distance_obstacle=125.0,
                                                        safe_distance_uav=150.0))  # fmt: skip
    scene.fleet.active[0] = False  # the leader far above plays no part
    tr = advance(scene, 0.02, 300).trajectory
    clearance = np.linalg.norm(tr.pos[:, 2] - np.array([3300.0, 3900.0, 300.0]), axis=1) - 300.0
    assert clearance.min() >= 125.0
    assert np.linalg.norm(tr.pos[:, 1] - tr.pos[:, 2], axis=1).min() >= 150.0


def test_table3_planned_within_arduplanes_pitch_limits_still_keeps_every_distance() -> None:
    """With the airframe's flight-path limits (ArduPlane's defaults, +20°/−25°) the plan
    climbs round the obstacles less steeply and keeps both safe distances."""
    mission = load_mission_file(Path(__file__).resolve().parents[4] / "examples/paper_table3.json")
    scene = scene_from_mission(mission)
    limits = scene.limits._replace(
        max_climb_angle=math.radians(20.0), max_dive_angle=math.radians(25.0)
    )
    scene = replace(scene, limits=limits)
    run = advance(scene, 0.01, 12000)
    tr = run.trajectory
    assert run.arrived
    assert tr.pitch.min() >= math.radians(-25.0) - 1e-9
    assert tr.pitch.max() <= math.radians(20.0) + 1e-9
    ob = scene.obstacles
    clearance = np.linalg.norm(tr.pos[:, :, None] - ob.center[None, None], axis=-1) - ob.radius
    assert clearance.min() >= mission.limits.safe_distance_obstacle
    gaps = np.linalg.norm(tr.pos[:, :, None] - tr.pos[:, None], axis=-1)
    n = tr.pos.shape[1]
    gaps[:, np.arange(n), np.arange(n)] = np.inf
    assert gaps.min() >= mission.limits.safe_distance_uav


def test_obstacles_first_drops_only_a_teammates_push_into_the_obstacle() -> None:
    # Obstacle repels along +x; a teammate pushes along −x and +y: only the −x part goes.
    assert obstacles_first(1.0 - 0.5, 0.5, 0.0, 1.0, 0.0, 0.0) == pytest.approx((1.0, 0.5, 0.0))
    # A push away from the obstacle, or no obstacle at all: unchanged.
    assert obstacles_first(1.5, 0.5, 0.0, 1.0, 0.0, 0.0) == (1.5, 0.5, 0.0)
    assert obstacles_first(-0.5, 0.5, 0.0, 0.0, 0.0, 0.0) == (-0.5, 0.5, 0.0)


def test_a_teammate_does_not_push_a_wingman_into_an_obstacle() -> None:
    """Flown closed loop (Table 3 with the 100 m planning margin), telemetry state: wingman
    4 slid round the 650 m obstacle while teammates converged on it.  Their repulsion,
    against the obstacle's, pushed it in: from this state the plan came to 40.9 m of the
    surface with the paper's free pitch (and 12.6 m into it at ArduPlane's 20° climb limit,
    before the half turn of ``airframe_limited``).  Obstacles first: 74.3 m."""
    doc = json.loads(
        (Path(__file__).resolve().parents[4] / "examples/paper_table3.json").read_text()
    )
    states = {
        1: ((4254.1, 4004.4, 404.7), 0.1779, 1.0410, 100.0),  # 99.9: v_min as online
        2: ((4073.4, 3793.4, 523.4), 0.3264, 0.6162, 148.3),
        3: ((3810.4, 3426.7, 440.3), 0.0443, 1.1934, 174.3),
        4: ((4552.1, 3922.4, 436.7), 0.1798, 1.3189, 104.8),
        5: ((4287.7, 3605.0, 395.2), -0.1000, 0.9577, 156.3),
    }
    for v in doc["vehicles"]:
        v["position"], v["pitch"], v["yaw"], v["speed"] = states[v["id"]]
    doc["ground"] = 0.0
    scene = scene_from_mission(Mission.model_validate(doc))
    limits = scene.limits._replace(safe_distance_obstacle=125.0, safe_distance_uav=150.0)
    tr = advance(replace(scene, limits=limits), 0.02, 400).trajectory
    i = scene.fleet.ids.tolist().index(4)
    obstacle = np.array([5000.0, 4500.0, 100.0])
    clearance = np.linalg.norm(tr.pos[:, i] - obstacle, axis=1) - 650.0
    assert clearance.min() >= 62.5  # half the planned keep-out at least (40.9 m without)


def test_a_climb_limited_airframe_starts_avoiding_a_turn_radius_further_out() -> None:
    """``airframe_limited``: room for a half turn, since it cannot climb over in a quarter."""
    mission = solo([0.0, 0.0, 300.0], 0.0, [9000.0, 0.0, 300.0],
                   [{"center": [3000.0, 0.0, 300.0], "radius": 650.0}])  # fmt: skip
    scene = scene_from_mission(mission)
    rho = 100.0 / OMEGA
    reach = influence_radius(100.0, OMEGA, 650.0 + 25.0)
    limited = scene.limits._replace(max_climb_angle=math.radians(20.0),
                                    max_dive_angle=math.radians(25.0))  # fmt: skip
    for gap, free_avoids, limited_avoids in ((reach + 0.5 * rho, False, True),
                                             (reach + 1.5 * rho, False, False)):  # fmt: skip
        fleet = scene.fleet.copy()
        fleet.pos[0, 0] = 3000.0 - gap
        free = advance(replace(scene, fleet=fleet), 0.01, 1).trajectory
        lim = advance(replace(scene, fleet=fleet, limits=limited), 0.01, 1).trajectory
        assert bool(free.avoiding[0, 0]) is free_avoids
        assert bool(lim.avoiding[0, 0]) is limited_avoids

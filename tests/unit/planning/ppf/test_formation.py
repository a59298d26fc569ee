"""Formation maintenance (gcs_ppf.planning.ppf.formation): crossing points and speed laws."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gcs_ppf.mission import Mission, load_mission_file
from gcs_ppf.planning.metrics import formation_share, formation_time, local_target_points
from gcs_ppf.planning.planner import advance
from gcs_ppf.planning.ppf.formation import (
    formation_turn_rate,
    just_reaching,
)
from gcs_ppf.planning.ppf.kernel import (
    catching_up_speed,
    crossing_point,
    falling_back_speed,
)
from gcs_ppf.planning.ppf.primitives import (
    LEADER_PATH_ANGLE_SHARE,
    inside_turn,
    leader_limits,
    reaching_turn_rate,
    turn_missed_ahead,
    way_clear,
)
from gcs_ppf.planning.ppf.reference import _crossing
from gcs_ppf.planning.ppf.repulsion import padding
from gcs_ppf.planning.scene import Scene, scene_from_mission, with_margins
from tests.conftest import ARDUPLANE, EXAMPLES

EAST = (1.0, 0.0, 0.0)
CLEARANCE = 127.0
FAR = 1000.0


def cross(p: tuple[float, ...], g: tuple[float, ...], m: tuple[float, ...] = (0.0, 0.0, 0.0),
          u: tuple[float, ...] = EAST, reach: float = FAR) -> tuple[float, np.ndarray]:  # fmt: skip
    s, x, y, z = crossing_point(
        p[0], p[1], p[2], g[0], g[1], g[2], m[0], m[1], m[2], u[0], u[1], u[2], CLEARANCE, reach
    )
    return s, np.array([x, y, z])


def closest_to(m: np.ndarray, p: np.ndarray, q: np.ndarray) -> float:
    """Distance from m to the ray from p through q."""
    d = (q - p) / np.linalg.norm(q - p)
    t = max(float((m - p) @ d), 0.0)
    return float(np.linalg.norm(p + t * d - m))


def test_a_clear_way_is_kept() -> None:
    g = (-100.0, 100.0, 0.0)
    s, point = cross((-300.0, -100.0, 0.0), g)  # passes 212 m behind the leader
    assert s == -1.0
    assert np.allclose(point, g)
    s, point = cross((-100.0, 200.0, 0.0), g)  # the leader is not between
    assert s == -1.0
    assert np.allclose(point, g)


def test_a_way_across_the_track_close_behind_passes_at_the_clearance() -> None:
    p = np.array([-100.0, -150.0, 5.0])
    s, point = cross(tuple(p), (-100.0, 100.0, 0.0))
    assert 0.0 < s < 1.0
    assert closest_to(np.zeros(3), p, point) == pytest.approx(CLEARANCE, rel=1e-9)
    d = (point - p) / np.linalg.norm(point - p)
    nearest = p + float(-p @ d) * d
    assert nearest[0] < 0.0  # it passes behind the leader, never ahead of it


def test_a_way_straight_through_the_teammate_passes_above_it() -> None:
    p = np.array([0.0, -150.0, 0.0])
    _, point = cross(tuple(p), (0.0, 150.0, 0.0))
    assert point[2] > 0.0
    assert point[0] == pytest.approx(0.0, abs=1e-9)


def test_a_way_passing_ahead_of_the_leader_is_turned_above_it_not_further_ahead() -> None:
    p = np.array([20.0, -150.0, 0.0])
    _, point = cross(tuple(p), (20.0, 150.0, 10.0))
    assert closest_to(np.zeros(3), p, point) == pytest.approx(CLEARANCE, rel=1e-9)
    assert point[0] <= p[0] + 1e-9  # no further forward than the wingman is
    assert point[2] > 0.0


def test_inside_the_clearance_the_wingman_heads_across_the_line_to_the_teammate() -> None:
    p = np.array([-90.0, -20.0, 10.0])
    _, point = cross(tuple(p), (-100.0, 100.0, 0.0))
    assert float((point - p) @ (np.zeros(3) - p)) == pytest.approx(0.0, abs=1e-6)


def test_the_point_made_for_is_at_most_reach_away() -> None:
    p = (-100.0, -400.0, 0.0)
    _, point = cross(p, (-100.0, 400.0, 0.0), reach=150.0)
    assert np.linalg.norm(point - np.array(p)) == pytest.approx(150.0)


coordinate = st.floats(-400.0, 400.0)


@given(
    p=st.tuples(coordinate, coordinate, coordinate),
    g=st.tuples(coordinate, coordinate, coordinate),
    m=st.tuples(coordinate, coordinate, coordinate),
    heading=st.floats(-math.pi, math.pi),
    climb=st.floats(-1.0, 1.0),
    reach=st.floats(50.0, 600.0),
)
def test_the_kernel_and_the_reference_make_for_the_same_point(
    p: tuple[float, float, float], g: tuple[float, float, float],
    m: tuple[float, float, float], heading: float, climb: float, reach: float,
) -> None:  # fmt: skip
    u = (math.cos(climb) * math.cos(heading), math.cos(climb) * math.sin(heading), math.sin(climb))
    s, point = cross(p, g, m, u, reach)
    s_ref, point_ref = _crossing(np.array(p), np.array(g), np.array(m), np.array(u), CLEARANCE,
                                 reach)  # fmt: skip
    assert s == pytest.approx(s_ref, abs=1e-12)
    assert np.allclose(point, point_ref, atol=1e-6)
    if s >= 0.0 and np.linalg.norm(np.subtract(m, p)) > CLEARANCE:
        # Outside the sphere the way made for is tangent to it: it keeps the clearance.
        assert closest_to(np.array(m), np.array(p), point) >= CLEARANCE * (1 - 1e-9)


@pytest.mark.parametrize(("v0", "d"), [(100.0, 2000.0), (16.0, 500.0), (220.0, 37.0)])
def test_catching_up_speed_is_eq22_with_the_closing_speed(v0: float, d: float) -> None:
    """Eq. 21–22 relative to the moving local target point: braking from v_i to v_0 at a
    closes exactly d on it (where √(2ad) is below the gain's limit)."""
    a = 40.0
    vi = catching_up_speed(v0, d, a, math.inf)
    dt_prime = (vi - v0) / a  # Eq. 21
    dd_prime = (vi - v0) * dt_prime - a * dt_prime**2 / 2  # Eq. 22, closing speed v_i − v_0
    assert dd_prime == pytest.approx(d, rel=1e-12)


def eased(
    turn: float,
    left: float,
    speeds: list[float],
    slots_y: list[float],
    behind: list[float],
    above: list[float] | None = None,
) -> float:
    """The leader (at the origin, heading east) turning at ``turn`` with wingmen whose slots
    are 100 m behind it, ``slots_y`` to its left, each wingman ``behind`` m behind its slot
    (and ``above`` m over it), ``left`` rad from the heading it wants."""
    ys = [0.0, *slots_y]
    local_target = np.array([[0.0 if i == 0 else -100.0, y, 0.0] for i, y in enumerate(ys)])
    pos = local_target.copy()
    pos[1:, 0] -= behind
    pos[1:, 2] += above or [0.0] * len(behind)
    active = np.ones(len(ys), dtype=np.bool_)
    return formation_turn_rate(turn, left, pos, np.array(speeds), active, local_target, 1.0, 0.0,
                               ARDUPLANE)  # fmt: skip


def test_a_wingman_keeping_station_is_turned_no_faster_from_its_speed_than_it_follows() -> None:
    """At the leader's speed, the slot 100 m inside a 0.035 rad/s turn would fly 3.5 m/s
    slower at once; a wingman in its slot is left within ε/2 of it: the turn starts at
    √(a·ε)/|y| = 0.0245 rad/s, and more slowly with the wingman already 4 m ahead of its
    slot (√(2a·(ε/2 − 4))/|y|).  A wingman 50 m behind its slot (joining it) does not hold
    the leader, one 50 m above it does; neither does one already slower by more."""
    budget = math.sqrt(0.6 * 10.0) / 100.0
    assert eased(0.035, math.pi, [22.0, 22.0], [100.0], [0.0]) == pytest.approx(budget)
    ahead = math.sqrt(2 * 0.6 * 1.0) / 100.0
    assert eased(0.035, math.pi, [22.0, 22.0], [100.0], [-4.0]) == pytest.approx(ahead)
    assert eased(0.035, math.pi, [22.0, 22.0], [100.0], [50.0]) == 0.035
    assert eased(0.035, math.pi, [22.0, 22.0], [100.0], [0.0], [50.0]) == pytest.approx(budget)
    assert eased(0.035, math.pi, [22.0, 18.5], [100.0], [0.0]) == 0.035
    assert eased(-0.035, math.pi, [22.0, 22.0, 22.0], [100.0, -100.0], [0.0, 0.0]) == (
        pytest.approx(-budget)
    )


def test_a_wingman_at_the_edge_of_its_slot_holds_the_turn_that_would_take_it_further() -> None:
    """A wingman ε/2 (5 m) behind its slot, at the leader's speed: the leader does not turn
    away from it (its slot outside the turn, faster) at all, and turns towards it as fast as
    the slot's speed may fall below the wingman's (√(2a·ε)/|y|)."""
    assert eased(-0.035, math.pi, [22.0, 22.0], [100.0], [5.0]) == 0.0
    towards = math.sqrt(2 * 0.6 * 10.0) / 100.0
    assert eased(0.035, math.pi, [22.0, 22.0], [100.0], [5.0]) == pytest.approx(towards)


WINGMEN = st.tuples(st.floats(16.0, 28.0), st.floats(-300.0, 300.0), st.floats(-40.0, 40.0))


@given(
    st.floats(-0.3, 0.3),
    st.floats(-math.pi, math.pi),
    st.lists(WINGMEN, min_size=1, max_size=6),
    st.floats(16.0, 28.0),
)
def test_an_eased_turn_never_takes_a_slot_further_from_its_wingman_than_it_can_follow(
    turn: float, left: float, wingmen: list[tuple[float, float, float]], v0: float
) -> None:
    """Eased, the turn keeps its sense and is no faster; no wingman within three target
    accuracies of its slot sees its slot speed (v₀ − ω·y) get further from its own than it
    can make good within ε/2 of the slot (g²/2a, from where it is) or than it was; and the
    turn eases out towards the heading wanted: no faster than √(2·a/|y|·|Δψ|)."""
    speeds = [v0] + [w[0] for w in wingmen]
    ys = [w[1] for w in wingmen]
    rate = eased(turn, left, speeds, ys, [w[2] for w in wingmen])
    assert rate * turn >= 0.0
    assert abs(rate) <= abs(turn)
    for v, y, behind in wingmen:
        if abs(behind) <= 30.0 and abs(y) >= 1e-9:
            gap = v0 - v
            faster = (gap - rate * y) - max(gap, 0.0)  # beyond what straight flight gives
            slower = (rate * y - gap) - max(-gap, 0.0)
            assert faster <= math.sqrt(2 * 0.6 * max(5.0 - behind, 0.0)) + 1e-9
            assert slower <= math.sqrt(2 * 0.6 * max(5.0 + behind, 0.0)) + 1e-9
    widest = max(abs(y) for y in ys)
    if widest > 0.0:
        assert abs(rate) <= math.sqrt(2 * 0.6 / widest * abs(left)) + 1e-12


def test_the_turn_that_just_reaches_the_target_is_never_eased_away() -> None:
    """Where the target lies inside the formation's turn, the leader turns at least at the
    rate that just reaches it, however its wingmen are placed; elsewhere the easing alone."""
    lim = ARDUPLANE._replace(leader_turn_rate=0.0173)
    reaching = 0.0286  # REACH_TIGHTER over the just-reaching 0.026 rad/s
    floor = just_reaching(reaching, lim)
    assert floor == pytest.approx(0.026)
    assert just_reaching(lim.leader_turn_rate, lim) == 0.0
    local_target = np.array([[0.0, 0.0, 0.0], [-100.0, 100.0, 0.0]])
    pos = local_target - [[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]]  # 5 m behind its slot
    speed, active = np.array([22.0, 22.0]), np.ones(2, dtype=np.bool_)
    held = formation_turn_rate(-0.035, math.pi, pos, speed, active, local_target, 1.0, 0.0, lim)
    assert held == 0.0  # the slot outside the turn may not get faster
    reached = formation_turn_rate(-0.035, math.pi, pos, speed, active, local_target, 1.0, 0.0,
                                  lim, floor)  # fmt: skip
    assert reached == pytest.approx(-floor)


def test_near_the_slot_the_speed_laws_are_linear_and_meet_at_the_leaders_speed() -> None:
    gain = math.pi / 6
    assert catching_up_speed(100.0, 0.0, 40.0, gain) == 100.0
    assert falling_back_speed(100.0, 0.0, 10.0, gain) == 100.0
    assert catching_up_speed(100.0, 2.0, 40.0, gain) == pytest.approx(100.0 + 2.0 * gain)
    assert falling_back_speed(100.0, 2.0, 10.0, gain) == pytest.approx(100.0 - 2.0 * gain)
    # Far from it, the ground given back is what the acceleration can take back from the
    # end of the linear piece (a/g² out, at a/g): v² = (a/g)² + 2·a·(d − a/g²).
    linear_m = 10.0 / gain**2
    far = math.sqrt((10.0 / gain) ** 2 + 2 * 10.0 * (500.0 - linear_m))
    assert falling_back_speed(100.0, 500.0, 10.0, gain) == pytest.approx(100.0 - far)


@given(st.floats(0.1, 50.0), st.floats(0.01, 1.0), st.floats(0.0, 5000.0))
def test_the_speed_laws_never_ask_more_than_the_acceleration(
    accel: float, gain: float, d: float
) -> None:
    """Followed exactly, a wingman closing on its slot by the law's excess speed e(d) changes
    speed at e·de/dd: never more than a, on the linear piece, the root and where they meet
    (ArduPlane's 0.6 m/s² at 0.3 /s: min(g·d, √(2·a·d)) asked 1.2 m/s² 13 m out)."""
    step = 1e-4 * max(d, 1.0)
    e0 = catching_up_speed(0.0, d, accel, gain)
    e1 = catching_up_speed(0.0, d + step, accel, gain)
    assert e0 * (e1 - e0) / step <= accel * (1 + 1e-3)
    v0 = 1e4  # the same excess given back ahead of the slot
    assert v0 - falling_back_speed(v0, d, accel, gain) == pytest.approx(e0, rel=1e-9, abs=1e-9)


def _climbing_pair(climb_angle: float) -> Scene:
    """A leader climbing at ``climb_angle`` towards a target far above and ahead, its wingman
    100 m below its slot (150 m behind it in its climbing frame)."""
    mission = Mission.model_validate({
        "limits": {"v_min": 100.0, "v_max": 300.0, "accel": 10.0, "decel": 40.0},
        "target": [60000.0, 0.0, 60000.0],
        "vehicles": [
            {"id": 1, "role": "leader", "position": [0.0, 0.0, 1000.0], "pitch": climb_angle,
             "yaw": 0.0},
            {"id": 2, "role": "wingman", "position": [-150.0 * math.cos(climb_angle),
             -300.0, 1000.0 - 150.0 * math.sin(climb_angle) - 100.0], "pitch": climb_angle,
             "yaw": 0.0, "slot": [-150.0, -300.0, 0.0]},
        ],
    })  # fmt: skip
    scene = scene_from_mission(mission)
    limits = scene.limits._replace(max_climb_angle=climb_angle, max_dive_angle=math.radians(25))
    return replace(scene, limits=limits)


def test_the_leader_leaves_a_wingman_below_its_slot_room_to_climb_into_it() -> None:
    """Climbing at the airframe's limit (+20°), the leader keeps a share of it in hand, as
    it keeps speed in hand (Eq. 24): a wingman 100 m below its slot climbs into it; the
    paper's free pitch is left as it was."""
    scene = _climbing_pair(math.radians(20.0))
    limited = leader_limits(scene.limits)
    assert limited.max_climb_angle == pytest.approx(LEADER_PATH_ANGLE_SHARE * math.radians(20))
    assert limited.max_dive_angle == pytest.approx(LEADER_PATH_ANGLE_SHARE * math.radians(25))
    free = scene.limits._replace(max_climb_angle=math.pi / 2, max_dive_angle=math.pi / 2)
    assert leader_limits(free) == free
    run = advance(scene, 0.01, 3000)
    assert run.trajectory.formed[-1, 1]  # within the target accuracy of its slot after 30 s


def test_a_wingman_round_an_obstacle_does_not_overrun_its_slot() -> None:
    """The five-vehicle line abreast at ArduPlane's scale, each vehicle avoiding on its own
    (``obstacle_passage: "each"``): the slot of the wingman on the leader's right lies
    inside the sphere's keep-out while the leader passes it.  Going round, it gives the
    ground back with its slot behind it (``speed_trend``): once the leader is past the
    sphere's centre, no wingman gets more than 30 m ahead of its slot along the leader's
    track (Eq. 19 alone flew it 55 m ahead, at v_max while the leader waited)."""
    doc = json.loads((EXAMPLES / "arduplane_5.json").read_text())
    mission = Mission.model_validate({**doc, "obstacle_passage": "each"})
    scene = scene_from_mission(mission)
    steps = int(mission.planner.max_time / mission.planner.dt)
    tr = advance(scene, mission.planner.dt, steps, record_every=5).trajectory
    way = scene.target - tr.pos[0, 0]
    passed = int(np.argmax((tr.pos[:, 0] - scene.obstacles.center[0]) @ way > 0.0))
    slots = local_target_points(tr, scene.fleet.slot)
    pitch, yaw = tr.pitch[:, 0], tr.yaw[:, 0]
    u = np.stack([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), np.sin(pitch)], axis=1)
    ahead = np.einsum("knj,kj->kn", tr.pos - slots, u)[passed:, 1:]
    assert ahead.max() <= 30.0, ahead.max(axis=0)


def _planned_share(doc: dict[str, Any], frame: str) -> tuple[float, float]:
    """In formation after forming and the closest two vehicles (m), ``doc`` planned as the
    closed loop plans it at ArduPlane's scale: from 50 m up (after the takeoff), over
    ground, with a 50 m margin on the obstacles' safe distance."""
    doc = {**doc, "formation_frame": frame, "ground": 0.0}
    doc["vehicles"] = [{**v, "position": [*v["position"][:2], 50.0]} for v in doc["vehicles"]]
    mission = Mission.model_validate(doc)
    scene = with_margins(scene_from_mission(mission), 50.0, 0.0)
    steps = int(mission.planner.max_time / mission.planner.dt)
    run = advance(scene, mission.planner.dt, steps, record_every=5)
    tr = run.trajectory
    assert run.arrived
    off = np.linalg.norm(local_target_points(tr, scene.fleet.slot) - tr.pos, axis=-1)
    share = formation_share(tr.t, off <= mission.limits.target_accuracy)
    gaps = np.linalg.norm(tr.pos[:, :, None] - tr.pos[:, None], axis=-1)
    gaps[:, np.arange(len(scene.fleet.ids)), np.arange(len(scene.fleet.ids))] = np.inf
    assert share is not None
    return share, float(gaps.min())


def test_on_the_course_frame_a_dodge_of_the_leader_does_not_break_the_formation() -> None:
    """The three-vehicle line abreast, each vehicle avoiding on its own: round the sphere the
    leader swings 30–45° aside and back.  With its slots in its VCS they swing with it
    and the wingman on its right is flung 245 m across the formation; placed along its
    way to the target while it avoids (``formation_frame: "course"``) the formation is
    in formation at least 15 points more of the flight after forming (measured 0.48 →
    0.71), and no two vehicles come nearer."""
    doc = {**json.loads((EXAMPLES / "arduplane_3.json").read_text()), "obstacle_passage": "each"}
    leader_frame, leader_gap = _planned_share(doc, "leader")
    course, course_gap = _planned_share(doc, "course")
    assert course >= leader_frame + 0.15, (leader_frame, course)
    assert course_gap >= leader_gap


def test_passed_as_a_formation_the_line_abreast_holds_round_the_obstacle() -> None:
    """``obstacle_passage: "formation"``: the leader keeps its farthest slot's distance more
    from the sphere and turns round it as its formation follows, so the line abreast
    passes it whole: in formation at least 30 points more of the flight after forming
    than each vehicle avoiding on its own (measured 0.48 → 0.96), no two nearer."""
    doc = json.loads((EXAMPLES / "arduplane_3.json").read_text())
    each, each_gap = _planned_share({**doc, "obstacle_passage": "each"}, "leader")
    whole, whole_gap = _planned_share({**doc, "obstacle_passage": "formation"}, "leader")
    assert whole >= each + 0.30, (each, whole)
    assert whole_gap >= each_gap


def test_passed_as_a_formation_every_slot_keeps_out_of_the_obstacle() -> None:
    """The pad is the farthest slot's distance, so the slots (not only the wingmen) keep
    the safe distance from the sphere all the way, and the leader keeps the pad more."""
    doc = json.loads((EXAMPLES / "arduplane_5.json").read_text())
    mission = Mission.model_validate({**doc, "obstacle_passage": "formation"})
    scene = scene_from_mission(mission)
    pad = scene.limits.leader_keep_out_pad
    assert pad == pytest.approx(float(np.hypot(200.0, 200.0)))
    assert scene.limits.leader_turn_rate < math.inf  # turns held by default
    run = advance(scene, mission.planner.dt, int(mission.planner.max_time / mission.planner.dt))
    tr = run.trajectory
    assert run.arrived
    centre, radius = scene.obstacles.center[0], scene.obstacles.radius[0]
    keep_out = radius + mission.limits.safe_distance_obstacle
    slots = local_target_points(tr, scene.fleet.slot)[:, 1:]
    assert np.linalg.norm(slots - centre, axis=-1).min() >= keep_out
    assert np.linalg.norm(tr.pos[:, 0] - centre, axis=-1).min() >= keep_out + pad


def test_a_target_inside_the_padded_keep_out_drops_the_pad_for_that_obstacle() -> None:
    """A leader kept the pad out could never reach a target beside an obstacle."""
    target = np.array([0.0, 0.0, 0.0])
    centre = np.array([[300.0, 0.0, 0.0]])
    assert padding(target, centre, 0, 200.0, 141.0, 0.0, 0.0) == 0.0
    assert padding(target, centre, 0, 100.0, 141.0, 0.0, 0.0) == 141.0


def test_a_target_inside_the_pads_reach_at_the_formation_turn_drops_the_pad() -> None:
    """The pad repels the leader wherever it is within the influence radius of the padded
    keep-out at its formation's turn, which reaches further than the keep-out: a target
    there was circled for ever.  Keep-out 875 m, pad 283 m, the turn 1,571 m: the reach is
    2,231 m (and grows by what comes ``beyond`` it)."""
    centre = np.array([[0.0, 0.0, 0.0]])
    reach = math.sqrt((875.0 + 283.0 + 1571.0) ** 2 - 1571.0**2)
    inside = np.array([reach - 1.0, 0.0, 0.0])
    outside = np.array([reach + 1.0, 0.0, 0.0])
    assert padding(inside, centre, 0, 875.0, 283.0, 1571.0, 0.0) == 0.0
    assert padding(outside, centre, 0, 875.0, 283.0, 1571.0, 0.0) == 283.0
    assert padding(outside, centre, 0, 875.0, 283.0, 1571.0, 2.0) == 0.0


def test_table3_passed_as_a_formation_forms_early_and_reaches_its_target() -> None:
    """The paper's Table 3 with ``obstacle_passage: "formation"``: its target lies 1,803 m
    from the last sphere's centre, outside the padded keep-out (1,158 m) but inside the
    pad's reach at the formation's turn; the leader circled it 325–800 m off for the whole
    300 s.  Now it arrives, and the formation forms before the spheres, not in the last
    seconds (the paper's way: 65.9 s of 68.3 s)."""
    doc = json.loads((EXAMPLES / "paper_table3.json").read_text())
    mission = Mission.model_validate({**doc, "obstacle_passage": "formation"})
    scene = scene_from_mission(mission)
    run = advance(scene, mission.planner.dt, int(mission.planner.max_time / mission.planner.dt))
    tr = run.trajectory
    assert run.arrived
    assert tr.t[-1] < 100.0
    off = np.linalg.norm(local_target_points(tr, scene.fleet.slot) - tr.pos, axis=-1)
    formed = formation_time(tr.t, off <= mission.limits.target_accuracy)
    assert formed is not None
    assert formed < 40.0


def test_passed_as_a_formation_the_leader_pitches_no_faster_than_its_formation_turns() -> None:
    """A slot |x| behind the leader rises or sinks at ω_θ·|x| as it pitches: round the
    sphere the leader's pitch rate is held to its formation's turn rate as its yaw rate
    is (``passing_limits``).  In free space the sphere's centre lies above the line
    abreast, and at the full pitch rate its leader dived under it and broke the formation
    (in formation 0.62 of the flight after forming; 0.81 held)."""
    mission = load_mission_file(EXAMPLES / "arduplane_3.json")
    assert mission.obstacle_passage == "formation"
    scene = scene_from_mission(mission)
    run = advance(scene, mission.planner.dt, int(mission.planner.max_time / mission.planner.dt))
    tr = run.trajectory
    passing = tr.avoiding[:-1, 0] & tr.avoiding[1:, 0]
    assert passing.sum() > 100
    pitch_rate = np.abs(np.diff(tr.pitch[:, 0])) / np.diff(tr.t)
    assert pitch_rate[passing].max() <= scene.limits.leader_turn_rate * (1 + 1e-6)
    assert pitch_rate[passing].max() > 0.5 * scene.limits.leader_turn_rate  # it does pitch


def test_a_target_inside_the_formations_turn_is_turned_onto_just_faster_than_reaches_it() -> None:
    """The V of five turns on 1,265 m (1°/s at 21.9 m/s); a target 300 m ahead and 800 m to
    the side lies inside that turn.  The leader turns onto it 10 % faster than the circle
    through it (radius (a² + b²) / 2|b| = 456 m), not at the airframe's 17°/s; a target
    outside keeps the formation's rate, and a leader whose turns are not held gets none."""
    mission = load_mission_file(EXAMPLES / "arduplane_5.json")
    lim = scene_from_mission(mission).limits
    v, held = lim.leader_cruise_speed, lim.leader_turn_rate
    rate = reaching_turn_rate(0.0, 0.0, 1.0, 0.0, v, lim, 300.0, 800.0)
    assert rate == pytest.approx(1.1 * v / ((300.0**2 + 800.0**2) / 1600.0))
    assert held < rate < lim.max_yaw_rate
    assert not inside_turn(0.0, 0.0, 1.0, 0.0, v, rate, 300.0, 800.0)  # it reaches it
    assert inside_turn(0.0, 0.0, 1.0, 0.0, v, rate / 1.2, 300.0, 800.0)  # slower does not
    assert reaching_turn_rate(0.0, 0.0, 1.0, 0.0, v, lim, 3000.0, 800.0) == held
    free = lim._replace(leader_turn_rate=math.inf)
    assert reaching_turn_rate(0.0, 0.0, 1.0, 0.0, v, free, 300.0, 800.0) == 0.0
    # at the cruise speed it makes for, if it is slower now
    assert reaching_turn_rate(0.0, 0.0, 1.0, 0.0, v - 5.0, lim, 300.0, 800.0) == rate


def test_the_way_to_a_target_is_the_turn_onto_it_then_the_line() -> None:
    """``way_clear``: heading north from the origin, a turn of 500 m onto a target 2 km
    east keeps 500 m from the turn's centre (500, 0) and leaves the circle where the line
    to the target touches it, at (667, 471) (acos(1/3) round from the target's bearing);
    a point on the arc, or on that line, is not clear; one behind the vehicle is; a
    target inside the turn is never headed at."""
    assert way_clear(0.0, 0.0, 0.0, 1.0, 500.0, 2000.0, 0.0, 500.0, 0.0, 400.0)
    assert not way_clear(0.0, 0.0, 0.0, 1.0, 500.0, 2000.0, 0.0, 500.0, 450.0, 100.0)
    assert not way_clear(0.0, 0.0, 0.0, 1.0, 500.0, 2000.0, 0.0, 1333.0, 236.0, 10.0)
    assert way_clear(0.0, 0.0, 0.0, 1.0, 500.0, 2000.0, 0.0, 1333.0, 336.0, 90.0)
    assert way_clear(0.0, 0.0, 0.0, 1.0, 500.0, 2000.0, 0.0, -300.0, 0.0, 250.0)
    assert not way_clear(0.0, 0.0, 0.0, 1.0, 500.0, 200.0, 100.0, 0.0, -5000.0, 10.0)
    # straight on to a target ahead: clear by the point's distance from the line
    assert way_clear(0.0, 0.0, 0.0, 1.0, 500.0, 0.0, 1000.0, 200.0, 500.0, 150.0)
    assert not way_clear(0.0, 0.0, 0.0, 1.0, 500.0, 0.0, 1000.0, 100.0, 500.0, 150.0)


def test_held_to_the_edge_of_an_influence_a_target_can_fall_inside_the_turn() -> None:
    """``turn_missed_ahead``: heading north from the origin inside a sphere of 1 km round
    (0, 500, 0), the vehicle leaves it at (0, 1500); a target 300 m east of that point
    lies inside a 1 km turn there, one 2.5 km east does not, nor one 2 km beyond it
    unless the vehicle looks 1.5 km further on; outside the sphere the point is the
    vehicle's own."""
    args = (0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 500.0, 0.0, 1000.0, 0.0, 20.0, 0.02)
    assert turn_missed_ahead(*args, 300.0, 1500.0)
    assert not turn_missed_ahead(*args, 2500.0, 1500.0)
    assert not turn_missed_ahead(*args, 300.0, 3500.0)  # far ahead: reached
    led = (0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 500.0, 0.0, 1000.0, 1500.0, 20.0, 0.02)
    assert turn_missed_ahead(*led, 300.0, 3000.0)  # 1.5 km further on, it would be
    outside = (0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -5000.0, 0.0, 1000.0, 0.0, 20.0, 0.02)
    assert turn_missed_ahead(*outside, 300.0, 0.0)
    assert not turn_missed_ahead(*outside, 300.0, 1500.0)


@pytest.mark.parametrize(
    ("name", "share_min", "gap_before"),
    [("arduplane_5", 0.99, 93.5), ("arduplane_formation_takeoff_5", 0.92, 98.0),
     ("arduplane_3", 0.975, 133.9), ("arduplane_formation_takeoff_3", 0.95, 133.9)],
)  # fmt: skip
def test_passed_as_a_formation_the_leader_turns_back_once_its_way_is_clear(
    name: str, share_min: float, gap_before: float
) -> None:
    """Repelled until it left the padded keep-out's influence radius (1.17 km at the V of
    five's turn), the leader flew 1.2 km aside and its target then lay inside its
    formation's turn.  Let go once its way to the target clears the padded keep-out, where
    holding on would miss the target, and turned as the wingmen keeping station follow
    (``formation_turn_rate``), the V of five is in formation 1.00 and 0.93 of the flight
    after forming (planned the same way: 0.67 and 0.67 holding on; 0.86 and 0.83 let go
    once the way cleared it by one more pad, its turns held by the formed wingmen alone);
    the three-vehicle formations, whose target lies outside their turn at the edge, hold
    on and keep 0.98 and 0.95 (0.97 and 0.95); no two vehicles come nearer than before
    (``gap_before``, m)."""
    share, gap = _planned_share(json.loads((EXAMPLES / f"{name}.json").read_text()), "leader")
    assert share >= share_min
    assert gap >= gap_before

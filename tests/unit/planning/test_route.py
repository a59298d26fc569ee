"""Routes (gcs_ppf.planning.route) and turning in formation (gcs_ppf.planning.turns)."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gcs_ppf.mission import MissionError, load_mission, load_mission_file
from gcs_ppf.offline.plan import plan_mission
from gcs_ppf.planning.metrics import local_target_points
from gcs_ppf.planning.planner import Trajectory
from gcs_ppf.planning.ppf.primitives import inside_turn, reaching_turn_rate
from gcs_ppf.planning.route import (
    TURN_POINT_WIDER,
    Leg,
    Loitering,
    leg_flown,
    legs,
    loiter_point,
    on_circle,
    onto_target,
    turn_point,
)
from gcs_ppf.planning.scene import FloatArray, scene_from_mission
from gcs_ppf.planning.turns import (
    formation_turn_limits,
    held_speed_range,
    slot_turn_rates,
    turn_envelope,
)
from tests.conftest import ARDUPLANE

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"


def route_doc(route: list[dict[str, Any]], target: list[float]) -> dict[str, Any]:
    doc: dict[str, Any] = json.loads((EXAMPLES / "arduplane_route_3.json").read_text())
    doc["route"], doc["target"] = route, target
    return doc


def test_the_legs_run_waypoint_to_waypoint_and_the_last_has_no_finish_line() -> None:
    m = load_mission_file(EXAMPLES / "arduplane_route_3.json")
    route = legs(m)
    assert [leg.index for leg in route] == [0, 1, 2]
    assert np.allclose(route[0].start_m, m.leader.position)
    assert np.allclose(route[1].start_m, m.route[0].position)
    assert np.allclose(route[2].end_m, m.target)
    assert [leg.final for leg in route] == [False, False, True]
    assert route[2].radius_m == m.limits.target_accuracy
    assert np.allclose(route[0].finish_normal, [0.0, 1.0, 0.0])  # north, then east
    assert np.allclose(route[1].finish_normal, [1.0, 0.0, 0.0])


def test_a_leg_is_flown_within_its_radius_or_across_its_finish_line() -> None:
    leg = legs(load_mission_file(EXAMPLES / "arduplane_route_3.json"))[0]  # to (0, 2000)
    p = np.array
    assert leg_flown(leg, None, p([30.0, 1990.0, 150.0]))
    assert not leg_flown(leg, None, p([300.0, 1990.0, 150.0]))
    # passed 300 m wide: counted once it crosses the line through the waypoint
    assert not leg_flown(leg, p([300.0, 1980.0, 150.0]), p([300.0, 1999.0, 150.0]))
    assert leg_flown(leg, p([300.0, 1990.0, 150.0]), p([300.0, 2010.0, 150.0]))
    # stepping over the acceptance sphere between two reports counts
    assert leg_flown(leg, p([0.0, 1900.0, 150.0]), p([0.0, 2100.0, 150.0]))
    final = legs(load_mission_file(EXAMPLES / "arduplane_route_3.json"))[-1]
    assert not leg_flown(final, p([300.0, 2600.0, 150.0]), p([-300.0, 2700.0, 150.0]))


def test_a_waypoint_inside_an_obstacle_or_below_the_ground_is_named() -> None:
    doc = route_doc([{"position": [0.0, 1000.0, 150.0]}], [0.0, 3000.0, 150.0])
    doc["obstacles"] = [{"center": [0.0, 1000.0, 150.0], "radius": 100.0}]
    with pytest.raises(MissionError) as e:
        load_mission(json.dumps(doc))
    assert e.value.field == "route[0].position"
    doc["obstacles"], doc["ground"] = [], 140.0
    doc["vehicles"] = [{**v, "position": [v["position"][0], v["position"][1], 170.0]}
                       for v in doc["vehicles"]]  # fmt: skip
    with pytest.raises(MissionError) as e:
        load_mission(json.dumps(doc))
    assert e.value.field == "route[0].position"
    doc = route_doc([{"position": [0.0, 1000.0, 150.0], "acceptance_radius": -1}], [0, 3000, 150])
    with pytest.raises(MissionError) as e:
        load_mission(json.dumps(doc))
    assert e.value.field == "route[0].acceptance_radius"


def test_a_document_without_a_route_is_the_papers_leader() -> None:
    m = load_mission_file(EXAMPLES / "paper_table3.json")
    assert m.route == []
    assert not m.holds_turns
    lim = scene_from_mission(m).limits
    assert lim.leader_cruise_speed == math.inf
    assert lim.leader_turn_rate == math.inf
    assert load_mission_file(EXAMPLES / "arduplane_route_3.json").holds_turns


def slot_speeds(v: float, omega: float, slots: FloatArray) -> FloatArray:
    """Speeds of the slots of a leader flying at v and turning at omega, by differentiating
    their positions over a short time (independent of the closed form in turns.py)."""
    h = 1e-4
    out = []
    for s in slots:

        def at(t: float, s: FloatArray = s) -> FloatArray:
            if omega == 0.0:
                centre_pos, psi = np.array([v * t, 0.0]), 0.0
            else:
                psi = omega * t
                centre_pos = np.array([v / omega * math.sin(psi), v / omega * (1 - math.cos(psi))])
            c, sn = math.cos(psi), math.sin(psi)
            where: FloatArray = centre_pos + np.array([c * s[0] - sn * s[1], sn * s[0] + c * s[1]])
            return where

        out.append(float(np.linalg.norm(at(h) - at(-h))) / (2 * h))
    return np.array(out)


@given(
    st.lists(st.tuples(st.floats(-300, 300), st.floats(-300, 300)), min_size=1, max_size=8),
    st.floats(16.0, 28.0),
)
def test_every_slot_moves_within_the_speed_range_at_the_turn_rate_allowed(
    offsets: list[tuple[float, float]], v: float
) -> None:
    slots = np.array([[x, y, 0.0] for x, y in offsets])
    omega = float(slot_turn_rates(np.array([v]), slots, ARDUPLANE)[0])
    assert 0.0 <= omega <= ARDUPLANE.max_yaw_rate
    for turn in (omega, -omega):
        speeds = slot_speeds(v, turn, slots)
        assert speeds.max() <= ARDUPLANE.v_max + 1e-3
        assert speeds.min() >= ARDUPLANE.v_min - 1e-3
    # the roll-in: the slot's change of speed is what the wingman gains in the accuracy
    lateral = np.abs(slots[:, 1]).max()
    assert omega * lateral <= math.sqrt(2 * 0.6 * 10.0) + 1e-9


def test_the_cruise_speed_is_where_the_formation_turns_fastest() -> None:
    slots = np.array([[-100.0, 100.0, 0.0], [-100.0, -100.0, 0.0]])
    env = turn_envelope(slots, ARDUPLANE)
    speeds = np.linspace(16.0, 28.0, 97)
    assert env.turn_rate_rad_s >= slot_turn_rates(speeds, slots, ARDUPLANE).max() - 1e-9
    assert 16.0 < env.cruise_speed_m_s < 28.0


def test_a_held_leader_within_its_speed_range_leaves_every_slot_its_turn() -> None:
    slots = np.array([[-100.0, 100.0, 0.0], [-100.0, -100.0, 0.0]])
    lim = formation_turn_limits(ARDUPLANE, slots)
    held = held_speed_range(slots, lim)
    assert held is not None
    low, high = held
    assert 16.0 < low <= lim.leader_cruise_speed <= high < 28.0
    for v, follows in ((low, True), (high, True), (low - 0.1, False), (high + 0.1, False)):
        omega = float(slot_turn_rates(np.array([v]), slots, lim)[0])
        assert (omega >= lim.leader_turn_rate - 1e-9) is follows
    assert held_speed_range(slots, ARDUPLANE) is None  # not turning in formation


def yaw_rates(tr: Trajectory) -> FloatArray:
    dyaw = np.angle(np.exp(1j * np.diff(tr.yaw, axis=0)))
    rates: FloatArray = np.abs(dyaw) / np.diff(tr.t)[:, None]
    return rates


@pytest.mark.parametrize("name", ["arduplane_route_3.json", "paper_table3_route.json"])
def test_the_route_examples_are_flown_in_order_safely(name: str) -> None:
    m = load_mission_file(EXAMPLES / name)
    run = plan_mission(m)
    assert run.arrived
    times = run.metrics["waypoint_times_s"]
    assert len(times) == len(m.route)
    assert times == sorted(times)
    assert run.metrics["collisions"] == 0
    assert run.metrics["min_separation_m"] >= m.limits.safe_distance_uav
    clearance = run.metrics["min_obstacle_clearance_m"]
    assert clearance is None or clearance >= m.limits.safe_distance_obstacle
    # each waypoint was passed within its radius or across its finish line, in order
    tr, lim = run.trajectory, run.scene.limits
    for leg, t in zip(legs(m), times, strict=False):
        k = int(np.searchsorted(tr.t, t))
        assert leg_flown(leg, tr.pos[k - 1, 0], tr.pos[k, 0])
    # the leader, following its target, turns no faster than its formation can follow,
    # unless the target lies inside that turn: then no faster than the turn onto it
    ends = [leg.end_m for leg in legs(m)]
    leg_of = np.searchsorted(np.array(times), tr.t[:-1], side="right")
    onto = np.array([
        reaching_turn_rate(p[0], p[1], math.cos(y), math.sin(y), v, lim, ends[k][0], ends[k][1])
        for p, y, v, k in zip(tr.pos[:-1, 0], tr.yaw[:-1, 0], tr.speed[:-1, 0], leg_of,
                              strict=True)
    ])  # fmt: skip
    free = ~tr.avoiding[:-1, 0] & ~tr.avoiding[1:, 0]
    assert (free & (onto <= lim.leader_turn_rate)).mean() > 0.5
    allowed = np.maximum(lim.leader_turn_rate, onto)
    assert (yaw_rates(tr)[free, 0] <= allowed[free] * (1 + 1e-6)).all()


def test_formed_on_the_arduplane_route_the_wingmen_stay_near_their_slots_in_the_turns() -> None:
    """The formation's turn limits at ArduPlane's scale: every wingman within 2x the target
    accuracy of its slot through both turns (13.4 m measured; 16.2 m matching the leader's
    speed instead of the slot's; 25-33 m with the speed and turn-rate limits alone; 180 m
    for the paper's leader)."""
    m = load_mission_file(EXAMPLES / "arduplane_route_3.json")
    run = plan_mission(m)
    tr = run.trajectory
    error = np.linalg.norm(tr.pos - local_target_points(tr, run.scene.fleet.slot), axis=-1)
    assert error[:, 1:].max() <= 2 * m.limits.target_accuracy


@settings(max_examples=8, deadline=None)
@given(
    st.lists(
        st.tuples(st.floats(-2500, 2500), st.floats(500, 4000), st.floats(80, 300)),
        min_size=1, max_size=3,
    ),
)  # fmt: skip
def test_any_route_is_flown_waypoint_by_waypoint_within_the_limits(
    points: list[tuple[float, float, float]],
) -> None:
    route = [{"position": list(p), "acceptance_radius": 60.0} for p in points]
    doc = route_doc(route, [0.0, 4500.0, 150.0])
    doc["planner"]["max_time"] = 2400.0
    m = load_mission(json.dumps(doc))
    run = plan_mission(m)
    assert run.arrived
    assert len(run.metrics["waypoint_times_s"]) == len(points)
    assert run.metrics["collisions"] == 0
    assert run.metrics["min_separation_m"] >= m.limits.safe_distance_uav
    lim = m.limits
    assert run.metrics["max_speed_m_s"] <= lim.v_max + 1e-9
    assert run.metrics["min_speed_m_s"] >= lim.v_min - 1e-9
    assert run.metrics["max_yaw_rate_rad_s"] <= lim.max_yaw_rate * (1 + 1e-6)


def test_a_point_inside_the_turn_circle_is_one_no_turn_at_that_rate_reaches() -> None:
    # heading +x at 20 m/s turning at 0.05 rad/s: circles of 400 m radius centred 400 m
    # to the left (0, 400) and to the right (0, -400)
    assert inside_turn(0.0, 0.0, 1.0, 0.0, 20.0, 0.05, 100.0, 300.0)
    assert inside_turn(0.0, 0.0, 1.0, 0.0, 20.0, 0.05, 100.0, -300.0)
    assert not inside_turn(0.0, 0.0, 1.0, 0.0, 20.0, 0.05, 2000.0, 300.0)
    assert not inside_turn(0.0, 0.0, 1.0, 0.0, 20.0, 0.05, -900.0, 0.0)  # behind, outside both
    assert not inside_turn(0.0, 0.0, 1.0, 0.0, 20.0, math.inf, 100.0, 300.0)


def loiter_leg(clockwise: bool = True, turns: float | None = 1.0) -> Leg:
    time_s = None if turns is not None else 30.0
    doc = route_doc(
        [
            {
                "position": [0.0, 2000.0, 150.0],
                "loiter": {"radius_m": 700.0, "turns": turns, "time_s": time_s,
                           "clockwise": clockwise},
            }
        ],
        [0.0, 4000.0, 150.0],
    )  # fmt: skip
    return legs(load_mission(json.dumps(doc)))[0]


def test_the_point_a_loiter_steers_to_lies_ahead_on_its_circle() -> None:
    """Clockwise seen from above: from due east of the centre the point lies 30° round
    towards the south; anticlockwise, towards the north; at the centre's altitude."""
    for clockwise, sign in ((True, -1.0), (False, 1.0)):
        leg = loiter_leg(clockwise)
        c = leg.end_m
        p = loiter_point(leg, c + np.array([650.0, 0.0, -40.0]))
        a = math.radians(30.0) * sign
        assert np.allclose(p, c + 700.0 * np.array([math.cos(a), math.sin(a), 0.0]))


def test_a_loiter_counts_the_turns_swept_on_its_circle_only() -> None:
    """Round the circle clockwise: a full turn counts 2π and ends a one-turn loiter;
    flown the other way it counts back; nothing counts off the circle."""
    leg = loiter_leg(clockwise=True)
    c = leg.end_m
    ring = [c + 700.0 * np.array([math.cos(-a), math.sin(-a), 0.0])
            for a in np.linspace(0.0, 2.0 * math.pi, 73)]  # fmt: skip
    going = Loitering(ring[0]).on(leg, np.array(ring[1:]), 50.0)
    assert going.swept == pytest.approx(2.0 * math.pi)
    assert going.began_s == 50.0
    assert leg.loiter is not None
    assert going.flown(leg.loiter, 50.0)
    back = Loitering(ring[-1]).on(leg, np.array(ring[::-1][1:]), 50.0)
    assert back.swept == pytest.approx(-2.0 * math.pi)
    assert not back.flown(leg.loiter, 50.0)
    inside = Loitering(c).on(leg, np.array([0.3 * (r - c) + c for r in ring]), 50.0)
    assert inside.swept == 0.0
    assert inside.began_s is None


def test_a_timed_loiter_counts_from_when_the_leader_came_onto_its_circle() -> None:
    leg = loiter_leg(turns=None)
    assert leg.loiter is not None
    c = leg.end_m
    far = Loitering(c + np.array([0.0, -2000.0, 0.0])).on(
        leg, (c + np.array([0.0, -1500.0, 0.0]))[None], 10.0
    )
    assert far.began_s is None
    assert not far.flown(leg.loiter, 100.0)
    on = far.on(leg, (c + np.array([0.0, -700.0, 0.0]))[None], 20.0)
    assert on.began_s == 20.0
    assert not on.flown(leg.loiter, 49.0)
    assert on.flown(leg.loiter, 50.0)


def test_a_loiter_is_flown_no_tighter_than_the_formation_turns() -> None:
    """The ArduPlane formation holds its turns at 632 m at its cruise speed: a 400 m loiter
    is flown on that circle, a 700 m one on its own."""
    doc = json.loads((EXAMPLES / "arduplane_route_loiter_3.json").read_text())
    m = load_mission(json.dumps(doc))
    held = turn_envelope(
        np.array([w.slot for w in m.wingmen], dtype=float), scene_from_mission(m).limits
    ).turn_radius_m
    doc["route"][0]["loiter"]["radius_m"] = 400.0
    assert legs(load_mission(json.dumps(doc)))[0].loiter_radius_m == pytest.approx(held)
    doc["route"][0]["loiter"]["radius_m"] = 700.0
    assert legs(load_mission(json.dumps(doc)))[0].loiter_radius_m == 700.0


def test_a_loiter_needs_turns_or_time_and_a_radius_the_leader_can_turn() -> None:
    base = {"position": [0.0, 2000.0, 150.0]}
    for loiter, field in (
        ({"radius_m": 700.0}, "turns"),
        ({"radius_m": 700.0, "turns": 1, "time_s": 20}, "turns"),
        ({"radius_m": 20.0, "turns": 1}, "route[0].loiter.radius_m"),
    ):
        with pytest.raises(MissionError, match=re.escape(field)):
            load_mission(json.dumps(route_doc([{**base, "loiter": loiter}], [0.0, 4000.0, 150.0])))


def test_a_waypoint_inside_the_turn_is_reached_from_a_turn_point_straight_on() -> None:
    # heading +x from the origin, turns of 400 m: circles centred at (0, ±400)
    point = turn_point(np.array([100.0, 300.0, 150.0]), np.zeros(3), 0.0, 400.0)
    assert point is not None
    assert point[1] == pytest.approx(0.0)  # straight on …
    assert point[2] == 150.0  # … at the waypoint's height
    centre = np.array([point[0], 400.0])  # the left turn from there
    assert math.dist(centre, (100.0, 300.0)) == pytest.approx((1 + TURN_POINT_WIDER) * 400.0)
    right = turn_point(np.array([100.0, -300.0, 0.0]), np.zeros(3), 0.0, 400.0)
    assert right is not None
    assert right[0] == pytest.approx(point[0])  # either side alike
    assert turn_point(np.array([2000.0, 300.0, 0.0]), np.zeros(3), 0.0, 400.0) is None
    assert turn_point(np.array([-900.0, 0.0, 0.0]), np.zeros(3), 0.0, 400.0) is None


def test_the_turn_point_is_kept_until_passed_and_only_where_turns_are_held() -> None:
    held = Leg(0, np.zeros(3), np.array([100.0, 300.0, 0.0]), 10.0, np.zeros(3),
               turn_rate_rad_s=0.05)  # fmt: skip
    leg = onto_target(held, np.zeros(3), 0.0, 20.0)  # turns of 400 m
    assert leg.turn_point_m is not None
    assert np.array_equal(leg.aim_m, leg.turn_point_m)
    along = leg.turn_point_m[0]
    turned = onto_target(leg, np.array([along - 1.0, 5.0, 0.0]), 0.3, 20.0)
    assert turned is leg  # not passed yet, whatever the heading now
    passed = onto_target(leg, np.array([along + 1.0, 0.0, 0.0]), 0.0, 20.0)
    assert passed.turn_point_m is None
    assert np.array_equal(passed.aim_m, held.end_m)
    # Past its point, a leader 20 % faster (its turn 20 % wider: the waypoint inside it
    # again) turns onto the waypoint: no second point on the leg.
    past = np.array([along + 1.0, 0.0, 0.0])
    assert turn_point(held.end_m, past, 0.0, 480.0) is not None  # a fresh leg: out again
    assert onto_target(passed, past, 0.0, 24.0).turn_point_m is None
    free = Leg(0, np.zeros(3), np.array([100.0, 300.0, 0.0]), 10.0, np.zeros(3))
    assert onto_target(free, np.zeros(3), 0.0, 20.0) is free  # turns as it can
    assert all(leg.turn_rate_rad_s == math.inf for leg in legs(load_mission_file(
        EXAMPLES / "arduplane_5.json")))  # fmt: skip


def test_the_loiter_routes_last_turn_is_flown_in_formation() -> None:
    """The target lies 1 km on from the last waypoint, inside the 633 m turn the V follows:
    the leader flies out to a turn point and turns back onto it with its formation (every
    wingman within 2x the target accuracy of its slot; 46-115 m turning onto it at 0.3
    rad/s, as before)."""
    m = load_mission_file(EXAMPLES / "arduplane_route_loiter_3.json")
    run = plan_mission(m)
    assert run.arrived
    tr = run.trajectory
    last = int(np.searchsorted(tr.t, run.metrics["waypoint_times_s"][-1]))
    error = np.linalg.norm(tr.pos - local_target_points(tr, run.scene.fleet.slot), axis=-1)
    assert error[last:, 1:].max() <= 2 * m.limits.target_accuracy


@pytest.mark.parametrize("name", ["arduplane_route_loiter_3.json", "arduplane_route_uturn_3.json"])
def test_the_straight_legs_after_the_turns_are_flown_in_formation(name: str) -> None:
    """The leader eases its turns in and out as its wingmen's speeds follow
    (``formation_turn_rate``): where its course changes slower than 0.5°/s, every wingman
    is within the target accuracy of its slot (3.2 and 7.2 m; 13.0 and 9.2 m with the turns
    started and stopped at once, the wingmen settling after each)."""
    m = load_mission_file(EXAMPLES / name)
    run = plan_mission(m)
    tr = run.trajectory
    error = np.linalg.norm(tr.pos - local_target_points(tr, run.scene.fleet.slot), axis=-1)
    keep = np.concatenate([[True], np.diff(tr.t) > 1e-9])
    t, worst, course = tr.t[keep], error[keep, 1:].max(axis=1), np.unwrap(tr.yaw[keep, 0])
    second = np.searchsorted(t, t + 1.0).clip(max=t.size - 1)
    straight = np.abs(course[second] - course) < math.radians(0.5) * (t[second] - t)
    assert straight[t < t[-1] - 1.0].mean() > 0.25
    assert worst[straight].max() <= m.limits.target_accuracy


def test_the_loiter_example_circles_its_waypoint_in_formation() -> None:
    """Offline: the leader sweeps its one turn round the waypoint on the circle (within
    ``ON_CIRCLE`` of its radius), in formation the whole loiter, then flies on."""
    m = load_mission_file(EXAMPLES / "arduplane_route_loiter_3.json")
    run = plan_mission(m)
    assert run.arrived
    tr = run.trajectory
    leg = legs(m)[0]
    end = int(np.searchsorted(tr.t, run.metrics["waypoint_times_s"][0]))
    flown = Loitering(tr.pos[0, 0]).on(leg, tr.pos[1 : end + 1, 0], 0.0)
    assert 2.0 * math.pi <= flown.swept <= 2.0 * math.pi + 0.2
    began = int(np.argmax([on_circle(leg, p) for p in tr.pos[:, 0]]))
    error = np.linalg.norm(tr.pos - local_target_points(tr, run.scene.fleet.slot), axis=-1)
    in_formation = error[began:end, 1:].max(axis=1) <= m.limits.target_accuracy
    assert in_formation.mean() >= 0.9

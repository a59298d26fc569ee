"""The speed reference: each tick plans from the speed the previous plan had reached by now,
kept within a bound of the measured speed."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from gcs_ppf.guidance.online import Guidance, VehicleState
from gcs_ppf.guidance.speed_reference import (
    HOLD_RESERVE_M_S,
    REFERENCE_BOUND_M_S,
    REFERENCE_COURSE_BOUND_RAD,
    SPEED_COMMAND_LEAD_S,
    SpeedPlan,
    follows_speed_plan,
    formation_holds,
    leader_held,
    reference_course,
    reference_speed,
    reference_states,
    speed_to_command,
)
from gcs_ppf.planning.scene import FloatArray


def _plan(start_m_s: float, accel: float, top_m_s: float, at_s: float) -> SpeedPlan:
    """A toy plan of one vehicle (id 1): from ``start_m_s`` at ``accel`` up to ``top_m_s``
    over 3 s, recorded every 0.02 s, made at mission time ``at_s``."""
    t = np.concatenate([[0.0], np.arange(1, 151) * 0.02])
    speed = np.minimum(start_m_s + accel * t, top_m_s)[:, None]
    return SpeedPlan((1,), t, speed, at_s)


def test_the_plan_is_read_at_the_time_elapsed_since_it_was_made() -> None:
    plan = _plan(20.0, 0.6, 28.0, at_s=10.0)
    assert plan.speed_at(1, 10.0) == pytest.approx(20.0)
    assert plan.speed_at(1, 10.5) == pytest.approx(20.3)
    assert plan.speed_at(1, 10.51) == pytest.approx(20.306)  # between records
    assert plan.speed_at(1, 9.9) is None  # before it
    assert plan.speed_at(1, 13.5) is None  # past its end: not a reference any more
    assert plan.speed_at(2, 10.5) is None  # not in it


def test_the_reference_is_kept_within_the_bound_of_the_measured_speed() -> None:
    assert reference_speed(None, 23.0) == 23.0
    assert reference_speed(24.0, 23.0) == 24.0
    assert reference_speed(30.0, 23.0) == 23.0 + REFERENCE_BOUND_M_S
    assert reference_speed(16.0, 23.0) == 23.0 - REFERENCE_BOUND_M_S
    assert reference_speed(16.0, 23.0, bound_m_s=10.0) == 16.0


def test_only_the_speed_is_replaced() -> None:
    measured = VehicleState((1.0, 2.0, 3.0), 0.1, 0.2, 22.0, 0.05)
    out = reference_states({1: measured, 2: measured}, _plan(23.0, 0.6, 28.0, 0.0), 0.0)
    assert out[1] == VehicleState((1.0, 2.0, 3.0), 0.1, 0.2, 23.0, 0.05)
    assert out[2] == measured  # not in the plan: as measured
    assert reference_states({1: measured}, None, 0.0)[1] == measured


def _turning_plan(start_rad: float, rate_rad_s: float, at_s: float) -> SpeedPlan:
    """``_plan`` at a steady speed with vehicle 1's course turning from ``start_rad`` at
    ``rate_rad_s``, wrapped to (−π, π] as the planner records it."""
    plan = _plan(22.0, 0.0, 22.0, at_s)
    course = np.remainder(start_rad + rate_rad_s * plan.t_s + math.pi, math.tau) - math.pi
    return replace(plan, course_rad=course[:, None])


def test_the_course_reached_is_read_across_the_wrap() -> None:
    plan = _turning_plan(math.pi - 0.01, 0.1, at_s=5.0)  # crosses ±π after 0.1 s
    reached = plan.course_at(1, 5.2)
    assert reached is not None
    assert math.remainder(reached - (math.pi + 0.01), math.tau) == pytest.approx(0.0, abs=1e-9)
    assert plan.course_at(1, 4.9) is None
    assert plan.course_at(2, 5.2) is None
    assert _plan(22.0, 0.0, 22.0, 5.0).course_at(1, 5.2) is None  # no courses planned


def test_the_course_reference_is_kept_within_its_bound_of_the_course_flown() -> None:
    bound = REFERENCE_COURSE_BOUND_RAD
    assert reference_course(None, 1.0) == 1.0
    assert reference_course(1.02, 1.0) == pytest.approx(1.02)  # within 2°
    assert reference_course(1.5, 1.0) == pytest.approx(1.0 + bound)
    assert reference_course(0.5, 1.0) == pytest.approx(1.0 - bound)
    # across ±π: 0.02 rad to the left of a course of 3.13 rad is −3.13 rad
    assert reference_course(-math.pi + 0.01, math.pi - 0.01) == pytest.approx(-math.pi + 0.01)
    assert reference_course(-math.pi + 0.5, math.pi - 0.02) == pytest.approx(
        math.remainder(math.pi - 0.02 + bound, math.tau)
    )


def test_only_the_leaders_course_is_planned_from_its_reference() -> None:
    plan = _turning_plan(0.5, 0.1, at_s=0.0)
    plan = replace(
        plan,
        ids=(1, 2),
        speed_m_s=np.hstack([plan.speed_m_s] * 2),
        course_rad=np.hstack([plan.course_rad] * 2),  # type: ignore[list-item]
    )
    flown = VehicleState((1.0, 2.0, 3.0), 0.1, 0.51, 22.0, 0.05)
    out = reference_states({1: flown, 2: flown}, plan, 0.3, leader_id=1)
    assert out[1].yaw_rad == pytest.approx(0.53)
    assert out[1].course_ahead_rad == pytest.approx(0.02)
    assert out[1].pos_m == flown.pos_m
    assert out[2] == flown  # a wingman: its course as flown
    assert reference_states({1: flown}, plan, 0.3)[1] == flown  # no leader named


def _flown_accel(use_reference: bool, tau_s: float = 0.25) -> float:
    """Mean acceleration (m/s²) from its second to its fourth second of an aircraft tracking
    its airspeed demand as a first-order lag ``tau_s``, commanded every 0.1 s the speed
    planned 1 s on by a plan that speeds up at 0.6 m/s² from the speed it starts at
    (measured, or the reference)."""
    v, t, dt = 22.0, 0.0, 0.1
    plan: SpeedPlan | None = None
    v_1s = v
    for k in range(40):
        if k == 10:
            v_1s = v
        start = v
        if use_reference:
            start = reference_states({1: VehicleState((0, 0, 0), 0, 0, v)}, plan, t)[1].speed_m_s
        plan = _plan(start, 0.6, 40.0, t)
        command = plan.speed_at(1, t + 1.0)
        assert command is not None
        for _ in range(10):  # the aircraft over one tick
            v += (command - v) * (dt / 10) / tau_s
        t += dt
    return (v - v_1s) / (t - 1.0)


def test_planned_from_the_reference_the_speed_changes_at_the_planned_rate() -> None:
    """Real ArduPlane tracked a speed step within ~0.25 s; commanded each tick the measured
    speed plus a second of 0.6 m/s², it sped up at 2.4 m/s² (four times the plan's rate).
    From the reference: at the plan's rate."""
    assert _flown_accel(use_reference=False) > 3 * 0.6
    assert _flown_accel(use_reference=True) == pytest.approx(0.6, rel=0.1)


def test_the_speed_commanded_is_the_plans_a_quarter_second_on() -> None:
    g = Guidance(
        ids=[1, 2], guided_point_m=np.zeros((2, 3)), speed_m_s=np.array([20.3, 25.0]),
        course_rad=np.zeros(2), turn_rate_rad_s=np.zeros(2), climb_rate_m_s=np.zeros(2),
        state=["s1", "s1"], avoiding=[False, False], formed=[False, False],
        local_target_distance_m=[None, 1.0], leader_arrives_within_lookahead=False,
        speed_ahead_m_s=np.array([20.6, 25.0]),
    )  # fmt: skip
    assert speed_to_command(g, 0) == pytest.approx(20.6)  # no plan: 1 s on, as before
    plan = _plan(20.0, 0.6, 28.0, 0.0)
    g = replace(g, speed_plan_t_s=plan.t_s, speed_plan_m_s=np.hstack([plan.speed_m_s] * 2))
    assert speed_to_command(g, 0) == pytest.approx(20.0 + 0.6 * SPEED_COMMAND_LEAD_S)


def _formation(distances: list[float | None], start_m_s: float = 27.0) -> Guidance:
    n = len(distances) + 1
    plan = _plan(start_m_s, 0.6, 28.0, 0.0)
    return Guidance(
        ids=list(range(1, n + 1)), guided_point_m=np.zeros((n, 3)),
        speed_m_s=np.full(n, start_m_s + 0.3), course_rad=np.zeros(n),
        turn_rate_rad_s=np.zeros(n), climb_rate_m_s=np.zeros(n), state=["s1"] * n,
        avoiding=[False] * n, formed=[False] * n, local_target_distance_m=[None, *distances],
        leader_arrives_within_lookahead=False, speed_ahead_m_s=np.full(n, start_m_s + 0.6),
        speed_plan_t_s=plan.t_s, speed_plan_m_s=np.hstack([plan.speed_m_s] * n),
    )  # fmt: skip


def test_a_formation_is_held_once_formed_until_a_wingman_is_twice_the_accuracy_off() -> None:
    assert not formation_holds(_formation([3.0, 12.0]), 10.0, held=False)
    assert formation_holds(_formation([3.0, 9.0]), 10.0, held=False)
    assert formation_holds(_formation([3.0, 19.0]), 10.0, held=True)
    assert not formation_holds(_formation([3.0, 21.0]), 10.0, held=True)
    assert not formation_holds(_formation([]), 10.0, held=True)  # no wingmen
    assert not formation_holds(_formation([3.0, None]), 10.0, held=True)


def test_the_leader_of_a_held_formation_keeps_its_speed_below_v_max() -> None:
    g = leader_held(_formation([3.0, 5.0], start_m_s=24.0), 28.0, 16.0, 0.8, 0.6)
    assert g.speed_plan_m_s is not None
    assert g.speed_ahead_m_s is not None
    assert np.all(g.speed_plan_m_s[:, 0] == 24.0)  # not sped up to v_max as planned
    assert g.speed_m_s[0] == 24.0
    assert g.speed_ahead_m_s[0] == 24.0
    assert g.speed_plan_m_s[-1, 1] == pytest.approx(25.8)  # the wingmen's plans as they were
    assert speed_to_command(g, 0) == 24.0
    fast = leader_held(_formation([3.0, 5.0], start_m_s=27.5), 28.0, 16.0, 0.8, 0.6)
    assert fast.speed_plan_m_s is not None
    assert speed_to_command(fast, 0) == pytest.approx(27.5 - 0.8 * SPEED_COMMAND_LEAD_S)
    assert fast.speed_plan_m_s[-1, 0] == pytest.approx(28.0 - HOLD_RESERVE_M_S)


def _held_leader(start_m_s: float, range_m_s: tuple[float, float]) -> FloatArray:
    banded = replace(_formation([3.0, 5.0], start_m_s), leader_speed_range_m_s=range_m_s)
    plan = leader_held(banded, 28.0, 16.0, 0.8, 0.6).speed_plan_m_s
    assert plan is not None
    return plan[:, 0]


def test_a_held_leader_slower_than_its_inner_slot_can_follow_speeds_up_into_the_range() -> None:
    """The loiter route on a lossy link: held at 19 m/s, the inner slot flew 15.5 < v_min.
    The range is kept ``HOLD_RESERVE_M_S`` inside at each end: held at 24.5 m/s, the top of
    the U-turn route's range, the outer slot flew at v_max and its wingman fell 18 m behind."""
    held = _held_leader(19.0, (19.5, 24.5))
    t = _formation([3.0, 5.0]).speed_plan_t_s
    assert t is not None
    assert held[0] == 19.0
    assert held[-1] == pytest.approx(min(19.0 + 0.6 * t[-1], 19.5 + HOLD_RESERVE_M_S))
    assert _held_leader(21.0, (19.5, 24.5))[-1] == pytest.approx(19.5 + HOLD_RESERVE_M_S)
    assert np.all(np.diff(held) <= 0.6 * np.diff(t) + 1e-9)  # at accel
    assert _held_leader(23.0, (19.5, 24.5))[-1] == pytest.approx(24.5 - HOLD_RESERVE_M_S)
    assert np.all(_held_leader(22.0, (19.5, 24.5)) == 22.0)  # within it: kept
    assert _held_leader(19.0, (20.0, 21.0))[-1] == pytest.approx(20.5)  # narrow: its middle


def test_only_missions_at_arduplanes_scale_are_flown_from_the_reference() -> None:
    assert follows_speed_plan(0.6, 0.8)  # examples/arduplane_*.json
    assert not follows_speed_plan(10.0, 40.0)  # the paper's Table 1

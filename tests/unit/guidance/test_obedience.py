"""Vehicles that stop obeying: flagged after the bound of their own time, cleared when they
obey again, avoided meanwhile as moving traffic."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_ppf.guidance.obedience import (
    Obedience,
    Report,
    as_obstacles,
    courses_in_effect,
    with_obstacles,
)
from gcs_ppf.guidance.online import VehicleState
from gcs_ppf.planning.scene import Obstacles

FAILED, DENIED, ACCEPTED = 4, 2, 0


def test_a_vehicle_out_of_guided_is_flagged_after_the_bound_and_cleared_when_back() -> None:
    ob = Obedience(bound_s=3.0)
    ok, manual = Report(2, True, ACCEPTED), Report(2, False, FAILED)
    assert ob.update(0.0, [ok]) == ([], [])
    assert ob.update(1.0, [manual]) == ([], [])
    assert ob.update(3.9, [manual]) == ([], [])  # 2.9 s: not yet
    assert ob.update(4.0, [manual]) == ([2], [])
    assert ob.update(5.0, [manual]) == ([], [])  # flagged once
    assert ob.update(6.0, [ok]) == ([], [2])
    assert ob.not_responding == set()


@pytest.mark.parametrize("result", [FAILED, DENIED])
def test_commands_refused_in_guided_count_as_not_obeying(result: int) -> None:
    """Issue 10: 1,800 FAILED answers went unnoticed."""
    ob = Obedience(bound_s=2.0)
    ob.update(0.0, [Report(1, True, result)])
    assert ob.update(2.5, [Report(1, True, result)]) == ([1], [])


def test_a_blip_shorter_than_the_bound_is_not_flagged() -> None:
    ob = Obedience(bound_s=3.0)
    ob.update(0.0, [Report(3, False, None)])
    ob.update(2.0, [Report(3, True, None)])
    assert ob.update(10.0, [Report(3, False, None)]) == ([], [])  # the clock starts again


def test_uncontrolled_vehicles_become_spheres_flying_as_they_fly() -> None:
    states = {4: VehicleState((100.0, 200.0, 300.0), 0.0, math.pi / 2, 20.0),
              5: VehicleState((0.0, 0.0, 0.0), 0.0, 0.0, 10.0)}  # fmt: skip
    obs = as_obstacles(states, {4}, 25.0)
    assert obs.center.tolist() == [[100.0, 200.0, 300.0]]
    assert obs.velocity[0] == pytest.approx([0.0, 20.0, 0.0], abs=1e-9)
    assert obs.radius.tolist() == [25.0]
    both = with_obstacles(Obstacles(np.zeros((1, 3)), np.ones(1), np.zeros((1, 3))), obs)
    assert both.radius.tolist() == [1.0, 25.0]
    assert as_obstacles(states, set(), 25.0).radius.shape == (0,)


def test_a_vehicle_stuck_on_its_last_course_is_flagged_though_it_acks_everything() -> None:
    """The SITL's ``ignore`` fault: GUIDED, every command ACCEPTED, but it flies on at 40°
    off the course it is sent without turning: flagged after the bound."""
    ob = Obedience(bound_s=3.0)
    stuck = Report(4, True, ACCEPTED, course_error_rad=math.radians(40.0), turn_rate_rad_s=0.0)
    assert ob.update(0.0, [stuck]) == ([], [])
    assert ob.update(3.0, [stuck]) == ([4], [])


@pytest.mark.parametrize(
    ("error_deg", "turn_rate"),
    [(4.0, 0.0), (90.0, 0.2), (-90.0, -0.2), (-170.0, -0.05)],
)  # fmt: skip
def test_a_vehicle_on_its_course_or_turning_towards_it_obeys(
    error_deg: float, turn_rate: float
) -> None:
    r = Report(4, True, ACCEPTED, course_error_rad=math.radians(error_deg),
               turn_rate_rad_s=turn_rate)  # fmt: skip
    assert Obedience.obeys(r)


def test_a_vehicle_turning_away_from_its_course_does_not_obey() -> None:
    r = Report(4, True, ACCEPTED, course_error_rad=math.radians(60.0), turn_rate_rad_s=-0.2)
    assert not Obedience.obeys(r)


def test_a_restart_forgets_the_evidence_but_keeps_the_flags() -> None:
    """After the ground station's own stall, a vehicle's clock starts again; one already
    flagged stays flagged until it obeys."""
    ob = Obedience(bound_s=3.0)
    ob.update(0.0, [Report(2, True, ACCEPTED, math.radians(90.0)), Report(3, False, None)])
    assert ob.update(3.0, [Report(3, False, None)]) == ([3], [])
    ob.restart()
    stuck = Report(2, True, ACCEPTED, math.radians(90.0))  # 90° off and not turning
    assert ob.update(3.7, [stuck]) == ([], [])  # 3.7 s since 0.0, but no evidence before
    assert ob.update(6.6, [stuck]) == ([], [])
    assert ob.update(6.7, [stuck]) == ([2], [])  # 3.0 s of evidence since the restart
    assert ob.not_responding == {2, 3}


def test_a_vehicle_stuck_within_the_slewed_course_lead_is_flagged() -> None:
    """Campaign (d): the course sent is slewed at most ~17° ahead of the course flown, and
    the stuck wingman flew 17.4° off it, straight, for 80 s (tolerance 20° then: never
    flagged)."""
    ob = Obedience(bound_s=3.0)
    stuck = Report(5, True, ACCEPTED, course_error_rad=math.radians(-17.4),
                   turn_rate_rad_s=0.0, expected_turn_rad_s=0.15)  # fmt: skip
    assert ob.update(0.0, [stuck]) == ([], [])
    assert ob.update(3.0, [stuck]) == ([5], [])


def test_a_fast_vehicle_a_few_degrees_off_obeys_turning_as_slowly_as_expected() -> None:
    """At 300 m/s a P-controller 8° off banks a few degrees: 0.01 rad/s is a third of the
    0.03 expected, though under ``TURNING_RAD_S``; turning the wrong way never obeys."""
    toward = Report(4, True, ACCEPTED, course_error_rad=math.radians(8.0),
                    turn_rate_rad_s=0.01, expected_turn_rad_s=0.03)  # fmt: skip
    assert Obedience.obeys(toward)
    assert not Obedience.obeys(Report(4, True, ACCEPTED, math.radians(8.0), 0.005, 0.03))
    assert not Obedience.obeys(Report(4, True, ACCEPTED, math.radians(8.0), -0.05, 0.03))


def test_the_courses_in_effect_are_those_sent_within_the_lag() -> None:
    """A report answers commands sent a lag ago: the courses sent within the lag and
    ``RESPONSE_S`` count, the latest always, none when none was sent."""
    sent = [(10.0, 0.1), (10.9, 0.2), (11.8, 0.3), (12.0, 0.4)]
    assert courses_in_effect(sent, 12.0, 0.0) == [0.3, 0.4]
    assert courses_in_effect(sent, 12.0, 0.5) == [0.2, 0.3, 0.4]
    assert courses_in_effect(sent, 30.0, 1.0) == [0.4]
    assert courses_in_effect([], 12.0, 1.0) == []


def test_a_vehicle_answering_an_earlier_course_obeys() -> None:
    """Escapes sent left and right by turns: the vehicle still turns towards the course
    sent a moment ago, away from the latest.  One report per course in effect; it obeys
    if it obeys one, and is flagged only if it obeys none for the bound."""
    ob = Obedience(bound_s=3.0)
    left, right = math.radians(40.0), math.radians(-40.0)
    turning_left = 0.2
    for t in (0.0, 1.0, 2.0, 3.0):
        reports = [Report(4, True, ACCEPTED, e, turning_left, 0.3) for e in (left, right)]
        assert ob.update(t, reports) == ([], [])
    latest_only = [Report(4, True, ACCEPTED, right, turning_left, 0.3)]
    ob.update(4.0, latest_only)
    assert ob.update(7.0, latest_only) == ([4], [])


def test_a_silent_vehicle_is_not_judged_by_its_last_report() -> None:
    """A link cut: the last course reported, judged against the courses sent into the cut,
    flagged a wingman 3 s into an 8 s cut (Table 3, ×10, a CPU burner per core)."""
    ob = Obedience(bound_s=3.0)
    off_course = Report(3, True, ACCEPTED, course_error_rad=0.5)
    assert ob.update(0.0, [off_course]) == ([], [])
    for t in (1.0, 2.0, 3.0, 4.0):  # silent: no report, the evidence dropped each tick
        ob.unheard(3)
        assert ob.update(t, []) == ([], [])
    assert ob.update(5.0, [off_course]) == ([], [])  # heard again: the clock starts again
    assert ob.update(8.0, [off_course]) == ([3], [])  # and it does not obey for 3 s


def test_a_vehicle_back_from_a_loss_is_judged_afresh() -> None:
    """Flagged, it is no longer commanded: kept flagged after it was lost and heard again,
    it could be cleared only by flying the last course sent before the loss, by chance."""
    ob = Obedience(bound_s=3.0)
    manual = Report(2, False, FAILED)
    ob.update(0.0, [manual])
    assert ob.update(3.0, [manual]) == ([2], [])
    ob.forget(2)
    assert ob.not_responding == set()
    assert ob.update(4.0, [manual]) == ([], [])  # the bound counted from now
    assert ob.update(7.0, [manual]) == ([2], [])

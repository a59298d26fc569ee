"""Run-time assurance: a command that would take a vehicle into a keep-out before it can
escape is replaced by the nearest one that cannot, the rest pass untouched, and a naive
guidance (straight at a target behind an obstacle, like a final approach) flown under
assurance never enters the keep-out."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gcs_ppf.guidance import assurance
from gcs_ppf.guidance.assurance import (
    ESCAPE_OFFSETS,
    SIDE_SWITCH_S,
    SLACK_S,
    Escape,
    KeepOut,
    assure,
    escape_altitudes,
    score,
)
from gcs_ppf.guidance.vehicle_motion import (
    Command,
    Motion,
    advance,
    escape_s,
    hold_path,
    motion_vector,
    straight_track,
    track,
    turn_side,
)
from gcs_ppf.planning.scene import Obstacles

SPEED, OMEGA = 25.0, 0.3  # ArduPlane-like: 25 m/s, ~40° of bank


def sphere(x: float, y: float, z: float, r: float) -> Obstacles:
    return Obstacles(np.array([[x, y, z]]), np.array([r]), np.zeros((1, 3)))


def keep(obstacles: Obstacles, ground: float | None = 0.0) -> KeepOut:
    return KeepOut(obstacles, ground, safe_distance_obstacle=25.0, safe_distance_uav=50.0)


def plane(x: float, y: float, z: float, yaw: float) -> Motion:
    return Motion((x, y, z), yaw, SPEED, OMEGA, climb_m_s=5.0, sink_m_s=5.0, heading_tau_s=1.5)


def test_a_course_into_an_obstacle_close_ahead_is_replaced_by_one_that_escapes() -> None:
    walls = sphere(200.0, 0.0, 150.0, 100.0)  # its keep-out 75 m ahead, the turn radius 83 m
    m = plane(0.0, 0.0, 150.0, 0.0)
    [v] = assure([m], [Command(0.0, 150.0)], hold_s=1.0, keep=keep(walls))
    assert v.replaced
    assert v.reason == "obstacle"
    assert v.margin_m < 0.0 <= v.chosen_margin_m
    assert v.command.course_rad != 0.0
    s, _ = score(m, v.command, 1.0, keep(walls), [])
    assert s >= 0.0


def test_a_course_past_an_obstacle_with_room_to_turn_away_is_kept() -> None:
    walls = sphere(300.0, 250.0, 150.0, 150.0)  # 75 m of keep-out margin abeam, to the left
    m = plane(0.0, 0.0, 150.0, 0.0)
    [v] = assure([m], [Command(0.0, 150.0)], hold_s=1.0, keep=keep(walls))
    assert not v.replaced
    assert v.reason is None
    assert v.command == Command(0.0, 150.0)


def test_a_far_obstacle_straight_ahead_does_not_replace_the_command() -> None:
    """Far enough that the vehicle can still turn back after the hold: the planner's turn
    is still to come, the command stands."""
    walls = sphere(2000.0, 0.0, 150.0, 150.0)
    [v] = assure([plane(0.0, 0.0, 150.0, 0.0)], [Command(0.0, 150.0)], 1.0, keep(walls))
    assert not v.replaced


def test_a_descent_into_the_ground_is_replaced_with_a_safe_altitude() -> None:
    m = plane(0.0, 0.0, 30.0, 0.0)
    [v] = assure([m], [Command(0.0, -100.0)], hold_s=2.0, keep=keep(sphere(1e5, 0, 0, 1)))
    assert v.replaced
    assert v.reason == "ground"
    assert v.command.z_m >= 50.0


def test_the_wingman_yields_to_the_leader_head_on() -> None:
    """240 m apart head on, the wingman has an escape with the slack on its own: it turns,
    the leader holds its course."""
    leader = plane(0.0, 0.0, 150.0, 0.0)
    wingman = plane(240.0, 0.0, 150.0, math.pi)
    verdicts = assure([leader, wingman], [Command(0.0, 150.0), Command(math.pi, 150.0)],
                      hold_s=1.0, keep=keep(sphere(1e5, 0, 0, 1)))  # fmt: skip
    assert not verdicts[0].replaced
    assert verdicts[1].replaced
    assert verdicts[1].reason == "teammate"
    assert verdicts[1].chosen_margin_m >= SLACK_S * SPEED
    assert verdicts[1].gives_way_to is None


def test_the_leader_makes_way_when_the_wingman_alone_cannot_keep_the_slack() -> None:
    """160 m apart head on: whatever the wingman does on its own, the leader flying on
    leaves it less than the slack (measured in flight: a wingman escaping alone with 7–9 m
    where the slack was 50 m came to 37.1 m of a teammate).  The leader gives way too, and
    both keep the slack, each turning the same way as the other (each to its own left, or
    each to its right): their turns open the gap between them."""
    leader = plane(0.0, 0.0, 150.0, 0.0)
    wingman = plane(160.0, 0.0, 150.0, math.pi)
    k = keep(sphere(1e5, 0, 0, 1))
    leader_on = straight_track(leader, 1.0, 200)
    alone = max(
        score(wingman, Command(math.pi + offset, z), 1.0, k, [leader_on])[0]
        for offset in (0.0, *ESCAPE_OFFSETS)
        for z in escape_altitudes(wingman, Command(math.pi, 150.0), "teammate", 1.0, k)
    )
    assert alone < SLACK_S * SPEED
    verdicts = assure([leader, wingman], [Command(0.0, 150.0), Command(math.pi, 150.0)],
                      hold_s=1.0, keep=k)  # fmt: skip
    assert verdicts[0].replaced
    assert verdicts[0].reason == "teammate"
    assert verdicts[0].gives_way_to == 1
    assert verdicts[1].replaced
    assert min(v.chosen_margin_m for v in verdicts) >= SLACK_S * SPEED
    assert verdicts[0].side == verdicts[1].side != 0


def fly_straight_at(target: np.ndarray, start: Motion, k: KeepOut, steps: int) -> np.ndarray:
    """Line-of-sight guidance at 10 Hz, every command through ``assure``; the flight is the
    assurance's own response model (``hold_path``) for one tick at a time."""
    m, flown = start, [start.pos_m]
    for _ in range(steps):
        x, y, _ = m.pos_m
        course = math.atan2(target[1] - y, target[0] - x)
        [v] = assure([m], [Command(course, float(target[2]))], hold_s=0.6, keep=k)
        m = advance(m, v.command, 0.1)
        flown.append(m.pos_m)
    return np.array(flown)


@settings(max_examples=25, deadline=None)
@given(
    offset=st.floats(-120.0, 120.0),
    radius=st.floats(80.0, 300.0),
    heading=st.floats(-0.6, 0.6),
)
def test_a_final_approach_through_an_obstacle_never_enters_its_keep_out(
    offset: float, radius: float, heading: float
) -> None:
    walls = sphere(900.0, offset, 150.0, radius)
    k = keep(walls)
    flown = fly_straight_at(np.array([2000.0, 0.0, 150.0]), plane(0.0, 0.0, 150.0, heading),
                            k, steps=600)  # fmt: skip
    surface = np.linalg.norm(flown - walls.center[0], axis=1) - walls.radius[0]
    assert surface.min() >= k.safe_distance_obstacle - 1.0  # 1 m of sampling between ticks


def test_a_wingman_yields_to_a_teammate_diving_through_its_height() -> None:
    """A wingman level at 1,000 m at 200 m/s with the leader 160 m above it, the same way,
    diving at 84 m/s towards 600 m: the leader flown on along its dive comes down through
    the wingman's height (margin −23 m), and the wingman turns away; were the leader level,
    it would stay 160 m above (margin 110 m), and the command would stand.  At 200 m/s no
    escape of the wingman's alone keeps the slack (100 m): the leader gives way as well,
    levelling off above it."""
    keep_out = keep(sphere(1e5, 0, 0, 1), ground=None)
    wingman = Motion((0.0, 0.0, 1000.0), 0.0, 200.0, 0.5, 68.4, 84.5, heading_tau_s=0.4,
                     climb_lag_s=0.4, height_gain_1_s=1.75)  # fmt: skip
    leader = replace(wingman, pos_m=(0.0, 0.0, 1160.0), climb_rate_m_s=-84.0)
    diving = assure([leader, wingman], [Command(0.0, 600.0), Command(0.0, 1000.0)], 1.0,
                    keep_out)  # fmt: skip
    level = replace(leader, climb_rate_m_s=0.0)
    held = assure([level, wingman], [Command(0.0, 1160.0), Command(0.0, 1000.0)], 1.0,
                  keep_out)  # fmt: skip
    assert not held[1].replaced
    assert held[1].margin_m > 50.0
    along_its_dive = track(motion_vector(leader), Command(0.0, 600.0), 1.0, 200)
    assert score(wingman, Command(0.0, 1000.0), 1.0, keep_out, [along_its_dive])[0] < 0.0
    assert diving[1].replaced
    assert diving[1].reason == "teammate"
    assert diving[1].chosen_margin_m >= 0.0
    assert diving[0].gives_way_to == 1
    assert diving[0].command.z_m > 1000.0 + 50.0


def test_a_vehicle_diving_at_an_obstacle_with_no_level_escape_pulls_up() -> None:
    """Told to descend onto a sphere below and ahead, with no turn left that clears it at
    the commanded altitude, the vehicle is sent up instead: the escape is vertical."""
    walls = sphere(0.0, 0.0, -300.0, 400.0)  # its top 100 m up; the keep-out 125 m up
    m = Motion((-200.0, 0.0, 180.0), 0.0, 100.0, 0.5, climb_m_s=60.0, sink_m_s=60.0,
               heading_tau_s=0.4)  # fmt: skip
    [v] = assure([m], [Command(0.0, 0.0)], hold_s=2.0, keep=keep(walls, ground=None))
    assert v.replaced
    assert v.reason == "obstacle"
    assert v.chosen_margin_m >= 0.0
    assert v.command.z_m >= 180.0


def test_a_command_that_keeps_out_by_less_than_the_slack_is_replaced() -> None:
    """Recoverable, but by 5 m where half a second of flight (12.5 m) is the slack: the
    vehicle turns away now, to a command with the slack to spare."""
    m = plane(0.0, 0.0, 150.0, 0.0)

    def planned_margin(radius: float) -> float:
        return score(m, Command(0.0, 150.0), 1.0, keep(sphere(400.0, 0.0, 150.0, radius)), [])[0]

    lo, hi = 10.0, 300.0  # the radius that leaves 5 m, by bisection (the margin falls with it)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if planned_margin(mid) > 5.0 else (lo, mid)
    walls = sphere(400.0, 0.0, 150.0, lo)
    planned = planned_margin(lo)
    assert planned == pytest.approx(5.0, abs=0.5)
    [v] = assure([m], [Command(0.0, 150.0)], hold_s=1.0, keep=keep(walls))
    assert v.replaced
    assert v.chosen_margin_m >= SLACK_S * SPEED


def test_the_overtaking_vehicle_gives_way_whatever_its_priority() -> None:
    """The leader (first, highest priority) 40 m behind a slower wingman on the same track
    gives way to it; flying side by side, neither is taken to overtake the other."""
    from gcs_ppf.guidance.assurance import overtaking

    fast = Motion((0.0, 0.0, 150.0), 0.0, 30.0, 0.3, 5.0, 5.0, 1.5)
    slow = Motion((90.0, 0.0, 150.0), 0.0, 18.0, 0.3, 5.0, 5.0, 1.5)
    assert overtaking(fast, slow)
    assert not overtaking(slow, fast)
    far = keep(sphere(1e5, 0.0, 0.0, 1.0), ground=None)
    verdicts = assure([fast, slow], [Command(0.0, 150.0), Command(0.0, 150.0)], 1.0, far)
    assert verdicts[0].replaced
    assert verdicts[0].reason == "teammate"
    abreast = Motion((0.0, 141.0, 150.0), 0.0, 28.0, 0.3, 5.0, 5.0, 1.5)
    assert not overtaking(replace(fast, speed_m_s=28.0), abreast)


def test_an_escape_in_force_is_kept_rather_than_its_mirror() -> None:
    """A sphere dead ahead and no escape with the slack left: escaping to either side is as
    good.  Chosen afresh, the first in the search's order; with an escape in force to the
    other side, that one is kept (turning left and right by turns, a wingman flew into an
    obstacle)."""
    walls = sphere(200.0, 0.0, 150.0, 100.0)
    m = plane(0.0, 0.0, 150.0, 0.0)
    [fresh] = assure([m], [Command(0.0, 150.0)], hold_s=1.0, keep=keep(walls))
    assert fresh.replaced
    mirror = Command(-fresh.command.course_rad, fresh.command.z_m)
    assert fresh.chosen_margin_m < SLACK_S * SPEED
    assert score(m, mirror, 1.0, keep(walls), [])[0] == pytest.approx(fresh.chosen_margin_m)
    side = turn_side(m, mirror.course_rad)
    assert side == -fresh.side != 0
    [kept] = assure([m], [Command(0.0, 150.0)], hold_s=1.0, keep=keep(walls),
                    escaping=[Escape(mirror, side)])  # fmt: skip
    assert kept.command == mirror
    [none] = assure([m], [Command(0.0, 150.0)], hold_s=1.0, keep=keep(walls), escaping=[None])
    assert none.command == fresh.command


def test_an_escape_keeps_turning_the_way_the_last_one_turned() -> None:
    """A sphere ahead, a little to the left: afresh the vehicle escapes to the right (the
    nearest course with the slack), but having escaped to the left a moment ago it keeps
    turning left while that keeps out and is within ``SIDE_SWITCH_S`` of the best; with a
    wall across the left as well, it turns right after all (measured: escapes sent left
    and right by turns kept a wingman flying straight on into an obstacle)."""
    m = plane(0.0, 0.0, 150.0, 0.0)
    ahead = sphere(200.0, 20.0, 150.0, 100.0)
    [fresh] = assure([m], [Command(0.0, 150.0)], hold_s=1.0, keep=keep(ahead))
    assert fresh.replaced
    assert fresh.side == -1 == turn_side(m, fresh.command.course_rad)
    [bound] = assure([m], [Command(0.0, 150.0)], 1.0, keep(ahead), [Escape(None, 1)])
    assert bound.replaced
    assert bound.side == 1 == turn_side(m, bound.command.course_rad)
    assert 0.0 <= bound.chosen_margin_m < fresh.chosen_margin_m
    walled = Obstacles(np.array([[200.0, 20.0, 150.0], [0.0, 140.0, 150.0]]),
                       np.array([100.0, 80.0]), np.zeros((2, 3)))  # fmt: skip
    [switched] = assure([m], [Command(0.0, 150.0)], 1.0, keep(walled), [Escape(None, 1)])
    assert switched.side == -1
    assert switched.chosen_margin_m > 0.0
    assert fresh.chosen_margin_m - bound.chosen_margin_m < SIDE_SWITCH_S * SPEED


def test_after_warm_up_nothing_is_compiled_in_flight() -> None:
    """The service warms the compiled prediction up before any run; a tick's calls, with
    integer or float inputs, then compile nothing more (seconds of a tick otherwise)."""
    from gcs_ppf.guidance import prediction, reach

    assurance.warm_up()
    compiled = {
        f: len(getattr(prediction, f).signatures)
        for f in ("flights", "judge", "judge_each", "judge_in_turn", "judge_flown", "track_into",
                  "longest_step", "track_path", "fly_hold", "escape_s", "escape_steps",
                  "height_demand_now")
    }  # fmt: skip
    assert all(compiled.values()), compiled  # warmed up, each of them
    yields_compiled = len(reach.yields.signatures)
    m = Motion((0, 0, 100), 0, 25, 0.3, 5, 5)
    walls = Obstacles(np.array([[500, 0, 100]]), np.array([100]), np.zeros((1, 3)))
    assure([m, m], [Command(0, 100)] * 2, 1, KeepOut(walls, 0, 25, 50))
    hold_path(m, Command(0, 100), 1)
    advance(m, Command(0, 100), 2)
    escape_s(m)
    from gcs_ppf.guidance.airframe import Airframe
    from gcs_ppf.guidance.online import VehicleState
    from gcs_ppf.mission import Mission
    from gcs_ppf.service.commanding import levelling_height
    from tests.conftest import EXAMPLES

    mission = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())
    state = VehicleState((0, 0, 100), 0, 0, 25, climb_rate_m_s=-3)
    levelling_height(state, Airframe(tecs_time_constant_s=5), mission)
    assert {f: len(getattr(prediction, f).signatures) for f in compiled} == compiled
    assert len(reach.yields.signatures) == yields_compiled == 1

"""The airframe envelope from ArduPlane's parameters, and what the service derives from it."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from gcs_ppf.guidance.airframe import (
    DEFAULT_GUARD_HORIZON_S,
    DEFAULT_GUARD_MARGIN_M,
    DEFAULT_GUARD_RESOLUTION_M,
    DEFAULT_PLANNING_MARGIN_M,
    G_M_S2,
    Airframe,
    guard_tuning,
    online_limits,
    planning_margin_m,
    response_lag_s,
    tick_envelope,
)
from gcs_ppf.mavlink.ardupilot import TURN_EFFICIENCY

PLANE_PARM = {  # ArduPlane 4.7 SITL, plane.parm defaults (../shared/arduplane-traces/meta.json)
    "TECS_CLMB_MAX": 5.0,
    "TECS_SINK_MAX": 5.0,
    "ROLL_LIMIT_DEG": 65.0,
    "PTCH_LIM_MAX_DEG": 25.0,
    "PTCH_LIM_MIN_DEG": -20.0,
    "GUIDED_P": 5000.0,
    "AIRSPEED_MIN": 10.0,
    "AIRSPEED_CRUISE": 22.0,
    "AIRSPEED_MAX": 30.0,
    "TKOFF_ALT": 50.0,
    "RLL2SRV_TCONST": 0.25,
}
PLANE = Airframe.from_params(PLANE_PARM.get)
NO_TCONST = dataclasses.replace(PLANE, roll_time_constant_s=None)


def test_the_envelope_from_arduplane_47_parameters() -> None:
    expected = Airframe(
        climb_max_m_s=5.0, sink_max_m_s=5.0, airspeed_min_m_s=10.0, airspeed_cruise_m_s=22.0,
        airspeed_max_m_s=30.0, roll_limit_deg=65.0, guided_p=5000.0, pitch_max_deg=25.0,
        pitch_min_deg=-20.0, takeoff_alt_m=50.0, roll_time_constant_s=0.25,
    )  # fmt: skip
    assert expected == PLANE
    assert PLANE.as_dict()["guided_p"] == 5000.0


def test_names_before_arduplane_45_and_values_that_cannot_be_limits() -> None:
    old = {"LIM_ROLL_CD": 4500.0, "LIM_PITCH_MAX": 2000.0, "LIM_PITCH_MIN": -2500.0,
           "ARSPD_FBW_MIN": 9.0, "ARSPD_FBW_MAX": 25.0, "TRIM_ARSPD_CM": 1500.0}  # fmt: skip
    a = Airframe.from_params(old.get)
    assert (a.roll_limit_deg, a.pitch_max_deg, a.pitch_min_deg) == (45.0, 20.0, -25.0)
    assert (a.airspeed_min_m_s, a.airspeed_cruise_m_s, a.airspeed_max_m_s) == (9.0, 15.0, 25.0)
    bad = Airframe.from_params(
        {"GUIDED_P": 0.0, "TECS_CLMB_MAX": -1.0, "ROLL_LIMIT_DEG": math.nan}.get
    )
    assert bad == Airframe()
    assert Airframe.from_params(lambda _name: None) == Airframe()


def test_turn_rate_and_flight_path_angles_at_a_speed() -> None:
    assert PLANE.max_turn_rate(22.0) == pytest.approx(
        TURN_EFFICIENCY * G_M_S2 * math.tan(math.radians(65)) / 22
    )
    assert PLANE.heading_gain == pytest.approx(0.8727, abs=1e-4)
    assert PLANE.heading_time_constant_s(22.0) == pytest.approx(
        22.0 / (0.87266 * TURN_EFFICIENCY * G_M_S2), 1e-4
    )
    # TECS: 5 m/s at 22 m/s is 13.1°, tighter than the 25° / 20° pitch limits
    assert PLANE.max_climb_angle(22.0) == pytest.approx(math.asin(5.0 / 22.0))
    assert PLANE.max_dive_angle(22.0) == pytest.approx(math.asin(5.0 / 22.0))
    # slow enough, the pitch limits bind
    assert PLANE.max_climb_angle(10.0) == pytest.approx(math.radians(25.0))
    assert PLANE.max_dive_angle(10.0) == pytest.approx(math.radians(20.0))
    assert Airframe().max_turn_rate(22.0) is None
    assert Airframe().max_climb_angle(22.0) is None


def test_the_fleets_online_limits_are_the_tightest_known() -> None:
    slower = Airframe(climb_max_m_s=3.0, roll_limit_deg=45.0, airspeed_max_m_s=25.0,
                      airspeed_min_m_s=12.0)  # fmt: skip
    silent = Airframe()  # answered nothing: leaves the others' limits
    lim = online_limits([PLANE, slower, silent], 25.0)
    assert (lim.v_min, lim.v_max) == (12.0, 25.0)
    assert lim.max_yaw_rate == pytest.approx(
        TURN_EFFICIENCY * G_M_S2 * math.tan(math.radians(45.0)) / 25.0
    )
    assert lim.max_climb_angle == pytest.approx(math.asin(3.0 / 25.0))
    assert lim.max_dive_angle == pytest.approx(math.asin(5.0 / 25.0))
    none = online_limits([silent], 25.0)
    assert (none.v_min, none.v_max, none.max_yaw_rate, none.max_climb_angle) == (None,) * 4


def test_the_response_lag_is_the_roll_in_with_the_feed_forward() -> None:
    """Led for its P-controller, a vehicle follows a turning plan after the roll-in (4 roll
    time constants: 1.0 s at RLL2SRV_TCONST 0.25, as real ArduPlane peaked at 50° of bank
    1.0 s after a course step); without RLL2SRV_TCONST, the heading time constant."""
    assert response_lag_s(PLANE, 28.0, 0.1) == pytest.approx(4 * 0.25 + 0.1)
    tau = 28.0 / (5000.0 * math.pi / 18000.0 * TURN_EFFICIENCY * G_M_S2)
    assert response_lag_s(NO_TCONST, 28.0, 0.1) == pytest.approx(tau + 0.1)
    assert math.isnan(response_lag_s(Airframe(roll_time_constant_s=0.25), 28.0, 0.1))


def test_the_planning_margin_is_v_max_times_the_response_lag() -> None:
    assert planning_margin_m([PLANE], 28.0, 0.1) == pytest.approx(28.0 * 1.1)
    k = 5000.0 * math.pi / 18000.0
    expected = 20.0 * (20.0 / (k * TURN_EFFICIENCY * G_M_S2) + 0.1)
    assert planning_margin_m([NO_TCONST], 20.0, 0.1) == pytest.approx(expected)
    assert 60.0 < expected < 70.0
    assert planning_margin_m([PLANE, NO_TCONST], 20.0, 0.1) == pytest.approx(expected)
    assert planning_margin_m([NO_TCONST], 28.0, 0.1) == DEFAULT_PLANNING_MARGIN_M  # 130 m
    # a vehicle that does not report GUIDED_P keeps today's fixed margin
    assert planning_margin_m([PLANE, Airframe()], 28.0, 0.1) == DEFAULT_PLANNING_MARGIN_M
    assert planning_margin_m([], 28.0, 0.1) == DEFAULT_PLANNING_MARGIN_M


def test_a_tick_envelope_takes_speed_limits_at_the_fastest_reachable_speed() -> None:
    env = tick_envelope([PLANE], [20.0, 22.0], 16.0, 28.0, 2.0, 3.0, 0.1)
    assert env.speed_m_s == pytest.approx(28.0)  # 22 + 2 × 3, within v_max 28
    assert env.limits.max_yaw_rate == pytest.approx(PLANE.max_turn_rate(28.0) or 0.0)
    slow = tick_envelope([PLANE], [18.0], 16.0, 28.0, 1.0, 3.0, 0.1)
    assert slow.speed_m_s == pytest.approx(21.0)
    # the paper's airframe on a simulator without ArduPlane's parameters: as before
    paper = tick_envelope([Airframe()], [150.0], 100.0, 300.0, 10.0, 3.0, 0.1)
    assert paper.planning_margin_m == DEFAULT_PLANNING_MARGIN_M
    assert paper.limits.max_yaw_rate is None
    # AIRSPEED_MAX below the mission's v_max caps the margin's speed; an override wins
    capped = tick_envelope([PLANE], [22.0], 16.0, 300.0, 2.0, 3.0, 0.1)
    assert capped.planning_margin_m == pytest.approx(planning_margin_m([PLANE], 30.0, 0.1))
    fixed = tick_envelope([PLANE], [22.0], 16.0, 28.0, 2.0, 3.0, 0.1, margin_override_m=40.0)
    assert fixed.planning_margin_m == 40.0


def test_the_guard_asks_an_arduplane_only_what_tecs_climbs_within_the_horizon() -> None:
    tuning = guard_tuning([NO_TCONST, NO_TCONST], [22.0, 22.0], 50.0, 0.1)
    lag = 22.0 / (PLANE.heading_gain or 1.0) / (TURN_EFFICIENCY * G_M_S2) + 0.1
    assert tuning.horizon_s == pytest.approx(50.0 / 5.0 + lag)  # 50 m at 5 m/s, after the lag
    assert np.allclose(tuning.resolution_up_m, 5.0 * tuning.horizon_s)
    assert np.allclose(tuning.resolution_down_m, 5.0 * tuning.horizon_s)
    assert np.allclose(tuning.margin_m, min(22.0 * lag, DEFAULT_GUARD_MARGIN_M))
    assert tuning.resolution_up_m[0] < DEFAULT_GUARD_RESOLUTION_M
    slow = guard_tuning([NO_TCONST], [16.0], 50.0, 0.1)  # what it flies during its lag
    lag16 = 16.0 / (PLANE.heading_gain or 1.0) / (TURN_EFFICIENCY * G_M_S2) + 0.1
    assert slow.margin_m[0] == pytest.approx(16.0 * lag16)
    assert slow.margin_m[0] < DEFAULT_GUARD_MARGIN_M
    led = guard_tuning([PLANE], [22.0], 50.0, 0.1)  # the roll-in lag with the feed-forward
    assert led.margin_m[0] == pytest.approx(22.0 * 1.1)
    assert led.horizon_s == pytest.approx(50.0 / 5.0 + 1.1)


def test_the_paper_airframe_keeps_the_figures_tuned_at_its_speeds() -> None:
    """The built-in SITL's airframe for the paper's 100–300 m/s (a 0.4 s heading loop at
    100 m/s, climbs at 20° at 300 m/s): the derivation would ask more than the figures
    tuned and measured there, which are the bounds."""
    paper = Airframe(climb_max_m_s=102.6, sink_max_m_s=126.8, roll_limit_deg=88.4,
                     guided_p=202866.0, airspeed_min_m_s=100.0, airspeed_max_m_s=300.0)  # fmt: skip
    assert planning_margin_m([paper], 300.0, 0.1) == DEFAULT_PLANNING_MARGIN_M
    tuning = guard_tuning([paper] * 2, [300.0, 100.0], 50.0, 0.1)
    assert tuning.horizon_s == DEFAULT_GUARD_HORIZON_S
    assert np.allclose(tuning.resolution_up_m, DEFAULT_GUARD_RESOLUTION_M)
    assert np.allclose(tuning.resolution_down_m, DEFAULT_GUARD_RESOLUTION_M)
    assert tuning.margin_m[0] == DEFAULT_GUARD_MARGIN_M
    assert tuning.margin_m[1] == pytest.approx(
        100.0 * (100.0 / (paper.heading_gain or 1) / (TURN_EFFICIENCY * G_M_S2) + 0.1)
    )
    lim = online_limits([paper], 300.0)  # Table 1's turn and climb stay the binding ones
    assert (lim.max_yaw_rate or 0.0) > math.pi / 6
    assert lim.max_climb_angle == pytest.approx(math.radians(20.0), abs=1e-3)


def test_the_guard_keeps_its_fixed_figures_where_nothing_was_answered_or_overridden() -> None:
    paper = guard_tuning([Airframe(), Airframe()], [200.0, 150.0], 50.0, 0.1)
    assert paper.horizon_s == DEFAULT_GUARD_HORIZON_S
    assert np.allclose(paper.margin_m, DEFAULT_GUARD_MARGIN_M)
    assert np.allclose(paper.resolution_up_m, DEFAULT_GUARD_RESOLUTION_M)
    mixed = guard_tuning([PLANE, Airframe()], [22.0, 22.0], 50.0, 0.1)
    assert mixed.resolution_up_m[1] == DEFAULT_GUARD_RESOLUTION_M
    assert mixed.margin_m[1] == DEFAULT_GUARD_MARGIN_M
    assert mixed.resolution_up_m[0] == pytest.approx(5.0 * mixed.horizon_s)
    given = guard_tuning(
        [PLANE], [22.0], 50.0, 0.1, horizon_s=4.0, margin_m=30.0, resolution_m=80.0
    )
    assert (given.horizon_s, given.margin_m[0], given.resolution_down_m[0]) == (4.0, 30.0, 80.0)

"""Unit tests of sitl.physics: Eq. 5 kinematics, ArduPlane's bank-to-turn, heading and
TECS loops, takeoff, and the airframe's limits under any command."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs

from gcs_ppf.mavlink.ardupilot import TURN_EFFICIENCY
from sitl.airframe import ARDUPLANE
from sitl.physics import (
    DT_S,
    GRAVITY_M_S2,
    Envelope,
    FleetState,
    GuidanceKind,
    default_envelope,
    effective_radius_m,
    hold_guidance,
    initial_state,
    step,
)

W = math.pi / 6


def envelope(n: int, v_min: float = 100.0, v_max: float = 300.0) -> Envelope:
    """The paper's airframe: 100–300 m/s, 30°/s, a bank that gives it at 300 m/s."""
    env = default_envelope(
        n, v_min=v_min, v_max=v_max, accel=10.0, decel=40.0, max_pitch_rate=W,
        max_yaw_rate=W, ground_z_m=np.zeros(n),
    )  # fmt: skip
    env.pitch_min_rad[:] = -0.4
    env.pitch_max_rad[:] = 0.35
    env.roll_limit_rad[:] = math.atan(300.0 * W / (TURN_EFFICIENCY * GRAVITY_M_S2))
    env.heading_gain[:] = 100.0 / (0.4 * TURN_EFFICIENCY * GRAVITY_M_S2)
    env.climb_max_m_s[:] = 300.0 * math.sin(0.35)
    env.sink_max_m_s[:] = 300.0 * math.sin(0.4)
    env.l1_period_s[:] = 4.0
    return env


def arduplane_envelope(n: int = 1) -> Envelope:
    """ArduPlane's plane.parm airframe (sitl.airframe.ARDUPLANE), its bank first-order
    (SIM_ROLL_ZETA 0), so that the autopilot's demand shows in it directly."""
    env = default_envelope(
        n, v_min=9.0, v_max=35.0, accel=0.65, decel=0.85, max_pitch_rate=math.radians(60),
        max_yaw_rate=math.radians(120), ground_z_m=np.zeros(n),
    )  # fmt: skip
    env.speed_height_coupling[:] = 0.5
    return env


def fleet(n: int = 1, speed: float = 100.0, z: float = 300.0, yaw: float = 0.0) -> FleetState:
    pos = np.zeros((n, 3))
    pos[:, 0] = np.arange(n) * 1000.0
    pos[:, 2] = z
    return initial_state(pos, np.zeros(n), np.full(n, yaw), np.full(n, speed))


def test_hold_flies_straight_eq5() -> None:
    s = fleet(yaw=0.3)
    env = envelope(1)
    g = hold_guidance(s)
    for _ in range(50):
        s = step(s, env, g, DT_S)
    # 1 s at 100 m/s along ψ = 0.3 rad: Eq. 5 exactly.
    assert s.pos_enu_m[0, 0] == pytest.approx(100 * math.cos(0.3), abs=1e-6)
    assert s.pos_enu_m[0, 1] == pytest.approx(100 * math.sin(0.3), abs=1e-6)
    assert s.pos_enu_m[0, 2] == pytest.approx(300.0)


def test_goto_turn_rate_limited_and_reaches_point() -> None:
    s = fleet()
    env = envelope(1)
    g = hold_guidance(s)
    g.kind[:] = GuidanceKind.GOTO
    g.target_enu_m[:] = (-3000.0, 0.0, 300.0)  # behind: a full turn is needed
    prev = s.yaw_rad.copy()
    closest = math.inf
    for _ in range(int(60 / DT_S)):
        s = step(s, env, g, DT_S)
        rate = abs(math.remainder(float(s.yaw_rad[0] - prev[0]), math.tau)) / DT_S
        assert rate <= W + 1e-9
        prev = s.yaw_rad.copy()
        closest = min(closest, float(np.hypot(*(s.pos_enu_m[0, :2] - (-3000.0, 0.0)))))
    assert closest < 50.0


def test_turn_is_what_the_bank_gives() -> None:
    s = fleet(speed=22.0)
    env = arduplane_envelope()
    g = hold_guidance(s)
    g.kind[:] = GuidanceKind.TURN
    g.radius_m[:] = 100.0
    g.direction[:] = 1.0  # clockwise: right wing down, yaw rate negative in ENU
    for _ in range(int(5 / DT_S)):
        s = step(s, env, g, DT_S)
    bank = math.atan(22.0**2 / (GRAVITY_M_S2 * 100.0))
    assert s.roll_rad[0] == pytest.approx(bank, abs=1e-3)
    assert s.yaw_rate_rad_s[0] == pytest.approx(
        -TURN_EFFICIENCY * GRAVITY_M_S2 * math.tan(bank) / 22.0, rel=1e-6
    )


def test_arduplane_bank_overshoots_a_saturated_demand_and_settles_on_it() -> None:
    """ArduPlane's roll overshoots a step of its demand: a course step at a 45° bank limit
    peaked at 50.0–50.3° in every recording of 90° or more; then the bank is the demand."""
    s = fleet(speed=22.0)  # east
    env = arduplane_envelope()
    env.roll_damping[:] = ARDUPLANE["SIM_ROLL_ZETA"]
    g = hold_guidance(s)
    g.kind[:] = GuidanceKind.COURSE
    g.course_rad[:] = math.pi / 2  # north: a left turn (negative bank)
    g.lateral_accel_m_s2[:] = 10.0  # the recordings' param3: bank ≤ 45.5°
    limit = math.degrees(math.atan(10.0 / GRAVITY_M_S2))
    banks = []
    for _ in range(int(30 / DT_S)):
        s = step(s, env, g, DT_S)
        banks.append(-math.degrees(float(s.roll_rad[0])))
    assert limit + 2.0 <= max(banks) <= limit + 8.0
    assert banks[int(2 / DT_S)] == pytest.approx(limit, abs=1.0)  # saturated, settled
    error = math.remainder(math.pi / 2 - float(s.yaw_rad[0]), math.tau)
    assert -banks[-1] == pytest.approx(-math.degrees(env.heading_gain[0] * error), abs=0.5)


def test_arduplane_airspeed_lags_a_ramp_and_overshoots_after_it() -> None:
    """ArduPlane's TECS flies a slowing asked at 0.6 m/s² about 1 m/s behind it and, sped up
    again, overshoots by ~0.7 m/s some 5 s after the ramp (traces 12-speed-ramp-*)."""
    s = fleet(speed=22.0)
    env = arduplane_envelope()
    env.speed_omega_rad_s[:] = ARDUPLANE["SIM_SPD_OMEGA"]
    env.speed_damping[:] = ARDUPLANE["SIM_SPD_ZETA"]
    g = hold_guidance(s)
    behind, after = [], []
    for k in range(int(40 / DT_S)):
        t = k * DT_S
        g.speed_cmd_m_s[:] = max(16.0, 22.0 - 0.6 * t) if t < 20 else min(22.0, 16 + 0.6 * (t - 20))
        s = step(s, env, g, DT_S)
        if 5.0 <= t <= 10.0:
            behind.append(float(s.speed_m_s[0]) - float(g.speed_cmd_m_s[0]))
        if t > 30.0:
            after.append(float(s.speed_m_s[0]) - 22.0)
    assert 0.6 <= np.mean(behind) <= 1.5
    assert 0.2 <= max(after) <= 1.0


def test_orbit_settles_near_the_effective_radius_clockwise() -> None:
    s = fleet()
    env = envelope(1)
    g = hold_guidance(s)
    g.kind[:] = GuidanceKind.ORBIT
    g.target_enu_m[:] = (2000.0, 500.0, 300.0)
    g.radius_m[:] = 60.0  # tighter than the vehicle can turn: it flies a wider circle
    for _ in range(int(150 / DT_S)):
        s = step(s, env, g, DT_S)
    r_eff = float(effective_radius_m(np.array([60.0]), np.array([100.0]), env)[0])
    assert r_eff > 60.0
    dist = float(np.hypot(*(s.pos_enu_m[0, :2] - (2000.0, 500.0))))
    # ArduPlane's loiter too flies wider than asked (trace 08: 94 m on an 80 m circle).
    assert r_eff * 0.9 <= dist <= r_eff / TURN_EFFICIENCY * 1.1
    assert s.yaw_rate_rad_s[0] < 0


def test_guided_heading_is_a_p_controller_within_the_bank_limit() -> None:
    """GUIDED heading: bank = GUIDED_P × error within atan(param3 / g) (mode_guided.cpp)."""
    s = fleet(speed=22.0)  # east
    env = arduplane_envelope()
    g = hold_guidance(s)
    g.kind[:] = GuidanceKind.COURSE
    g.course_rad[:] = math.pi / 2  # north: a left turn (negative bank)
    g.lateral_accel_m_s2[:] = 5.0  # bank ≤ 27°
    limit = math.atan(5.0 / GRAVITY_M_S2)
    banks = []
    for _ in range(int(30 / DT_S)):
        s = step(s, env, g, DT_S)
        banks.append(float(s.roll_rad[0]))
        assert abs(banks[-1]) <= limit + 1e-9
    assert min(banks) == pytest.approx(-limit, abs=1e-3)  # saturated early in the turn
    assert s.yaw_rad[0] == pytest.approx(math.pi / 2, abs=math.radians(1.0))
    # Small errors: the bank is the gain times the error (no integrator).
    error = math.remainder(math.pi / 2 - float(s.yaw_rad[0]), math.tau)
    assert s.roll_rad[0] == pytest.approx(-env.heading_gain[0] * error, abs=math.radians(0.5))


def test_a_turning_course_command_is_followed_with_the_p_controllers_lag() -> None:
    """A course that turns at ψ̇ is flown ψ̇-behind by the error that gives its bank."""
    s = fleet(speed=22.0)
    env = arduplane_envelope()
    g = hold_guidance(s)
    g.kind[:] = GuidanceKind.COURSE
    g.lateral_accel_m_s2[:] = 10.0
    rate = 0.1  # rad/s, to the left
    course = 0.0
    for _ in range(int(40 / DT_S)):
        course += rate * DT_S
        g.course_rad[:] = course
        s = step(s, env, g, DT_S)
    lag = math.remainder(course - float(s.yaw_rad[0]), math.tau)
    bank = math.atan(22.0 * rate / (TURN_EFFICIENCY * GRAVITY_M_S2))
    assert lag == pytest.approx(bank / env.heading_gain[0], rel=0.05)


def test_speed_follows_command_within_accel_limits() -> None:
    s = fleet()
    env = envelope(1)
    g = hold_guidance(s)
    g.speed_cmd_m_s[:] = 200.0
    speeds = []
    for _ in range(int(15 / DT_S)):
        s = step(s, env, g, DT_S)
        speeds.append(float(s.speed_m_s[0]))
    dv = np.diff([100.0, *speeds]) / DT_S
    assert dv.max() <= 10.0 + 1e-9
    assert speeds[-1] == pytest.approx(200.0, abs=1.0)
    g.speed_cmd_m_s[:] = 1000.0  # beyond v_max: clipped
    for _ in range(int(30 / DT_S)):
        s = step(s, env, g, DT_S)
    assert s.speed_m_s[0] <= 300.0


def test_speeding_up_costs_height_where_the_airframe_trades_energy() -> None:
    s = fleet(speed=22.0, z=100.0)
    env = arduplane_envelope()
    g = hold_guidance(s)
    g.kind[:] = GuidanceKind.GOTO
    g.target_enu_m[:] = (1e6, 0.0, 100.0)
    g.speed_cmd_m_s[:] = 28.0
    lowest = math.inf
    for _ in range(int(20 / DT_S)):
        s = step(s, env, g, DT_S)
        lowest = min(lowest, float(s.pos_enu_m[0, 2]))
    assert 94.0 < lowest < 99.0  # ArduPlane: −4.9 m (trace 07a)
    assert s.pos_enu_m[0, 2] == pytest.approx(100.0, abs=1.0)


def test_climb_to_target_altitude_within_pitch_and_climb_limits() -> None:
    s = fleet()
    env = envelope(1)
    g = hold_guidance(s)
    g.kind[:] = GuidanceKind.GOTO
    g.target_enu_m[:] = (1e6, 0.0, 1500.0)
    for _ in range(int(60 / DT_S)):
        s = step(s, env, g, DT_S)
        assert -0.4 - 1e-9 <= s.pitch_rad[0] <= 0.35 + 1e-9
    assert s.pos_enu_m[0, 2] == pytest.approx(1500.0, abs=2.0)
    s = fleet(speed=22.0, z=100.0)
    env = arduplane_envelope()
    g.target_enu_m[:] = (1e6, 0.0, 150.0)
    for _ in range(int(60 / DT_S)):
        s = step(s, env, g, DT_S)
        assert s.climb_m_s[0] <= env.climb_max_m_s[0] + 1e-9
    assert s.pos_enu_m[0, 2] == pytest.approx(150.0, abs=1.0)


def test_guided_altitude_param3_slews_the_demand_from_here_so_it_barely_climbs() -> None:
    """GUIDED_CHANGE_ALTITUDE param3 > 0: ArduPlane keeps the demand within param3 × 0.1 s
    of the current altitude (``update_target_altitude``): +50 m at 2 m/s climbed 3.6 m in
    60 s (trace 06); param3 = 0 (∞ here) climbs as TECS can (trace 04)."""
    climbed = {}
    for slew in (2.0, math.inf):
        s = fleet(speed=22.0, z=100.0)
        env = arduplane_envelope()
        g = hold_guidance(s)
        g.kind[:] = GuidanceKind.GOTO
        g.target_enu_m[:] = (1e6, 0.0, 150.0)
        g.alt_slew_m_s[:] = slew
        for _ in range(int(60 / DT_S)):
            s = step(s, env, g, DT_S)
        climbed[slew] = float(s.pos_enu_m[0, 2]) - 100.0
    assert 1.0 < climbed[2.0] < 8.0
    assert climbed[math.inf] == pytest.approx(50.0, abs=1.0)


def test_takeoff_rolls_lifts_off_at_rotation_speed_and_climbs() -> None:
    s = initial_state(np.zeros((1, 3)), np.zeros(1), np.full(1, math.pi / 2), np.zeros(1),
                      landed=np.ones(1, dtype=bool))  # fmt: skip
    env = arduplane_envelope()
    g = hold_guidance(s)
    g.kind[:] = GuidanceKind.GOTO
    g.target_enu_m[:] = (0.0, 1e6, 50.0)  # a GUIDED point: ArduPlane does not take off
    for _ in range(int(5 / DT_S)):
        s = step(s, env, g, DT_S)
    assert bool(s.landed[0])
    assert s.speed_m_s[0] == 0.0
    g.kind[:] = GuidanceKind.COURSE
    g.course_rad[:] = math.pi / 2
    g.takeoff[:] = True
    lift_off = None
    for k in range(int(10 / DT_S)):
        s = step(s, env, g, DT_S)
        if lift_off is None and not s.landed[0]:
            lift_off = (k + 1) * DT_S
            assert s.speed_m_s[0] >= env.rotate_speed_m_s[0]
    assert lift_off is not None
    assert 2.5 < lift_off < 4.5  # ArduPlane: 3.8 s
    assert s.pos_enu_m[0, 2] > 30.0
    assert abs(s.pos_enu_m[0, 0]) < 1e-6  # straight along the runway


def test_glide_without_thrust_lands() -> None:
    s = fleet(z=50.0)
    env = envelope(1)
    g = hold_guidance(s)
    g.thrust[:] = False
    g.kind[:] = GuidanceKind.GOTO
    for _ in range(int(60 / DT_S)):
        s = step(s, env, g, DT_S)
    assert bool(s.landed[0])
    assert s.speed_m_s[0] == 0.0
    assert s.pos_enu_m[0, 2] == pytest.approx(0.0)


def test_step_is_pure_and_deterministic() -> None:
    s0 = fleet(3)
    env = envelope(3)
    g = hold_guidance(s0)
    g.kind[:] = GuidanceKind.ORBIT
    before = s0.pos_enu_m.copy()
    a = step(s0, env, g, DT_S)
    b = step(s0, env, g, DT_S)
    assert np.array_equal(s0.pos_enu_m, before)
    assert np.array_equal(a.pos_enu_m, b.pos_enu_m)


@settings(max_examples=40, deadline=None)
@given(
    x=hs.floats(-5000, 5000), y=hs.floats(-5000, 5000), z=hs.floats(50, 1000),
    yaw=hs.floats(-math.pi, math.pi), v=hs.floats(100, 300), cmd=hs.floats(0, 500),
    kind=hs.sampled_from(list(GuidanceKind)), course=hs.floats(-10, 10),
    lateral=hs.floats(0.05, 1e3), slew=hs.floats(0.1, 1e3), ardu=hs.booleans(),
)  # fmt: skip
def test_limits_hold_for_any_command(
    x: float, y: float, z: float, yaw: float, v: float, cmd: float, kind: GuidanceKind,
    course: float, lateral: float, slew: float, ardu: bool,
) -> None:  # fmt: skip
    if ardu:  # ArduPlane's airframe at its own speeds
        v, cmd = v / 10.0, cmd / 10.0
    s = fleet(speed=v, yaw=yaw)
    env = arduplane_envelope() if ardu else envelope(1)
    g = hold_guidance(s)
    g.kind[:] = kind
    g.target_enu_m[:] = (x, y, z)
    g.speed_cmd_m_s[:] = cmd
    g.course_rad[:] = course
    g.lateral_accel_m_s2[:] = lateral
    g.alt_slew_m_s[:] = slew
    w_yaw, w_pitch = float(env.max_yaw_rate_rad_s[0]), float(env.max_pitch_rate_rad_s[0])
    for _ in range(50):
        n = step(s, env, g, DT_S)
        assert abs(math.remainder(float(n.yaw_rad[0] - s.yaw_rad[0]), math.tau)) <= (
            w_yaw * DT_S + 1e-9
        )
        assert abs(n.roll_rad[0]) <= env.roll_limit_rad[0] + 1e-9
        if kind == GuidanceKind.COURSE:  # and no more bank than the lateral accel allows
            assert abs(n.roll_rad[0]) <= math.atan(lateral / GRAVITY_M_S2) + 1e-9
        climb_step = abs(float(n.climb_m_s[0] - s.climb_m_s[0]))
        assert climb_step <= float(n.speed_m_s[0]) * w_pitch * DT_S + 1e-9
        assert -env.sink_max_m_s[0] - 1e-9 <= n.climb_m_s[0] <= env.climb_max_m_s[0] + 1e-9
        dv = float(n.speed_m_s[0] - s.speed_m_s[0])
        assert -env.decel_m_s2[0] * DT_S - 1e-9 <= dv <= env.accel_m_s2[0] * DT_S + 1e-9
        assert env.v_min_m_s[0] <= n.speed_m_s[0] <= env.v_max_m_s[0]
        s = n

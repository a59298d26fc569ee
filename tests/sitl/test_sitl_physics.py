"""Unit tests of sitl.physics: Eq. 5 kinematics, limits and guidance."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs

from sitl.physics import (
    DT_S,
    Envelope,
    GuidanceKind,
    effective_radius_m,
    hold_guidance,
    initial_state,
    step,
)


def envelope(
    n: int, v_min: float = 100.0, v_max: float = 300.0, w: float = math.pi / 6
) -> Envelope:
    return Envelope(
        v_min_m_s=np.full(n, v_min), v_max_m_s=np.full(n, v_max),
        accel_m_s2=np.full(n, 10.0), decel_m_s2=np.full(n, 40.0),
        max_pitch_rate_rad_s=np.full(n, w), max_yaw_rate_rad_s=np.full(n, w),
        pitch_min_rad=np.full(n, -0.4), pitch_max_rad=np.full(n, 0.35),
        ground_z_m=np.zeros(n),
    )  # fmt: skip


def fleet(n: int = 1, speed: float = 100.0, z: float = 300.0, yaw: float = 0.0):  # type: ignore[no-untyped-def]
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
        assert rate <= math.pi / 6 + 1e-9
        prev = s.yaw_rad.copy()
        closest = min(closest, float(np.hypot(*(s.pos_enu_m[0, :2] - (-3000.0, 0.0)))))
    assert closest < 50.0


def test_orbit_settles_on_effective_radius() -> None:
    s = fleet()
    env = envelope(1)
    g = hold_guidance(s)
    g.kind[:] = GuidanceKind.ORBIT
    g.target_enu_m[:] = (2000.0, 500.0, 300.0)
    g.radius_m[:] = 60.0  # tighter than v/ω = 191 m: the vehicle flies a wider circle
    for _ in range(int(120 / DT_S)):
        s = step(s, env, g, DT_S)
    r_eff = float(
        effective_radius_m(np.array([60.0]), np.array([100.0]), np.array([math.pi / 6]))[0]
    )
    dist = float(np.hypot(*(s.pos_enu_m[0, :2] - (2000.0, 500.0))))
    assert dist == pytest.approx(r_eff, rel=0.1)
    # clockwise (ArduPlane positive radius): in ENU the yaw rate is negative
    assert s.yaw_rate_rad_s[0] < 0


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


def test_climb_to_target_altitude_within_pitch_limits() -> None:
    s = fleet()
    env = envelope(1)
    g = hold_guidance(s)
    g.kind[:] = GuidanceKind.GOTO
    g.target_enu_m[:] = (1e6, 0.0, 500.0)
    for _ in range(int(60 / DT_S)):
        s = step(s, env, g, DT_S)
        assert -0.4 - 1e-9 <= s.pitch_rad[0] <= 0.35 + 1e-9
    assert s.pos_enu_m[0, 2] == pytest.approx(500.0, abs=2.0)


def test_course_is_held_and_turned_onto_within_the_lateral_acceleration() -> None:
    s = fleet()  # east at 100 m/s
    env = envelope(1)
    g = hold_guidance(s)
    g.kind[:] = GuidanceKind.COURSE
    g.course_rad[:] = math.pi / 2  # north
    g.lateral_accel_m_s2[:] = 5.0  # 0.05 rad/s at 100 m/s, below ω_max = 0.52
    for _ in range(int(2.0 / DT_S)):
        n = step(s, env, g, DT_S)
        assert abs(float(n.yaw_rad[0] - s.yaw_rad[0])) <= 0.05 * DT_S + 1e-12
        s = n
    g.lateral_accel_m_s2[:] = np.inf
    for _ in range(int(20 / DT_S)):
        s = step(s, env, g, DT_S)
    assert s.yaw_rad[0] == pytest.approx(math.pi / 2, abs=1e-3)  # on the course, not circling
    x = s.pos_enu_m[0, 0]
    for _ in range(int(10 / DT_S)):
        s = step(s, env, g, DT_S)
    assert s.pos_enu_m[0, 0] == pytest.approx(x, abs=0.5)
    assert s.pos_enu_m[0, 1] > 900.0


def test_climb_rate_caps_the_vertical_speed_towards_the_target_altitude() -> None:
    s = fleet()
    env = envelope(1)
    g = hold_guidance(s)
    g.kind[:] = GuidanceKind.GOTO
    g.target_enu_m[:] = (1e6, 0.0, 800.0)
    g.climb_rate_m_s[:] = 5.0
    z0 = s.pos_enu_m[0, 2]
    for _ in range(int(20 / DT_S)):
        s = step(s, env, g, DT_S)
        assert s.speed_m_s[0] * math.sin(s.pitch_rad[0]) <= 5.0 + 1e-6
    assert 20 * 5.0 * 0.8 <= s.pos_enu_m[0, 2] - z0 <= 20 * 5.0


def test_glide_without_thrust_lands() -> None:
    s = fleet(z=50.0)
    env = envelope(1)
    g = hold_guidance(s)
    g.thrust[:] = False
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
    lateral=hs.floats(0.05, 1e3), climb=hs.floats(0.1, 1e3),
)  # fmt: skip
def test_limits_hold_for_any_command(
    x: float, y: float, z: float, yaw: float, v: float, cmd: float, kind: GuidanceKind,
    course: float, lateral: float, climb: float,
) -> None:  # fmt: skip
    s = fleet(speed=v, yaw=yaw)
    env = envelope(1)
    g = hold_guidance(s)
    g.kind[:] = kind
    g.target_enu_m[:] = (x, y, z)
    g.speed_cmd_m_s[:] = cmd
    g.course_rad[:] = course
    g.lateral_accel_m_s2[:] = lateral
    g.climb_rate_m_s[:] = climb
    for _ in range(20):
        n = step(s, env, g, DT_S)
        assert (
            abs(math.remainder(float(n.yaw_rad[0] - s.yaw_rad[0]), math.tau))
            <= math.pi / 6 * DT_S + 1e-9
        )
        if kind == GuidanceKind.COURSE:  # and no harder than the lateral acceleration allows
            turned = abs(math.remainder(float(n.yaw_rad[0] - s.yaw_rad[0]), math.tau))
            assert turned <= lateral / float(s.speed_m_s[0]) * DT_S + 1e-9
        assert abs(float(n.pitch_rad[0] - s.pitch_rad[0])) <= math.pi / 6 * DT_S + 1e-9
        assert -40.0 * DT_S - 1e-9 <= float(n.speed_m_s[0] - s.speed_m_s[0]) <= 10.0 * DT_S + 1e-9
        assert 100.0 <= n.speed_m_s[0] <= 300.0
        s = n

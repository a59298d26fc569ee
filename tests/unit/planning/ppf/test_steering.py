"""The shortcuts in steering and target following give what the angles they skip give."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from gcs_ppf.planning.ppf.primitives import (
    MAX_FOLLOW_PITCH,
    KernelLimits,
    follow_direction,
    to_vcs,
    trend,
)
from gcs_ppf.planning.ppf.steering import saturated_trend, trend_matrix

components = st.floats(-1e4, 1e4, allow_nan=False, allow_subnormal=False)
# Offsets in metres: zero, or at least a micrometre (squares of 1e-160 underflow to 0).
offsets = components.map(lambda v: 0.0 if abs(v) < 1e-6 else v)
steps = st.sampled_from([(math.radians(30.0), 0.01), (0.3, 0.02), (0.5, 0.1), (2.0, 1.0)])


@given(components, components, steps)
def test_saturated_trend_is_the_trend_of_the_angle(
    y: float, x: float, rate_dt: tuple[float, float]
) -> None:
    rate, dt = rate_dt
    assert saturated_trend(y, x, rate, dt) == trend(math.atan2(y, x), rate, dt)


@given(components, components)
def test_saturated_trend_near_straight_ahead_is_exact(y: float, x: float) -> None:
    """Tiny angles (the proportional part of the trend), where the shortcut must not cut."""
    x = abs(x) + 1.0
    y = y * 1e-7
    assert saturated_trend(y, x, 0.5, 0.01) == trend(math.atan2(y, x), 0.5, 0.01)


@given(offsets, offsets, offsets, st.floats(-math.pi, math.pi))
def test_follow_direction_is_the_clamped_unit_direction(
    gx: float, gy: float, gz: float, yaw: float
) -> None:
    """Eq. 14 as written with angles: the elevation of G clamped to ±MAX_FOLLOW_PITCH, in
    G's heading (the current heading when G is straight up or down)."""
    fx, fy, fz = follow_direction(gx, gy, gz, math.cos(yaw), math.sin(yaw))
    assert math.isclose(fx * fx + fy * fy + fz * fz, 1.0, rel_tol=1e-12)
    h = math.hypot(gx, gy)
    if h == 0.0 and gz == 0.0:
        assert (fx, fy, fz) == (math.cos(yaw), math.sin(yaw), 0.0)
        return
    elevation = min(max(math.atan2(gz, h), -MAX_FOLLOW_PITCH), MAX_FOLLOW_PITCH)
    hx, hy = (gx / h, gy / h) if h > 0.0 else (math.cos(yaw), math.sin(yaw))
    expected = (math.cos(elevation) * hx, math.cos(elevation) * hy, math.sin(elevation))
    for got, want in zip((fx, fy, fz), expected, strict=True):
        assert math.isclose(got, want, rel_tol=1e-12, abs_tol=1e-12)


PAPER = KernelLimits(40.0, 250.0, 10.0, 10.0, 0.5, 0.5, 10.0, 50.0, 25.0, -math.inf)


def _path_after(pitch: float, f_pitch: float, f_yaw: float, dt: float) -> tuple[float, ...]:
    """The flight direction (ICS) one step after heading east at ``pitch`` (Eq. 2–5)."""
    theta = pitch + f_pitch * PAPER.max_pitch_rate * dt
    psi = f_yaw * PAPER.max_yaw_rate * dt
    return (math.cos(theta) * math.cos(psi), math.cos(theta) * math.sin(psi), math.sin(theta))


def _angle(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    dot = sum(x * y for x, y in zip(a, b, strict=True))
    norm = math.sqrt(sum(x * x for x in a) * sum(y * y for y in b))
    return math.acos(max(-1.0, min(1.0, dot / norm)))


@given(st.floats(math.radians(46.0), math.radians(59.0)), st.floats(0.2, 1.2), st.booleans())
def test_sliding_steep_turns_faster_towards_the_wanted_direction(
    steepness: float, azimuth: float, diving: bool
) -> None:
    """A vehicle steeper than MAX_FOLLOW_PITCH sliding off an obstacle, wanting a direction
    at its own elevation but ``azimuth`` round (84105 of the 100,000-scene sweep): turning
    along the great circle closes the angle faster than Eq. 19 aimed at the wanted
    elevation, which only yaws, and never past it."""
    pitch = -steepness if diving else steepness
    cp, sp = math.cos(pitch), math.sin(pitch)
    wanted = (cp * math.cos(azimuth), cp * math.sin(azimuth), sp)
    fv = to_vcs(*wanted, cp, sp, 1.0, 0.0)
    dt = 0.1
    now = _angle((cp, 0.0, sp), wanted)
    sliding = trend_matrix(*fv, *wanted, pitch, -1.0, True, PAPER, dt)
    elevation = trend_matrix(*fv, *wanted, pitch, -1.0, False, PAPER, dt)  # Eq. 19's
    assert abs(elevation[0]) < 1e-9  # yaw alone
    after = _angle(_path_after(pitch, *sliding, dt), wanted)
    assert after < _angle(_path_after(pitch, *elevation, dt), wanted)
    assert after < now
    assert max(abs(sliding[0]), abs(sliding[1])) <= 1.0 + 1e-12

"""The shortcuts in steering and target following give what the angles they skip give; the
pitch law of a repelled vehicle turning sideways (Eq. 19)."""

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


def test_a_repelled_vehicle_is_not_steepened_away_from_the_wanted_elevation() -> None:
    """Diving at 40° and wanting a direction 90° to its right at −30° (below its tilted
    x_v-y_v plane, F_v^z < 0): Eq. 19's sign of F_v^z steepens the dive.  Repelled, it
    pitches for the wanted elevation instead (up); following its target, F_v^z as before."""
    pitch, yaw = math.radians(-40.0), 0.0
    cp, sp, cy, sy = math.cos(pitch), math.sin(pitch), math.cos(yaw), math.sin(yaw)
    el = math.radians(-30.0)
    dx, dy, dz = 0.0, -math.cos(el), math.sin(el)  # to the right (−y), 30° down
    fvx, fvy, fvz = to_vcs(dx, dy, dz, cp, sp, cy, sy)
    assert fvz < 0.0
    assert fvy < 0.0
    rate = math.pi / 6
    lim = KernelLimits(100.0, 300.0, 10.0, 40.0, rate, rate, 10.0, 50.0, 25.0, -math.inf)
    args = (fvx, fvy, fvz, dx, dy, dz, pitch, -1.0, lim, 0.01)
    assert trend_matrix(*args, False) == (-1.0, -1.0)  # F_v^z: down, and right
    assert trend_matrix(*args, True) == (1.0, -1.0)  # the wanted elevation: up

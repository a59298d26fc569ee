"""Assertions shared by tests: a plan's metrics against the mission's limits."""

from __future__ import annotations

from typing import Any

from gcs_ppf.mission import Limits

RATE_TOL = 1e-9  # rad/s, m/s: float noise of differences of recorded states
ACCEL_TOL = 1e-6  # m/s²: speed differences divided by Δt


def assert_within_kinematic_limits(metrics: dict[str, Any], lim: Limits) -> None:
    """Every step respects |Δθ|, |Δψ| ≤ ω·Δt, v in [v_min, v_max] and the accelerations."""
    assert metrics["max_pitch_rate_rad_s"] <= lim.max_pitch_rate + RATE_TOL
    assert metrics["max_yaw_rate_rad_s"] <= lim.max_yaw_rate + RATE_TOL
    assert metrics["min_speed_m_s"] >= lim.v_min - RATE_TOL
    assert metrics["max_speed_m_s"] <= lim.v_max + RATE_TOL
    assert metrics["max_accel_m_s2"] <= lim.accel + ACCEL_TOL
    assert metrics["max_decel_m_s2"] <= lim.decel + ACCEL_TOL

"""Assertions shared by tests: a plan's metrics against the mission's limits, and waiting
for something a real process does."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, TypeVar

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


T = TypeVar("T")


def wait_for(
    predicate: Callable[[], T | None], timeout_s: float, what: str, every_s: float = 0.2
) -> T:
    """``predicate()``'s first truthy value within ``timeout_s``; AssertionError if none."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s:g} s waiting for {what}")
        time.sleep(every_s)

"""Lag, measured: a vehicle's lag from our measurements, the fleet's worst, the budget's
events, and how long a command may have to hold."""

from __future__ import annotations

import pytest

from gcs_ppf.guidance.lag import Budget, Lag, hold_s, vehicle_lag, worst


def test_a_vehicles_lag_is_its_age_and_delay_in_its_own_seconds() -> None:
    lag = vehicle_lag(age_since_arrival_s=0.05, round_trip_s=0.2, tick_work_s=0.02, rate=5.0)
    assert lag.telemetry_age_s == pytest.approx((0.05 + 0.1) * 5.0)
    assert lag.command_delay_s == pytest.approx((0.02 + 0.1) * 5.0)
    assert lag.total_s == pytest.approx(lag.telemetry_age_s + lag.command_delay_s)
    assert vehicle_lag(0.05, None, 0.02, 1.0) == Lag(0.05, 0.02)


def test_the_fleets_lag_is_each_part_at_its_worst_vehicle() -> None:
    assert worst([Lag(0.5, 0.1), Lag(0.2, 0.4)]) == Lag(0.5, 0.4)
    assert worst([]) == Lag(0.0, 0.0)


def test_the_budget_says_when_the_lag_goes_over_and_when_it_is_well_back() -> None:
    b = Budget(1.0)
    assert b.update(0.5) is None
    assert b.update(1.2) == "lag_over_budget"
    assert b.update(1.5) is None
    assert b.update(0.9) is None  # not yet under 80 %
    assert b.update(0.7) == "lag_within_budget"
    assert b.worst_s == 1.5


def test_a_command_holds_until_a_tick_as_late_as_the_latest_ones_acts() -> None:
    delay = Lag(telemetry_age_s=0.4, command_delay_s=0.3)
    assert hold_s([], 0.1, 0.1, delay) == pytest.approx(0.1 + 0.1 + 0.3)
    assert hold_s([0.1, 0.1, 0.1], 0.1, 0.1, delay) == pytest.approx(0.5)
    # a stall of the ground station: the ticks came 2.5 s apart once
    assert hold_s([0.1, 2.5, 0.1], 0.1, 0.1, delay) == pytest.approx(2.5 + 0.1 + 0.3)


def test_a_command_holds_across_the_starvation_allowed_before_any_stall_was_seen() -> None:
    """Ticks on time say nothing of the next stall: 0.5 s of ours at 10x is 5 s of flight."""
    delay = Lag(telemetry_age_s=0.4, command_delay_s=0.3)
    assert hold_s([0.1] * 50, 0.1, 0.1, delay, starvation_s=5.0) == pytest.approx(
        0.1 + 5.0 + 0.1 + 0.3
    )
    # a stall longer than the allowance counts as it came
    assert hold_s([0.1, 8.0], 0.1, 0.1, delay, starvation_s=5.0) == pytest.approx(8.0 + 0.4)

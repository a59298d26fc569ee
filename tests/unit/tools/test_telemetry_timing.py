"""The telemetry timing report: how far a vehicle's clock, as read, strays from a steady one."""

from __future__ import annotations

import numpy as np
import pytest

from gcs_ppf.tools.telemetry_timing import reading_lag


def test_a_steady_clock_read_on_time_lags_nothing() -> None:
    read = np.arange(0.0, 20.0, 0.1)
    lag = reading_lag(read, 5.0 * read + 3.0)
    assert lag.rate == pytest.approx(5.0)
    assert max(lag.late_s) == pytest.approx(0.0, abs=1e-9)


def test_readings_late_by_up_to_80_ms_of_ours_at_5x_lag_up_to_0_4_vehicle_seconds() -> None:
    rng = np.random.default_rng(1)
    sent = np.arange(0.0, 60.0, 0.02)
    late = rng.uniform(0.0, 0.08, sent.size)
    lag = reading_lag(sent + late, 5.0 * sent)
    assert lag.rate == pytest.approx(5.0, rel=1e-3)
    p50, p90, p99 = lag.late_s
    assert p50 == pytest.approx(0.2, abs=0.02)  # half of 0.08 s of ours, ×5
    assert p99 == pytest.approx(0.4, abs=0.02)
    assert p50 < p90 < p99


def test_too_few_readings_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match="at least 3 readings"):
        reading_lag(np.array([0.0, 1.0]), np.array([0.0, 1.0]))

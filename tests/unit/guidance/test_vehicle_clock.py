"""The rate of a vehicle's clock against ours (timeouts in vehicle time)."""

from __future__ import annotations

import pytest

from gcs_ppf.guidance.vehicle_clock import VehicleClock


def test_a_sitl_at_10x_runs_ten_vehicle_seconds_per_second() -> None:
    clock = VehicleClock()
    for k in range(31):  # 3 s of ours at 10 Hz, the vehicle stamping 10× as much
        clock.observe(100.0 + 0.1 * k, 5_000 + 1000 * k)
    assert clock.rate == pytest.approx(10.0)
    assert clock.vehicle_seconds(0.5) == pytest.approx(5.0)


def test_a_real_time_vehicle_and_a_stalled_clock_count_our_seconds() -> None:
    real, stalled = VehicleClock(), VehicleClock()
    for k in range(31):
        real.observe(0.1 * k, 100 * k)
        stalled.observe(0.1 * k, 7)
    assert real.rate == pytest.approx(1.0)
    assert stalled.rate == 1.0  # never slower than ours
    assert stalled.vehicle_seconds(5.0) == 5.0


def test_a_reboot_restarts_the_measurement() -> None:
    clock = VehicleClock()
    for k in range(21):
        clock.observe(0.1 * k, 1_000_000 + 2000 * k)
    assert clock.rate == pytest.approx(20.0)
    clock.observe(2.1, 50)  # rebooted: its clock starts again near 0
    for k in range(1, 21):
        clock.observe(2.1 + 0.1 * k, 50 + 100 * k)
    assert clock.rate == pytest.approx(1.0)


def test_one_late_read_does_not_move_the_rate() -> None:
    """×10, read every 0.1 s of ours, 0.4 s late once (a busy ground station): the median
    keeps 10."""
    clock = VehicleClock()
    for k in range(80):
        now = 0.1 * k
        late = 0.4 if k == 45 else 0.0
        clock.observe(now + late, round(1000 * 10 * now))
    assert clock.rate == pytest.approx(10.0, rel=0.02)

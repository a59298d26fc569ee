"""A radio's budget: the rate that fits the vehicles it carries."""

from __future__ import annotations

import pytest

from gcs_ppf.mavlink.radio_budget import FULL, MIN_RATE_HZ, bytes_per_s, fitted_rate_hz


def test_the_model_gives_back_what_the_radios_measured() -> None:
    assert bytes_per_s(10.0) == pytest.approx((1600.0, 970.0))
    down, up = bytes_per_s(5.0)
    assert 0.91 <= 5 * down / 5760.0 <= 0.95  # five vehicles on one radio at 5 Hz
    assert 0.50 <= 5 * up / 5760.0 <= 0.53


@pytest.mark.parametrize(
    ("vehicles", "rate_hz"), [(1, 10.0), (3, 10.0), (4, 7.1), (5, 4.6), (6, 3.0), (20, 1.0)]
)
def test_a_57600_baud_radio_carries_three_at_10_hz_and_five_at_a_lower_rate(
    vehicles: int, rate_hz: float
) -> None:
    assert fitted_rate_hz(57_600, vehicles, 10.0) == rate_hz
    down, up = bytes_per_s(rate_hz)
    if rate_hz > MIN_RATE_HZ:  # within the budget, both ways
        assert vehicles * max(down, up) <= FULL * 5760.0


def test_a_fit_never_asks_more_than_wanted_and_a_faster_radio_fits_more() -> None:
    assert fitted_rate_hz(57_600, 1, 4.0) == 4.0
    assert fitted_rate_hz(115_200, 5, 10.0) == 10.0
    assert fitted_rate_hz(57_600, 0, 10.0) == 10.0

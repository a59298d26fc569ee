"""The MAVLink boundary: geodetic ↔ ENU and heading conversions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_ppf.geodesy import (
    enu_to_geodetic,
    enu_to_geodetic_many,
    geodetic_to_enu,
    geodetic_to_enu_many,
    heading_ned_to_yaw,
    velocity_enu_to_ned,
    velocity_ned_to_enu,
    yaw_to_heading_ned,
)
from gcs_ppf.mission import Origin

ORIGIN = Origin(lat=47.397742, lon=8.545594, alt=488.0)


@pytest.mark.parametrize(
    ("yaw", "heading_deg"),
    [(0.0, 90.0), (math.pi / 2, 0.0), (math.pi, 270.0), (-math.pi / 2, 180.0)],
)
def test_yaw_east_ccw_to_heading_north_cw(yaw: float, heading_deg: float) -> None:
    assert math.degrees(yaw_to_heading_ned(yaw)) == pytest.approx(heading_deg)
    assert math.cos(heading_ned_to_yaw(math.radians(heading_deg)) - yaw) == pytest.approx(1.0)


def test_north_of_origin_has_higher_latitude() -> None:
    lat, lon, alt = enu_to_geodetic(0.0, 1000.0, 100.0, ORIGIN)
    assert lat > ORIGIN.lat
    assert lon == pytest.approx(ORIGIN.lon, abs=1e-9)
    assert alt == pytest.approx(588.0, abs=0.1)
    assert geodetic_to_enu(lat, lon, alt, ORIGIN) == pytest.approx((0.0, 1000.0, 100.0), abs=1e-6)


def test_velocity_frames() -> None:
    assert velocity_enu_to_ned(1.0, 2.0, 3.0) == (2.0, 1.0, -3.0)
    assert velocity_ned_to_enu(*velocity_enu_to_ned(1.0, 2.0, 3.0)) == (1.0, 2.0, 3.0)


def test_many_at_once_is_one_at_a_time() -> None:
    """The batched conversions (a tick converts all its vehicles in one call) give what
    the single ones give, both ways."""
    enu = np.array([[0.0, 0.0, 0.0], [1500.0, -800.0, 300.0], [-2e4, 3e4, 1e3]])
    lat, lon, alt = enu_to_geodetic_many(enu, ORIGIN)
    for k, (e, n, u) in enumerate(enu):
        assert (lat[k], lon[k], alt[k]) == pytest.approx(enu_to_geodetic(e, n, u, ORIGIN), abs=1e-9)
    back = geodetic_to_enu_many(np.column_stack([lat, lon, alt]), ORIGIN)
    np.testing.assert_allclose(back, enu, atol=1e-6)
    assert geodetic_to_enu_many(np.array([[lat[1], lon[1], alt[1]]]), ORIGIN).shape == (1, 3)

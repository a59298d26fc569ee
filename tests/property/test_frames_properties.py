"""Frame round trips (hypothesis)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from gcs_ppf.frames import ics_to_vcs, local_target_point, vcs_to_ics, wrap_angle
from gcs_ppf.geodesy import (
    enu_to_geodetic,
    geodetic_to_enu,
    heading_ned_to_yaw,
    yaw_to_heading_ned,
)
from gcs_ppf.mission import Origin

pitch = st.floats(-math.pi / 2, math.pi / 2)
yaw = st.floats(-math.pi, math.pi)
metres = st.floats(-20_000.0, 20_000.0)
vec = st.tuples(metres, metres, metres)


@given(pitch, yaw, vec)
def test_vcs_ics_round_trip(p: float, y: float, v: tuple[float, float, float]) -> None:
    x = np.array(v)
    assert np.allclose(ics_to_vcs(p, y) @ (vcs_to_ics(p, y) @ x), x, atol=1e-6)
    r = vcs_to_ics(p, y)
    assert np.allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) > 0


@given(pitch, yaw, vec, vec)
def test_local_target_point_keeps_slot_distance(
    p: float, y: float, leader: tuple[float, float, float], slot: tuple[float, float, float]
) -> None:
    g = local_target_point(np.array(leader), p, y, np.array(slot))
    assert np.linalg.norm(g - np.array(leader)) == np.float64(np.linalg.norm(slot)) or math.isclose(
        float(np.linalg.norm(g - np.array(leader))), float(np.linalg.norm(slot)), abs_tol=1e-6
    )


@given(st.floats(-90.0, 90.0), st.floats(-180.0, 180.0), vec)
def test_enu_geodetic_round_trip(lat: float, lon: float, v: tuple[float, float, float]) -> None:
    origin = Origin(lat=max(min(lat, 89.0), -89.0), lon=lon, alt=100.0)
    back = geodetic_to_enu(*enu_to_geodetic(*v, origin), origin)
    assert np.allclose(back, v, atol=1e-3)


@given(yaw)
def test_heading_round_trip(y: float) -> None:
    assert math.isclose(wrap_angle(heading_ned_to_yaw(yaw_to_heading_ned(y)) - y), 0.0,
                        abs_tol=1e-12)  # fmt: skip

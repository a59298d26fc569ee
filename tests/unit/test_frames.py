"""Frames of the paper (Eq. 6–8, 16–18) and the erratum of Eq. 8."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_ppf.frames import (
    attitude_of,
    direction,
    ics_to_vcs,
    local_target_point,
    pitch_matrix_vcs_to_ics,
    vcs_to_ics,
    wrap_angle,
)


def printed_eq8(pitch: float) -> np.ndarray:
    c, s = math.cos(pitch), math.sin(pitch)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [s, 0.0, c]])


def test_printed_eq8_is_not_a_rotation_but_the_corrected_one_is() -> None:
    """Erratum 1: the printed Eq. 8 is not orthonormal; ours is the inverse of Eq. 17."""
    pitch = 0.4
    printed = printed_eq8(pitch)
    assert not np.allclose(printed @ printed.T, np.eye(3))
    corrected = pitch_matrix_vcs_to_ics(pitch)
    assert np.allclose(corrected @ corrected.T, np.eye(3))
    a_fv = np.array(
        [[math.cos(pitch), 0, math.sin(pitch)], [0, 1, 0], [-math.sin(pitch), 0, math.cos(pitch)]]
    )  # Eq. 17 as printed
    assert np.allclose(corrected @ a_fv, np.eye(3))


@pytest.mark.parametrize(("pitch", "yaw"), [(0.0, 0.0), (0.3, 1.0), (-0.7, -2.5), (1.2, 3.0)])
def test_vcs_axes(pitch: float, yaw: float) -> None:
    """VCS x is the velocity direction, y the left wing (horizontal), z up."""
    r = vcs_to_ics(pitch, yaw)
    assert np.allclose(r[:, 0], direction(pitch, yaw))
    assert r[2, 1] == pytest.approx(0.0)  # the wing is level
    assert np.cross(r[:, 0], r[:, 1]) @ np.array([0, 0, 1]) > 0  # y is to the left
    assert r[2, 2] > 0  # z points up
    assert np.allclose(ics_to_vcs(pitch, yaw), r.T)


def test_local_target_point_behind_and_left_of_a_climbing_leader() -> None:
    """Eq. 6: a slot behind the leader lies below it when the leader climbs."""
    leader = np.array([100.0, 200.0, 300.0])
    g = local_target_point(leader, math.radians(30), math.pi / 2, np.array([-100.0, 0.0, 0.0]))
    # heading north and climbing at 30°: 100 m behind is 86.6 m south and 50 m lower
    assert np.allclose(g, [100.0, 200.0 - 86.6025, 250.0], atol=1e-3)
    left = local_target_point(leader, 0.0, 0.0, np.array([0.0, 50.0, 0.0]))
    assert np.allclose(left, [100.0, 250.0, 300.0])  # heading east, left is north


def test_attitude_of_inverts_direction() -> None:
    for pitch, yaw in [(0.2, -3.0), (-1.0, 0.5), (0.0, math.pi)]:
        p, y = attitude_of(direction(pitch, yaw))
        assert p == pytest.approx(pitch)
        assert wrap_angle(y - yaw) == pytest.approx(0.0, abs=1e-12)


def test_wrap_angle_range() -> None:
    assert wrap_angle(-math.pi) == math.pi
    assert wrap_angle(3 * math.pi) == pytest.approx(math.pi)
    assert wrap_angle(0.5 + 4 * math.pi) == pytest.approx(0.5)

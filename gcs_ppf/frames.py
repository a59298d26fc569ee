"""Frames of the paper: the inertial frame (ICS, local ENU) and the vehicle frame (VCS).

VCS: x forward along the velocity, y to the left wing, z up (perpendicular to x in the
vertical plane).  Pitch θ is positive nose up, yaw ψ is measured from +x (east)
counter-clockwise.  All functions are pure and take radians.

Errata (CONVENTIONS §2):

1. Eq. 8 as printed, ``[[cos θ, 0, sin θ], [0, 1, 0], [sin θ, 0, cos θ]]``, is not a
   rotation.  The VCS → ICS pitch matrix is the transpose of Eq. 17:
   ``[[cos θ, 0, −sin θ], [0, 1, 0], [sin θ, 0, cos θ]]``
   (so that VCS +x maps to the velocity direction ``(cos θ cos ψ, cos θ sin ψ, sin θ)``).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def wrap_angle(angle: float) -> float:
    """Wrap an angle to (−π, π]."""
    wrapped = math.remainder(angle, math.tau)
    return math.pi if wrapped == -math.pi else wrapped


def yaw_matrix_vcs_to_ics(yaw: float) -> FloatArray:
    """A_vf(ψ) of Eq. 7: rotation by ψ about ICS z."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def pitch_matrix_vcs_to_ics(pitch: float) -> FloatArray:
    """B_vf(θ) of Eq. 8, corrected (erratum 1): the transpose of Eq. 17."""
    c, s = math.cos(pitch), math.sin(pitch)
    return np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])


def vcs_to_ics(pitch: float, yaw: float) -> FloatArray:
    """VCS → ICS rotation A_vf(ψ) · B_vf(θ) (Eq. 6–8)."""
    rotation: FloatArray = yaw_matrix_vcs_to_ics(yaw) @ pitch_matrix_vcs_to_ics(pitch)
    return rotation


def ics_to_vcs(pitch: float, yaw: float) -> FloatArray:
    """ICS → VCS rotation A_fv(θ) · B_fv(ψ) (Eq. 16–18); the transpose of ``vcs_to_ics``."""
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    a_fv = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])  # Eq. 17
    b_fv = np.array([[cy, sy, 0.0], [-sy, cy, 0.0], [0.0, 0.0, 1.0]])  # Eq. 18
    rotation: FloatArray = a_fv @ b_fv
    return rotation


def direction(pitch: float, yaw: float) -> FloatArray:
    """Unit velocity direction in the ICS for attitude (θ, ψ) (Eq. 5 divided by v)."""
    cp = math.cos(pitch)
    return np.array([cp * math.cos(yaw), cp * math.sin(yaw), math.sin(pitch)])


def attitude_of(vector: FloatArray) -> tuple[float, float]:
    """Pitch and yaw (θ, ψ) of an ICS direction; yaw is 0 for a vertical vector."""
    x, y, z = (float(c) for c in vector)
    return math.atan2(z, math.hypot(x, y)), math.atan2(y, x)


def local_target_point(
    leader_position: FloatArray, leader_pitch: float, leader_yaw: float, slot: FloatArray
) -> FloatArray:
    """Local path target point G_i of a wingman (Eq. 6): its slot, in the leader's VCS,
    carried into the ICS."""
    point: FloatArray = vcs_to_ics(leader_pitch, leader_yaw) @ slot + leader_position
    return point

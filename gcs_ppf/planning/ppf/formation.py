"""Formation forming and maintenance: the wingmen's local target points (Eq. 6–8), the
attraction towards a target point (Eq. 14–15) and the speed law (Eq. 21–24).

* ``formation_targets``  Eq. 6–8: local target points G_i; Eq. 24's condition (leader waits)
* ``attraction``         Eq. 14–15: towards the target point while nothing repels
* ``speed_trend``        Eq. 19's f_l with Eq. 21–24 (wingman braking, leader waiting)
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gcs_ppf.planning.ppf.primitives import (
    S3_FORMATION,
    KernelLimits,
    braking_speed,
    follow_direction,
    slot_to_ics,
    trend,
)


@njit(cache=True, inline="always")
def formation_targets(
    pos: np.ndarray,
    slot: np.ndarray,
    active: np.ndarray,
    trig: np.ndarray,
    direction: np.ndarray,
    lim: KernelLimits,
    local_target: np.ndarray,
    formed: np.ndarray,
) -> bool:
    """The wingmen's local target points G_i = P_0 + A_vf(ψ₀) B_vf(θ₀) s_i (Eq. 6–8) into
    ``local_target[N,3]``, whether each wingman is formed (within the target accuracy of
    G_i) into ``formed[N]``, and whether the leader must wait (s3, Eq. 24).

    The leader waits while a wingman is out of formation and has to catch up: its local
    target point is not behind it, or it does not yet fly the leader's way.  A wingman
    that flies the leader's way ahead of its slot cannot fall back while the leader flies
    at v_min: then the leader leads on (s1) and the slot comes to it.
    """
    lcp, lsp, lcy, lsy = trig[0, 0], trig[0, 1], trig[0, 2], trig[0, 3]
    leader_waits = False
    for i in range(pos.shape[0]):
        formed[i] = False
        gx, gy, gz = slot_to_ics(slot[i, 0], slot[i, 1], slot[i, 2], lcp, lsp, lcy, lsy)
        local_target[i, 0] = pos[0, 0] + gx
        local_target[i, 1] = pos[0, 1] + gy
        local_target[i, 2] = pos[0, 2] + gz
        if i == 0 or not active[i]:
            continue
        gx = local_target[i, 0] - pos[i, 0]
        gy = local_target[i, 1] - pos[i, 1]
        gz = local_target[i, 2] - pos[i, 2]
        formed[i] = gx * gx + gy * gy + gz * gz <= lim.target_accuracy**2
        along = gx * direction[0, 0] + gy * direction[0, 1] + gz * direction[0, 2]
        same_way = (
            direction[i, 0] * direction[0, 0]
            + direction[i, 1] * direction[0, 1]
            + direction[i, 2] * direction[0, 2]
        ) > 0.0
        leader_waits = leader_waits or (not formed[i] and (along >= 0.0 or not same_way))
    return leader_waits


@njit(cache=True, inline="always")
def attraction(
    i: int,
    pos: np.ndarray,
    target: np.ndarray,
    local_target: np.ndarray,
    direction: np.ndarray,
    lead: float,
    hold_course: bool,
    hx: float,
    hy: float,
    hz: float,
    cy: float,
    sy: float,
) -> tuple[float, float, float]:
    """The field on a vehicle nothing repels (Eq. 15 with F_r = 0): the unit attraction F_g
    (Eq. 14, ``follow_direction``) towards its target point.

    The leader's target point is the mission's target.  A wingman aims where its local
    target point G_i will be ``lead`` seconds (one turn time 1/ω) ahead: its estimate of
    the leader's motion.  Just clear of a teammate conflict (miss vectors summed in
    (hx, hy, hz)) the vehicle holds its course, but only if following would take off more
    of the miss than flying on would (a wingman whose slot lies away from the conflict
    turns for it at once).
    """
    px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
    if i == 0:
        gx, gy, gz = target[0] - px, target[1] - py, target[2] - pz
    else:
        gx = local_target[i, 0] + lead * direction[0, 0] - px
        gy = local_target[i, 1] + lead * direction[0, 1] - py
        gz = local_target[i, 2] + lead * direction[0, 2] - pz
    fx, fy, fz = follow_direction(gx, gy, gz, cy, sy)
    ux, uy, uz = direction[i, 0], direction[i, 1], direction[i, 2]
    if hold_course and fx * hx + fy * hy + fz * hz < ux * hx + uy * hy + uz * hz:
        return ux, uy, uz
    return fx, fy, fz


@njit(cache=True, inline="always")
def speed_trend(
    i: int,
    along_field: float,
    repelled: bool,
    leader_waits: bool,
    pos: np.ndarray,
    speed: np.ndarray,
    local_target: np.ndarray,
    direction: np.ndarray,
    formed: np.ndarray,
    lim: KernelLimits,
    dt: float,
    state: int,
) -> tuple[float, int]:
    """The speed entry f_l of the trend matrix (Eq. 19): the sign of F_v^x (``along_field``),
    except that the leader waits at low speed while the formation forms (s3, Eq. 24), and
    a wingman that nothing repels brakes so as to arrive at the leader's speed (Eq. 21–23,
    ``braking_speed``; s3 once d_i ≤ Δd'_i) or, with its slot behind it, gives the lost
    ground back.  Returns (f_l, the vehicle's state: ``state`` or s3).
    """
    f_speed = 1.0 if along_field > 0.0 else (-1.0 if along_field < 0.0 else 0.0)
    if i == 0:
        if leader_waits:
            return -1.0, S3_FORMATION
        return f_speed, state
    if repelled or not along_field > 0.0:
        return f_speed, state
    vi, v0 = speed[i], speed[0]
    ex = local_target[i, 0] - pos[i, 0]
    ey = local_target[i, 1] - pos[i, 1]
    ez = local_target[i, 2] - pos[i, 2]
    along = ex * direction[0, 0] + ey * direction[0, 1] + ez * direction[0, 2]
    if along >= 0.0:
        v_cmd = braking_speed(v0, math.sqrt(ex * ex + ey * ey + ez * ez), lim.decel)
        if not formed[i] and vi >= v_cmd:
            state = S3_FORMATION  # Eq. 23: d_i ≤ Δd'_i
    else:
        v_cmd = braking_speed(v0, along, lim.accel)
    a_cmd = lim.accel if v_cmd >= vi else lim.decel
    return trend(v_cmd - vi, a_cmd, dt), state

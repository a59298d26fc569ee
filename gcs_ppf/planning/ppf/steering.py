"""From the field F_v in the vehicle's frame to the pitch and yaw entries of the trend
matrix (Eq. 16–20 of the paper), with the choices where the paper is silent.

* ``escape_local_minimum``  Eq. 20: state s2, F_add along +z_v
* ``slide_along_obstacles`` Eq. 19's wanted direction around static obstacles
* ``flight_path_limited``   the wanted direction within the flight-path and ground limits
* ``trend_matrix``          Eq. 19: pitch and yaw entries of f (erratum 2)
* ``steer``                 all of the above in order, with ``away_from_obstacles``
"""

from __future__ import annotations

import math

from numba import njit

from gcs_ppf.planning.ppf.primitives import (
    EPSILON_1,
    INFLUENCE_STEPS,
    LOCAL_MINIMUM_ANGLE,
    MAX_FOLLOW_PITCH,
    S1_FOLLOW,
    S2_LOCAL_MINIMUM,
    SIDEWAYS_EPS,
    KernelLimits,
    airframe_limited,
    away_from_obstacles,
    from_vcs,
    limit_climb,
    lowest_climb,
    to_vcs,
    trend,
)


@njit(cache=True, inline="always")
def escape_local_minimum(fvx: float, fvy: float, fvz: float, repelled: bool) -> tuple[float, int]:
    """Local minimum (Eq. 20): a repulsion within ``LOCAL_MINIMUM_ANGLE`` of antiparallel to
    the velocity leaves no turn to take, so F_add = ε₁ along +z_v makes the vehicle pull up
    (state s2).  Takes the field F_v in the VCS; returns (F_v^z, state s1 or s2)."""
    if not (repelled and fvx < 0.0):
        return fvz, S1_FOLLOW
    f_norm = math.sqrt(fvx * fvx + fvy * fvy + fvz * fvz)
    lateral = math.sqrt(fvy * fvy + fvz * fvz)
    if lateral <= f_norm * math.sin(LOCAL_MINIMUM_ANGLE):
        return fvz + EPSILON_1, S2_LOCAL_MINIMUM
    return fvz, S1_FOLLOW


@njit(cache=True, inline="always")
def slide_along_obstacles(fvx: float, fvy: float, fvz: float) -> tuple[float, float, float]:
    """The wanted direction (VCS) around static obstacles, for Eq. 19 to turn towards.

    Eq. 19 turns towards F_v; around static obstacles the turn is needed only until the
    vehicle no longer closes on them.  So the wanted direction is the velocity projected
    onto the plane normal to the repulsion, x − (x·F̂)F̂, while F_v^x < 0, and straight
    ahead once F_v^x ≥ 0.  The turn's sense is still that of F_v^y and F_v^z; a full turn
    towards F_v would end flying straight away from the obstacle and then zigzag along its
    influence sphere.  (Moving threats keep the full turn.)
    """
    if fvx >= 0.0:
        return 1.0, 0.0, 0.0
    f_norm = math.sqrt(fvx * fvx + fvy * fvy + fvz * fvz)
    k_proj = fvx / (f_norm * f_norm)
    return 1.0 - k_proj * fvx, -k_proj * fvy, -k_proj * fvz


@njit(cache=True, inline="always")
def flight_path_limited(
    fvx: float,
    fvy: float,
    fvz: float,
    rx: float,
    ry: float,
    rz: float,
    tangent: bool,
    pz: float,
    vi: float,
    cp: float,
    sp: float,
    cy: float,
    sy: float,
    lim: KernelLimits,
    dt: float,
) -> tuple[float, float, float, float, float, float, float]:
    """The wanted direction F_v (VCS) no steeper than ``MAX_AVOID_PITCH`` or the airframe,
    and descending no more steeply than a full-rate pull-up can level out of above the
    ground (``limit_climb``, ``lowest_climb``; where the paper is silent).

    (rx, ry, rz) is the repulsion and ``tangent`` whether F_v slides along a static
    obstacle.  Returns (F_v in the VCS, the same direction d in the ICS, the sine of the
    lowest flight-path angle allowed).
    """
    height = pz - lim.ground - lim.safe_distance_obstacle - INFLUENCE_STEPS * vi * dt
    lowest = lowest_climb(height, vi, lim)
    dx, dy, dz = from_vcs(fvx, fvy, fvz, cp, sp, cy, sy)
    dx, dy, dz = limit_climb(dx, dy, dz, rx, ry, rz, tangent, cy, sy, lowest, lim)
    fvx, fvy, fvz = to_vcs(dx, dy, dz, cp, sp, cy, sy)
    return fvx, fvy, fvz, dx, dy, dz, lowest


@njit(cache=True, inline="always")
def saturated_trend(y: float, x: float, max_rate: float, dt: float) -> float:
    """``trend(atan2(y, x), max_rate, dt)``, the angle taken only where the trend is not
    saturated: within a step ω·Δt of straight ahead (x > 0, |y| ≤ x·tan ωΔt).  Outside it
    the angle is at least the step, and the trend is the sign of y ≠ 0: no ``atan2`` is
    taken while a vehicle turns at its full rate.  tan ωΔt is bounded above by
    ωΔt·(1 + (ωΔt)²) for ωΔt ≤ 1, with a relative 10⁻⁹ for round-off: a wider gate only
    takes the angle more often."""
    step = max_rate * dt
    if (
        y == 0.0
        or step >= 1.0
        or (x > 0.0 and abs(y) <= x * step * (1.0 + step * step) * (1.0 + 1e-9))
    ):
        return trend(math.atan2(y, x), max_rate, dt)
    return 1.0 if y > 0.0 else -1.0


@njit(cache=True, inline="always")
def trend_matrix(
    fvx: float,
    fvy: float,
    fvz: float,
    dx: float,
    dy: float,
    dz: float,
    pitch: float,
    lowest: float,
    lim: KernelLimits,
    dt: float,
    repelled: bool = False,
) -> tuple[float, float]:
    """The pitch and yaw entries of the trend matrix f (Eq. 19, erratum 2): pitch follows
    F_v^z, yaw follows F_v^y, each a saturated sign (``trend``).  (dx, dy, dz) is the
    wanted direction in the ICS, ``lowest`` the ground's limit (``flight_path_limited``)
    and ``repelled`` whether a repulsion makes the field.

    With the wanted direction behind, or a steep vehicle, the sign of F_v^z would pitch the
    nose on through the vertical (a loop; and a steep vehicle that yaws keeps steepening,
    its z_v tilted away from the wanted direction's vertical plane), which Eq. 1's pitch
    range [−π/2, π/2] rules out and where yaw loses its hold.  Then the vehicle goes for the
    wanted elevation in the ICS and turns round by yaw (to the left when straight behind).
    Near the ground too: while the vehicle yaws, F_v^z is not the flight-path angle still
    to climb, and the ground's limit is on the flight-path angle.  So are an airframe's
    limits (a leader climbing at 20° while it turned kept pitching up to 45° on F_v^z).
    So is a repelled vehicle whose F_v^z would steepen its climb or dive while the wanted
    elevation is shallower: pitched, its VCS is tilted, and a wanted direction far to the
    side lies below (diving) or above (climbing) its x_v-y_v plane though it is less steep.
    Diving at 45° and turning sideways round an obstacle, a wingman nodded down on F_v^z,
    was taken back by the wanted elevation once past 45° and hung there for a second,
    turning by yaw at only ω·cos θ, and came to 17.7 m of the obstacle's surface (safe
    25 m; feasible sweep, seed 2, scene 84105); pitching for the wanted elevation, 119.5 m.
    """
    wanted = math.sqrt(fvx * fvx + fvy * fvy + fvz * fvz)
    sideways = abs(fvy) > SIDEWAYS_EPS * wanted
    steep = fvx < 0.0 or abs(pitch) > MAX_FOLLOW_PITCH or lowest > -1.0 or airframe_limited(lim)
    if not sideways:
        f_yaw = 1.0 if steep and fvx < 0.0 else 0.0  # straight behind: round to the left
    else:
        f_yaw = saturated_trend(fvy, fvx, lim.max_yaw_rate, dt)
    if not steep:
        f_pitch = saturated_trend(fvz, math.sqrt(fvx * fvx + fvy * fvy), lim.max_pitch_rate, dt)
        if not (repelled and f_pitch * pitch > 0.0):  # (not steepening: no angle taken)
            return f_pitch, f_yaw
    elevation = math.atan2(dz, math.sqrt(dx * dx + dy * dy)) - pitch
    if not steep and f_pitch * elevation >= 0.0:  # steepening, and so is the wanted elevation
        return f_pitch, f_yaw
    return trend(elevation, lim.max_pitch_rate, dt), f_yaw


@njit(cache=True, inline="always")
def steer(
    fx: float,
    fy: float,
    fz: float,
    rx: float,
    ry: float,
    rz: float,
    ox: float,
    oy: float,
    oz: float,
    moving_threat: bool,
    z: float,
    speed: float,
    pitch: float,
    yaw: float,
    cp: float,
    sp: float,
    cy: float,
    sy: float,
    lim: KernelLimits,
    dt: float,
) -> tuple[float, float, float, int]:
    """The field F (ICS) on one vehicle to the pitch and yaw entries of the trend matrix
    (Eq. 16–20): into the VCS (Eq. 16–18), s2 (Eq. 20), the slide along static obstacles,
    the flight-path and ground limits, Eq. 19, and never a turn further into a repelling
    obstacle when the other way is not (``away_from_obstacles``).

    (rx, ry, rz) is the total repulsion, (ox, oy, oz) the obstacles' part of it,
    ``moving_threat`` whether a moving obstacle or a teammate repels; z, speed, pitch, yaw
    and cos/sin of pitch and yaw are the vehicle's.  Returns (f_θ, f_ψ, F_v^x before any
    change, which sets f_l; the state s1 or s2).
    """
    repelled = rx != 0.0 or ry != 0.0 or rz != 0.0
    fvx, fvy, fvz = to_vcs(fx, fy, fz, cp, sp, cy, sy)  # into the VCS (Eq. 16–18)
    along_field = fvx
    fvz, s = escape_local_minimum(fvx, fvy, fvz, repelled)  # s2 (Eq. 20)
    tangent = repelled and not moving_threat and fvx < 0.0
    if repelled and not moving_threat:
        fvx, fvy, fvz = slide_along_obstacles(fvx, fvy, fvz)
    fvx, fvy, fvz, dx, dy, dz, lowest = flight_path_limited(
        fvx, fvy, fvz, rx, ry, rz, tangent, z, speed, cp, sp, cy, sy, lim, dt
    )
    f_pitch, f_yaw = trend_matrix(fvx, fvy, fvz, dx, dy, dz, pitch, lowest, lim, dt, repelled)
    f_yaw = away_from_obstacles(pitch, yaw, f_pitch, f_yaw, ox, oy, oz, lim, dt)
    return f_pitch, f_yaw, along_field, s

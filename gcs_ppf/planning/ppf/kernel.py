"""The PPF formation planner's compiled kernel: one time step of the whole fleet.

Plain arrays in, plain arrays out; no I/O, no clock.  ``fleet_step`` is the paper's
algorithm for one step; each equation group it uses is a numba function of its own:

* ``unit_velocities``       Eq. 5 over v: each vehicle's flight direction
* ``formation_targets``     Eq. 6 (local target points G_i) and Eq. 24's condition (leader waits)
* ``obstacle_repulsion``    Eq. 10–13: ε₁ from every obstacle whose influence radius we are in
* ``teammate_conflicts``    Eq. 12–13 with teammates of higher priority as moving obstacles
* ``attraction``            Eq. 14–15: towards the target point while nothing repels
* ``escape_local_minimum``  Eq. 20: state s2, F_add along +z_v
* ``slide_along_obstacles`` Eq. 19's wanted direction around static obstacles
* ``flight_path_limited``   the wanted direction within the flight-path and ground limits
* ``trend_matrix``          Eq. 19: pitch and yaw entries of f (erratum 2)
* ``speed_trend``           Eq. 19's f_l with Eq. 21–24 (wingman braking, leader waiting)
* ``kinematics``            Eq. 3–5: the new speed, pitch and yaw
* ``fly``                   Eq. 5: one step of flight

The small formulas these are built from (frames, influence radius, saturated trend,
braking speed, flight-path limits) are in ``gcs_ppf.planning.ppf.primitives``.  The equation
groups are inlined into ``fleet_step`` by numba (``inline="always"``): left to LLVM, the
calls were not inlined and the step ran about twice as slow.

Fleet layout (structure of arrays, N vehicles, M obstacles):
``pos[N,3]`` ICS metres, ``pitch[N]``, ``yaw[N]`` radians, ``speed[N]`` m/s,
``slot[N,3]`` the wingman's place in the leader's VCS (zeros for the leader, index 0),
``rank[N]`` avoidance priority (a vehicle avoids every active vehicle of lower rank),
``active[N]`` (inactive vehicles are neither moved nor avoided),
``obs_center[M,3]``, ``obs_radius[M]``, ``obs_velocity[M,3]``.

Design choices where the paper is silent or cannot be used as printed are documented
next to the code that makes them; the README summarises them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gcs_ppf.planning.ppf.primitives import (
    AVOIDANCE_TURN_ANGLE,
    CONFLICT_HORIZON_TURNS,
    EPSILON_1,
    EPSILON_3,
    INFLUENCE_STEPS,
    LOCAL_MINIMUM_ANGLE,
    MAX_AVOID_PITCH,
    MAX_FOLLOW_PITCH,
    S1_FOLLOW,
    S2_LOCAL_MINIMUM,
    S3_FORMATION,
    SIDEWAYS_EPS,
    KernelLimits,
    airframe_limited,
    away_from_obstacles,
    braking_speed,
    closing_speed,
    follow_direction,
    from_vcs,
    influence_radius,
    limit_climb,
    lowest_climb,
    obstacles_first,
    slot_to_ics,
    to_vcs,
    trend,
)

__all__ = [
    "AVOIDANCE_TURN_ANGLE",
    "CONFLICT_HORIZON_TURNS",
    "EPSILON_1",
    "EPSILON_3",
    "INFLUENCE_STEPS",
    "LOCAL_MINIMUM_ANGLE",
    "MAX_AVOID_PITCH",
    "MAX_FOLLOW_PITCH",
    "S1_FOLLOW",
    "S2_LOCAL_MINIMUM",
    "S3_FORMATION",
    "SIDEWAYS_EPS",
    "KernelLimits",
    "airframe_limited",
    "attitude_trig",
    "attraction",
    "away_from_obstacles",
    "braking_speed",
    "escape_local_minimum",
    "fleet_step",
    "flight_path_limited",
    "fly",
    "follow_direction",
    "formation_targets",
    "from_vcs",
    "influence_radius",
    "kinematics",
    "limit_climb",
    "lowest_climb",
    "move",
    "move_obstacles",
    "obstacle_repulsion",
    "obstacles_first",
    "slide_along_obstacles",
    "slot_to_ics",
    "speed_trend",
    "teammate_conflict",
    "teammate_conflicts",
    "to_vcs",
    "trend",
    "trend_matrix",
    "unit_velocities",
]

NO_CONFLICT = 0  # a teammate that does not repel
JUST_CLEAR = 1  # a teammate conflict only just avoided: hold course
CONFLICT = 2  # a teammate that repels (a moving obstacle)


@njit(cache=True)
def attitude_trig(pitch: np.ndarray, yaw: np.ndarray, trig: np.ndarray) -> None:
    """cos θ, sin θ, cos ψ, sin ψ of every vehicle into ``trig[N, 0:4]``."""
    for i in range(pitch.shape[0]):
        trig[i, 0], trig[i, 1] = math.cos(pitch[i]), math.sin(pitch[i])
        trig[i, 2], trig[i, 3] = math.cos(yaw[i]), math.sin(yaw[i])


@njit(cache=True, inline="always")
def unit_velocities(speed: np.ndarray, trig: np.ndarray, direction: np.ndarray) -> None:
    """Each vehicle's flight direction, Eq. 5 divided by v, into ``direction[N,3]``, and its
    velocity (Eq. 5) into ``trig[N, 4:7]``, from cos/sin of pitch and yaw in ``trig[N, 0:4]``."""
    for i in range(speed.shape[0]):
        cp, sp, cy, sy = trig[i, 0], trig[i, 1], trig[i, 2], trig[i, 3]
        direction[i, 0] = cp * cy
        direction[i, 1] = cp * sy
        direction[i, 2] = sp
        for c in range(3):
            trig[i, 4 + c] = speed[i] * direction[i, c]


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
def obstacle_repulsion(
    i: int,
    pos: np.ndarray,
    speed: np.ndarray,
    obs_center: np.ndarray,
    obs_radius: np.ndarray,
    obs_velocity: np.ndarray,
    near_start: np.ndarray,
    near_obstacles: np.ndarray,
    lim: KernelLimits,
    dt: float,
) -> tuple[float, float, float, bool]:
    """Repulsion on vehicle i from the obstacles (Eq. 10–13): ε₁ along the outward normal
    from every obstacle whose influence radius R_j (Eq. 10–11, erratum 4: see
    ``influence_radius``) the vehicle is in.  R_j grows by a few steps of travel, by the
    obstacle's closing speed times a quarter-turn time, and for an ``airframe_limited``
    vehicle by one turn radius.  Only ``near_obstacles[near_start[i]:near_start[i+1]]``
    are looked at.  Returns (F_r, whether a repelling obstacle moves).
    """
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    vi = speed[i]
    px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
    rx, ry, rz = 0.0, 0.0, 0.0
    moving_threat = False
    rho = vi / omega
    half_turn = rho if airframe_limited(lim) else 0.0
    for c in range(near_start[i], near_start[i + 1]):
        j = near_obstacles[c]
        dx = px - obs_center[j, 0]
        dy = py - obs_center[j, 1]
        dz = pz - obs_center[j, 2]
        d2 = dx * dx + dy * dy + dz * dz
        keep_out = obs_radius[j] + lim.safe_distance_obstacle
        u_max = math.sqrt(
            obs_velocity[j, 0] ** 2 + obs_velocity[j, 1] ** 2 + obs_velocity[j, 2] ** 2
        )
        reach = (
            keep_out
            + rho
            + INFLUENCE_STEPS * vi * dt
            + u_max * AVOIDANCE_TURN_ANGLE / omega
            + half_turn
        )
        if d2 > reach * reach:  # cheap rejection: R ≤ keep_out + ρ
            continue
        d = math.sqrt(d2)
        closing = closing_speed(
            dx, dy, dz, d, obs_velocity[j, 0], obs_velocity[j, 1], obs_velocity[j, 2]
        )
        radius = influence_radius(vi, omega, keep_out) + INFLUENCE_STEPS * vi * dt
        radius += closing * AVOIDANCE_TURN_ANGLE / omega + half_turn
        if d <= radius and d > 0.0:
            rx += EPSILON_1 * dx / d
            ry += EPSILON_1 * dy / d
            rz += EPSILON_1 * dz / d
            moving_threat = moving_threat or u_max > 0.0
    return rx, ry, rz, moving_threat


@njit(cache=True, inline="always")
def teammate_conflict(
    dx: float,
    dy: float,
    dz: float,
    wx: float,
    wy: float,
    wz: float,
    vi: float,
    vk: float,
    lim: KernelLimits,
    dt: float,
) -> tuple[int, float, float, float]:
    """One teammate k of higher priority as a moving obstacle (Eq. 12–13, formation model).

    (dx, dy, dz) is vehicle i's offset from k, (wx, wy, wz) k's velocity relative to i.
    The mate repels (``CONFLICT``) only while the two close on each other and, within a
    quarter turn's time, would come nearer than the safe distance plus what turning at
    full rate could take off it (closest point of approach); mates flying alongside do
    not (``NO_CONFLICT``).  A moving obstacle repels from where it will be at the closest
    approach: along the miss vector, which is what widens the miss; radially when the two
    would meet head-on (then s2 decides the way out).  Within one more safe distance of a
    conflict it is ``JUST_CLEAR``: hold course rather than turn back into it (otherwise the
    turn flips every step along the conflict's edge).  Returns (kind, unit miss vector).
    """
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    approach = wx * dx + wy * dy + wz * dz  # > 0: the gap is shrinking
    w2 = wx * wx + wy * wy + wz * wz
    if approach <= 0.0 or w2 == 0.0:  # (w2 can underflow while approach does not)
        return NO_CONFLICT, 0.0, 0.0, 0.0
    d2 = dx * dx + dy * dy + dz * dz
    # Closest approach within the horizon (straight flight), and its time.
    t_cpa = min(approach / w2, CONFLICT_HORIZON_TURNS * AVOIDANCE_TURN_ANGLE / omega)
    miss2 = d2 - 2.0 * approach * t_cpa + w2 * t_cpa * t_cpa
    # Either vehicle may be turning at full rate meanwhile (½ v ω t² each, at most one
    # more safe distance).
    turning = min(0.5 * (vi + vk) * omega * t_cpa * t_cpa, lim.safe_distance_uav)
    threshold = lim.safe_distance_uav + (2.0 * vi * dt + turning)
    if miss2 >= (threshold + lim.safe_distance_uav) ** 2:
        return NO_CONFLICT, 0.0, 0.0, 0.0
    d = math.sqrt(d2)
    radius = influence_radius(vi, omega, lim.safe_distance_uav) + vi * dt
    radius += vk * AVOIDANCE_TURN_ANGLE / omega
    if d > radius or d == 0.0:
        return NO_CONFLICT, 0.0, 0.0, 0.0
    mx, my, mz = dx - wx * t_cpa, dy - wy * t_cpa, dz - wz * t_cpa
    miss = math.sqrt(mx * mx + my * my + mz * mz)
    if miss > 1e-6 * d:
        mx, my, mz = mx / miss, my / miss, mz / miss
    else:
        mx, my, mz = dx / d, dy / d, dz / d
    return (JUST_CLEAR if miss2 >= threshold * threshold else CONFLICT), mx, my, mz


@njit(cache=True, inline="always")
def teammate_conflicts(
    i: int,
    rx: float,
    ry: float,
    rz: float,
    pos: np.ndarray,
    speed: np.ndarray,
    trig: np.ndarray,
    mate_start: np.ndarray,
    mates: np.ndarray,
    lim: KernelLimits,
    dt: float,
) -> tuple[float, float, float, bool, bool, float, float, float]:
    """The repulsion (rx, ry, rz) on vehicle i with that of its teammates of higher
    priority (lower rank) added (Eq. 12–13; each one by ``teammate_conflict``).  Only
    ``mates[mate_start[i]:mate_start[i+1]]`` are looked at (see ``nearby_teammates``);
    ``trig[:, 4:7]`` are the velocities (``unit_velocities``).

    Returns (F_r, whether a mate repels, whether a conflict was only just avoided, the sum
    of those conflicts' miss vectors).
    """
    vi = speed[i]
    px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
    repelled_by_mate = False
    hold_course = False
    hx, hy, hz = 0.0, 0.0, 0.0
    for c in range(mate_start[i], mate_start[i + 1]):
        k = mates[c]
        kind, mx, my, mz = teammate_conflict(
            px - pos[k, 0],
            py - pos[k, 1],
            pz - pos[k, 2],
            trig[k, 4] - trig[i, 4],
            trig[k, 5] - trig[i, 5],
            trig[k, 6] - trig[i, 6],
            vi,
            speed[k],
            lim,
            dt,
        )
        if kind == JUST_CLEAR:
            hold_course = True
            hx, hy, hz = hx + mx, hy + my, hz + mz
        elif kind == CONFLICT:
            rx, ry, rz = rx + EPSILON_1 * mx, ry + EPSILON_1 * my, rz + EPSILON_1 * mz
            repelled_by_mate = True
    return rx, ry, rz, repelled_by_mate, hold_course, hx, hy, hz


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
def escape_local_minimum(fvx: float, fvy: float, fvz: float, repelled: bool) -> tuple[float, int]:
    """Local minimum (Eq. 20): a repulsion within ``LOCAL_MINIMUM_ANGLE`` of antiparallel to
    the velocity leaves no turn to take, so F_add = ε₁ along +z_v makes the vehicle pull up
    (state s2).  Takes the field F_v in the VCS; returns (F_v^z, state s1 or s2)."""
    f_norm = math.sqrt(fvx * fvx + fvy * fvy + fvz * fvz)
    lateral = math.sqrt(fvy * fvy + fvz * fvz)
    if repelled and fvx < 0.0 and lateral <= f_norm * math.sin(LOCAL_MINIMUM_ANGLE):
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
) -> tuple[float, float]:
    """The pitch and yaw entries of the trend matrix f (Eq. 19, erratum 2): pitch follows
    F_v^z, yaw follows F_v^y, each a saturated sign (``trend``).  (dx, dy, dz) is the
    wanted direction in the ICS and ``lowest`` the ground's limit (``flight_path_limited``).

    With the wanted direction behind, or a steep vehicle, the sign of F_v^z would pitch the
    nose on through the vertical (a loop; and a steep vehicle that yaws keeps steepening,
    its z_v tilted away from the wanted direction's vertical plane), which Eq. 1's pitch
    range [−π/2, π/2] rules out and where yaw loses its hold.  Then the vehicle goes for the
    wanted elevation in the ICS and turns round by yaw (to the left when straight behind).
    Near the ground too: while the vehicle yaws, F_v^z is not the flight-path angle still
    to climb, and the ground's limit is on the flight-path angle.  So are an airframe's
    limits (a leader climbing at 20° while it turned kept pitching up to 45° on F_v^z).
    """
    elevation = math.atan2(fvz, math.sqrt(fvx * fvx + fvy * fvy))
    wanted = math.sqrt(fvx * fvx + fvy * fvy + fvz * fvz)
    azimuth = math.atan2(fvy, fvx) if abs(fvy) > SIDEWAYS_EPS * wanted else 0.0
    if fvx < 0.0 or abs(pitch) > MAX_FOLLOW_PITCH or lowest > -1.0 or airframe_limited(lim):
        elevation = math.atan2(dz, math.sqrt(dx * dx + dy * dy)) - pitch
        if fvx < 0.0 and azimuth == 0.0:
            azimuth = math.pi
    return trend(elevation, lim.max_pitch_rate, dt), trend(azimuth, lim.max_yaw_rate, dt)


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


@njit(cache=True, inline="always")
def kinematics(
    speed: float,
    pitch: float,
    yaw: float,
    f_speed: float,
    f_pitch: float,
    f_yaw: float,
    lim: KernelLimits,
    dt: float,
) -> tuple[float, float, float]:
    """The new (speed, pitch, yaw) from the trend matrix f (Eq. 3–5):
    V(t) = V(t′) + f·Δt·a, speed within [v_min, v_max], pitch within [−π/2, π/2] (Eq. 1),
    yaw wrapped to (−π, π]."""
    a_l = lim.accel if f_speed > 0.0 else lim.decel
    v_new = min(max(speed + f_speed * a_l * dt, lim.v_min), lim.v_max)
    th = pitch + f_pitch * lim.max_pitch_rate * dt
    th = min(max(th, -0.5 * math.pi), 0.5 * math.pi)
    ps = yaw + f_yaw * lim.max_yaw_rate * dt
    if ps > math.pi:
        ps -= 2.0 * math.pi
    elif ps <= -math.pi:
        ps += 2.0 * math.pi
    return v_new, th, ps


@njit(cache=True, inline="always")
def fly(
    i: int,
    pos: np.ndarray,
    pitch: np.ndarray,
    yaw: np.ndarray,
    speed: np.ndarray,
    next_motion: np.ndarray,
    dt: float,
) -> tuple[float, float, float, float]:
    """Vehicle i takes the new (speed, pitch, yaw) of ``next_motion`` and flies one step
    (Eq. 5); returns cos θ, sin θ, cos ψ, sin ψ of its new attitude."""
    speed[i] = next_motion[i, 0]
    pitch[i] = next_motion[i, 1]
    yaw[i] = next_motion[i, 2]
    cp, sp = math.cos(pitch[i]), math.sin(pitch[i])
    cy, sy = math.cos(yaw[i]), math.sin(yaw[i])
    pos[i, 0] += speed[i] * cp * cy * dt
    pos[i, 1] += speed[i] * cp * sy * dt
    pos[i, 2] += speed[i] * sp * dt
    return cp, sp, cy, sy


@njit(cache=True)
def move_obstacles(obs_center: np.ndarray, obs_velocity: np.ndarray, dt: float) -> None:
    """Every obstacle moves one step at its constant velocity."""
    for j in range(obs_center.shape[0]):
        for c in range(3):
            obs_center[j, c] += obs_velocity[j, c] * dt


@njit(cache=True)
def move(
    pos: np.ndarray,
    pitch: np.ndarray,
    yaw: np.ndarray,
    speed: np.ndarray,
    active: np.ndarray,
    next_motion: np.ndarray,
    obs_center: np.ndarray,
    obs_velocity: np.ndarray,
    dt: float,
) -> None:
    """Take the new (speed, pitch, yaw) of ``next_motion`` and fly one step (Eq. 5);
    move the obstacles at their constant velocity."""
    for i in range(pos.shape[0]):
        if active[i]:
            fly(i, pos, pitch, yaw, speed, next_motion, dt)
    move_obstacles(obs_center, obs_velocity, dt)


@njit(cache=True)
def fleet_step(
    pos: np.ndarray,
    pitch: np.ndarray,
    yaw: np.ndarray,
    speed: np.ndarray,
    slot: np.ndarray,
    rank: np.ndarray,
    active: np.ndarray,
    obs_center: np.ndarray,
    obs_radius: np.ndarray,
    obs_velocity: np.ndarray,
    target: np.ndarray,
    lim: KernelLimits,
    dt: float,
    state: np.ndarray,
    avoiding: np.ndarray,
    formed: np.ndarray,
    direction: np.ndarray,
    local_target: np.ndarray,
    next_motion: np.ndarray,
    near_start: np.ndarray,
    near_obstacles: np.ndarray,
    mate_start: np.ndarray,
    mates: np.ndarray,
    trig: np.ndarray,
) -> None:
    """Advance the fleet one step Δt in place: the paper's algorithm (Eq. 3–24).

    ``state[N]`` receives each vehicle's PPF state (1, 2, 3), ``avoiding[N]`` whether an
    obstacle or teammate repels it, ``formed[N]`` whether a wingman is within the target
    accuracy of its local target point, ``local_target[N,3]`` the wingmen's local target
    points G_i (Eq. 6).  ``direction[N,3]`` and ``next_motion[N,3]`` are scratch space.
    Vehicle i considers only the obstacles ``near_obstacles[near_start[i]:near_start[i+1]]``
    (see ``nearby_obstacles``), and only the teammates ``mates[mate_start[i]:mate_start[i+1]]``
    (see ``nearby_teammates``; every active teammate of higher priority for all pairs).
    ``trig[N,7]`` holds cos θ, sin θ, cos ψ, sin ψ of every vehicle on entry
    (``attitude_trig``) and of its new attitude on return; its last columns are scratch.
    Every vehicle decides from the fleet's state at the start of the step.
    Obstacles are moved by their velocity at the end of the step.
    """
    n = pos.shape[0]
    unit_velocities(speed, trig, direction)  # Eq. 5
    leader_waits = formation_targets(pos, slot, active, trig, direction, lim, local_target, formed)
    lead = speed[0] / min(lim.max_pitch_rate, lim.max_yaw_rate)  # one turn time ahead
    for i in range(n):
        if not active[i]:
            continue
        cp, sp, cy, sy = trig[i, 0], trig[i, 1], trig[i, 2], trig[i, 3]
        # Repulsion (Eq. 12–13): the obstacles', then the teammates' of higher priority,
        # never pushing the vehicle into an obstacle (``obstacles_first``).
        ox, oy, oz, moving_obstacle = obstacle_repulsion(
            i, pos, speed, obs_center, obs_radius, obs_velocity, near_start, near_obstacles,
            lim, dt,
        )  # fmt: skip
        rx, ry, rz, mate, hold_course, hx, hy, hz = teammate_conflicts(
            i, ox, oy, oz, pos, speed, trig, mate_start, mates, lim, dt
        )
        rx, ry, rz = obstacles_first(rx, ry, rz, ox, oy, oz)
        repelled = rx != 0.0 or ry != 0.0 or rz != 0.0
        moving_threat = moving_obstacle or mate
        avoiding[i] = repelled
        # The field (Eq. 14–15): the repulsion alone while repelled, else the attraction.
        if repelled:
            fx, fy, fz = rx, ry, rz
        else:
            fx, fy, fz = attraction(
                i, pos, target, local_target, direction, lead, hold_course, hx, hy, hz, cy, sy
            )
        fvx, fvy, fvz = to_vcs(fx, fy, fz, cp, sp, cy, sy)  # into the VCS (Eq. 16–18)
        along_field = fvx  # F_v^x sets the speed trend f_l
        fvz, s = escape_local_minimum(fvx, fvy, fvz, repelled)  # s2 (Eq. 20)
        tangent = repelled and not moving_threat and fvx < 0.0
        if repelled and not moving_threat:
            fvx, fvy, fvz = slide_along_obstacles(fvx, fvy, fvz)
        fvx, fvy, fvz, dx, dy, dz, lowest = flight_path_limited(
            fvx, fvy, fvz, rx, ry, rz, tangent, pos[i, 2], speed[i], cp, sp, cy, sy, lim, dt
        )
        # Trend matrix f (Eq. 19): pitch, yaw (never further into a repelling obstacle
        # when the other way is not), speed (Eq. 21–24); then the kinematics (Eq. 3–5).
        f_pitch, f_yaw = trend_matrix(fvx, fvy, fvz, dx, dy, dz, pitch[i], lowest, lim, dt)
        f_yaw = away_from_obstacles(pitch[i], yaw[i], f_pitch, f_yaw, ox, oy, oz, lim, dt)
        f_speed, state[i] = speed_trend(
            i, along_field, repelled, leader_waits, pos, speed, local_target, direction,
            formed, lim, dt, s,
        )  # fmt: skip
        next_motion[i, 0], next_motion[i, 1], next_motion[i, 2] = kinematics(
            speed[i], pitch[i], yaw[i], f_speed, f_pitch, f_yaw, lim, dt
        )
    for i in range(n):  # Eq. 5: every vehicle flies its new motion
        if active[i]:
            trig[i, 0], trig[i, 1], trig[i, 2], trig[i, 3] = fly(
                i, pos, pitch, yaw, speed, next_motion, dt
            )
    move_obstacles(obs_center, obs_velocity, dt)

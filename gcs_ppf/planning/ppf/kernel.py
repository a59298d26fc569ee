"""The PPF formation planner's compiled kernel: one time step of the whole fleet.

Plain arrays in, plain arrays out; no I/O, no clock.  One numba function per equation
group of the paper, so the equations stay visible:

* ``influence_radius``      Eq. 10–11, corrected (CONVENTIONS §2 erratum 4)
* ``to_vcs``                Eq. 16–18 (ICS → VCS)
* ``slot_to_ics``           Eq. 6–8 (VCS → ICS, erratum 1: the pitch matrix transposed)
* ``trend``                 Eq. 19 (velocity change trend matrix f, erratum 2)
* ``braking_speed``         Eq. 21–23 (wingman deceleration ahead of its local target)
* ``fleet_step``            Eq. 9, 12–15, 20, 24 and the kinematics of Eq. 3–5

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
from typing import NamedTuple

import numpy as np
from numba import njit

S1_FOLLOW = 1  # target following and obstacle avoidance
S2_LOCAL_MINIMUM = 2  # local-minimum escape (Eq. 20)
S3_FORMATION = 3  # formation forming: leader waits, wingman brakes (Eq. 21–24)

EPSILON_1 = 1.0e6  # |F_j| inside an influence radius, ε₁ ≫ 1 (Eq. 13)
EPSILON_3 = 1.0e9  # braking vector of s3, ε₃ ≫ |F_v^sx| (Eq. 24)
LOCAL_MINIMUM_ANGLE = math.radians(1.0)  # repulsion this close to antiparallel → s2
AVOIDANCE_TURN_ANGLE = math.pi / 2  # a moving obstacle is out-turned in a quarter turn
MAX_FOLLOW_PITCH = math.pi / 4  # steepest flight path target following asks for
MAX_AVOID_PITCH = math.pi / 3  # steepest flight path any wanted direction may have
INFLUENCE_STEPS = 3.0  # steps of travel added to the influence radius (discrete turning)
SIDEWAYS_EPS = 1e-9  # |F_v^y| below this fraction of |F_v| counts as 0 in Eq. 19 (round-off)
CONFLICT_HORIZON_TURNS = 1.0  # teammate conflicts are looked for this many quarter turns ahead


class KernelLimits(NamedTuple):
    """The performance envelope and safety distances the kernel needs (SI units)."""

    v_min: float
    v_max: float
    accel: float
    decel: float
    max_pitch_rate: float
    max_yaw_rate: float
    target_accuracy: float
    safe_distance_uav: float
    safe_distance_obstacle: float
    ground: float
    """ICS z of the ground (flat), kept ``safe_distance_obstacle`` below every vehicle;
    −∞ for the paper's free space."""
    max_climb_angle: float = math.pi / 2
    """Steepest flight-path angle up the airframe flies (rad; ArduPlane PTCH_LIM_MAX_DEG);
    π/2 for the paper's vehicles, whose pitch is limited by Eq. 1 only."""
    max_dive_angle: float = math.pi / 2
    """Steepest flight-path angle down, as a positive angle (ArduPlane −PTCH_LIM_MIN_DEG)."""


@njit(cache=True)
def airframe_limited(lim: KernelLimits) -> bool:
    """Whether the airframe's flight-path limits bind before ``MAX_AVOID_PITCH`` does.

    Such a vehicle cannot climb over an obstacle in a quarter turn as the paper's can, and
    two obstacles whose keep-outs overlap make a wall it must turn back from: it starts
    avoiding one turn radius further out (room for a half turn), and its pitch follows the
    flight-path angle (see ``fleet_step``).  Flown closed loop at ArduPlane's +20°/−25°,
    Table 3's wall of 650 m spheres was entered by 3.5 m in 1 of 9 runs without the half
    turn; with it the closest any vehicle came to an obstacle in 5 runs was 240 m.
    """
    return min(lim.max_climb_angle, lim.max_dive_angle) < MAX_AVOID_PITCH


@njit(cache=True)
def influence_radius(speed: float, turn_rate: float, keep_out: float) -> float:
    """Distance from an obstacle's centre at which avoidance must begin (Eq. 10–11, erratum 4).

    A vehicle flying straight at the centre turns at full rate ω on a circle of radius
    ρ = v/ω (Fig. 2).  The circle's centre is ρ to the side of the vehicle, so its closest
    approach to the obstacle centre is √(d² + ρ²) − ρ.  Clearing the keep-out sphere
    (``keep_out`` = R_o + safe distance) needs √(d² + ρ²) − ρ ≥ keep_out, hence

        R = √((keep_out + ρ)² − ρ²).

    The printed Eq. 10, √((R_o + R_v)² − R_o²), swaps the roles of R_o and ρ and gives
    R < R_o for Table 3's 650 m and 850 m obstacles at 100 m/s.
    """
    rho = speed / turn_rate
    return math.sqrt((keep_out + rho) ** 2 - rho**2)


@njit(cache=True)
def to_vcs(
    fx: float, fy: float, fz: float, cp: float, sp: float, cy: float, sy: float
) -> tuple[float, float, float]:
    """ICS vector → VCS of a vehicle with cos/sin of pitch (cp, sp) and yaw (cy, sy):
    A_fv(θ) · B_fv(ψ) · F (Eq. 16–18)."""
    bx = cy * fx + sy * fy  # B_fv(ψ), Eq. 18
    by = -sy * fx + cy * fy
    return cp * bx + sp * fz, by, -sp * bx + cp * fz  # A_fv(θ), Eq. 17


@njit(cache=True)
def slot_to_ics(
    sx: float, sy_: float, sz: float, cp: float, sp: float, cy: float, sy: float
) -> tuple[float, float, float]:
    """Leader-VCS vector → ICS: A_vf(ψ₀) · B_vf(θ₀) · s (Eq. 6–8, erratum 1)."""
    px = cp * sx - sp * sz  # corrected B_vf(θ), erratum 1
    pz = sp * sx + cp * sz
    return cy * px - sy * sy_, sy * px + cy * sy_, pz  # A_vf(ψ), Eq. 7


@njit(cache=True)
def trend(angle: float, max_rate: float, dt: float) -> float:
    """One entry of the trend matrix f (Eq. 19), saturated: ``sign(angle)`` when the turn
    needed is at least one full step ω·Δt, proportional below it.

    A pure sign law turns by ±ω·Δt every step and chatters about the wanted direction;
    turning exactly the remaining angle keeps |Δ| ≤ ω·Δt (Table 1) without the chatter.
    """
    step = max_rate * dt
    if angle >= step:
        return 1.0
    if angle <= -step:
        return -1.0
    return angle / step


@njit(cache=True)
def braking_speed(leader_speed: float, distance: float, accel: float) -> float:
    """Speed from which a wingman can just match the leader's speed within ``distance``.

    Eq. 21–22 give the distance needed to slow from v_i to v_0 at a_i:
    Δt' = (v_i − v_0)/a_i and Δd' = v_i Δt' − a_i Δt'²/2, i.e. v_i² − v_0² = 2 a_i Δd'.
    Eq. 23 brakes (s3) once d_i ≤ Δd'; so the wingman's speed limit at distance d_i is
    √(v_0² + 2 a_i d_i).  A negative distance (slot behind) asks for the speed that gives
    the lost ground back at ``accel``.
    """
    v2 = leader_speed * leader_speed + 2.0 * accel * distance
    return math.sqrt(v2) if v2 > 0.0 else 0.0


@njit(cache=True)
def from_vcs(
    vx: float, vy: float, vz: float, cp: float, sp: float, cy: float, sy: float
) -> tuple[float, float, float]:
    """VCS vector → ICS: the transpose of ``to_vcs`` (Eq. 6–8, erratum 1)."""
    return slot_to_ics(vx, vy, vz, cp, sp, cy, sy)


@njit(cache=True)
def lowest_climb(height: float, speed: float, lim: KernelLimits) -> float:
    """sin of the steepest descent allowed ``height`` metres above the ground's keep-out.

    Pulling up at the full pitch rate ω from a flight-path angle γ < 0 traces an arc of
    radius ρ = v/ω and loses ρ(1 − cos γ) of height, so a vehicle still levels out above
    the keep-out if cos γ ≥ 1 − height/ρ.  ρ is taken at the speed the vehicle could reach
    while pulling up (a quarter turn at full acceleration).  Inside the keep-out (height
    < 0) the vehicle must climb, the steeper the deeper, up to ``MAX_FOLLOW_PITCH``.
    """
    omega = lim.max_pitch_rate
    v = min(speed + lim.accel * AVOIDANCE_TURN_ANGLE / omega, lim.v_max)
    rho = v / omega
    if height >= rho:  # even straight down levels out in time
        return -1.0
    if height >= 0.0:
        c = 1.0 - height / rho
        return -math.sqrt(1.0 - c * c)
    return min(-height / rho, math.sin(MAX_FOLLOW_PITCH))


@njit(cache=True)
def limit_climb(
    dx: float,
    dy: float,
    dz: float,
    nx: float,
    ny: float,
    nz: float,
    in_plane: bool,
    cy: float,
    sy: float,
    lowest: float,
    lim: KernelLimits,
) -> tuple[float, float, float]:
    """The wanted ICS direction d, no steeper than ``MAX_AVOID_PITCH`` nor than the
    airframe's flight-path limits (``lim.max_climb_angle``, ``lim.max_dive_angle``), and
    descending no more steeply than ``lowest`` (the sine of the lowest flight-path angle
    allowed, see ``lowest_climb``; −1 for no ground).  A plan steeper than the airframe
    flies is a plan it cannot follow: flown closed loop, a wingman planned to climb over an
    obstacle at up to 60° and climbing at ArduPlane's 20° came within 6 m of it.

    Pitch stops at ±π/2 (Eq. 1) and near it yaw no longer turns the flight direction, so
    a vehicle asked to steepen past the vertical would hang there, unable to turn.  When d
    slides along a static obstacle (``in_plane``: d lies in the plane normal to the
    repulsion n), the limited direction is the nearest one in that plane, so it still does
    not close on the obstacle; otherwise (or when no direction in the plane is allowed)
    d keeps its heading and takes the limit angle.
    """
    norm = math.sqrt(dx * dx + dy * dy + dz * dz)
    if norm == 0.0:
        return dx, dy, dz
    dx, dy, dz = dx / norm, dy / norm, dz / norm
    steepest = min(MAX_AVOID_PITCH, lim.max_climb_angle)
    deepest = min(MAX_AVOID_PITCH, lim.max_dive_angle)
    top = math.sin(steepest)
    low = min(max(lowest, -math.sin(deepest)), top)
    if low <= dz <= top:
        return dx, dy, dz
    z_new = min(max(dz, low), top)
    n = math.sqrt(nx * nx + ny * ny + nz * nz)
    e1n = math.sqrt(nx * nx + ny * ny)
    if in_plane and n > 0.0 and e1n > 1e-9 * n:
        nx, ny, nz = nx / n, ny / n, nz / n
        e1x, e1y = -ny / e1n * n, nx / e1n * n  # horizontal, in the plane
        e2x, e2y, e2z = -nz * e1y, nz * e1x, nx * e1y - ny * e1x  # n × e1: steepest
        if e2z < 0.0:
            e2x, e2y, e2z = -e2x, -e2y, -e2z
        b_new = z_new / e2z
        if -1.0 <= b_new <= 1.0:
            a = dx * e1x + dy * e1y
            a_new = math.copysign(math.sqrt(max(1.0 - b_new * b_new, 0.0)), a if a != 0.0 else 1.0)
            return (a_new * e1x + b_new * e2x, a_new * e1y + b_new * e2y, b_new * e2z)
    h = math.sqrt(dx * dx + dy * dy)
    hx, hy = (dx / h, dy / h) if h > 0.0 else (cy, sy)
    if z_new == top:
        c = math.cos(steepest)
    elif z_new == -math.sin(deepest):
        c = math.cos(deepest)
    else:
        c = math.sqrt(1.0 - z_new * z_new)
    return c * hx, c * hy, z_new


@njit(cache=True)
def follow_direction(
    gx: float, gy: float, gz: float, cy: float, sy: float
) -> tuple[float, float, float]:
    """Unit attraction towards (gx, gy, gz) (Eq. 14), no steeper than ``MAX_FOLLOW_PITCH``.

    Near the vertical the yaw of Eq. 5 no longer turns the flight direction, and the pitch
    of Eq. 1 stops at ±π/2: a vehicle sent straight up at a target above and behind it
    would stay vertical until its yaw came round.  A fixed wing climbs to a high target
    in a spiral instead, so target following asks for at most this flight-path angle
    (obstacle avoidance may still use the whole range).  With no horizontal component
    the current heading (cos ψ, sin ψ) is kept.
    """
    h = math.sqrt(gx * gx + gy * gy)
    if h == 0.0 and gz == 0.0:
        return cy, sy, 0.0
    cx_, cy_ = (gx / h, gy / h) if h > 0.0 else (cy, sy)
    elevation = min(max(math.atan2(gz, h), -MAX_FOLLOW_PITCH), MAX_FOLLOW_PITCH)
    ce = math.cos(elevation)
    return ce * cx_, ce * cy_, math.sin(elevation)


@njit(cache=True)
def away_from_obstacles(
    pitch: float,
    yaw: float,
    f_pitch: float,
    f_yaw: float,
    ox: float,
    oy: float,
    oz: float,
    lim: KernelLimits,
    dt: float,
) -> float:
    """The yaw trend, reversed if it would turn a vehicle closing on the obstacles that
    repel it (repulsion (ox, oy, oz)) further towards them while the other sense would not.

    Eq. 19 turns by the sense of F_v^y.  With a teammate's repulsion added to an obstacle's
    the sum can point behind the vehicle, and the short way round can pass through the
    obstacle (the vehicle sandwiched between the two).  The obstacle is the certain danger:
    the turn never makes the closing on it worse when the other way does not.
    """
    o = math.sqrt(ox * ox + oy * oy + oz * oz)
    if o == 0.0 or f_yaw == 0.0:
        return f_yaw
    cp = math.cos(pitch)
    now = cp * (math.cos(yaw) * ox + math.sin(yaw) * oy) + math.sin(pitch) * oz
    if now >= 0.0:  # not closing
        return f_yaw
    th = pitch + f_pitch * lim.max_pitch_rate * dt
    ct, st = math.cos(th), math.sin(th)
    turn = f_yaw * lim.max_yaw_rate * dt
    after = ct * (math.cos(yaw + turn) * ox + math.sin(yaw + turn) * oy) + st * oz
    other = ct * (math.cos(yaw - turn) * ox + math.sin(yaw - turn) * oy) + st * oz
    return -f_yaw if after < now and other > after else f_yaw


@njit(cache=True)
def obstacles_first(
    rx: float, ry: float, rz: float, ox: float, oy: float, oz: float
) -> tuple[float, float, float]:
    """The total repulsion (rx, ry, rz) with the teammates' part (total minus the
    obstacles' (ox, oy, oz)) stripped of any component against the obstacles' repulsion.

    Flown closed loop, a wingman sliding round an obstacle at ArduPlane's 20° climb limit
    was pushed into it by a teammate's repulsion (replayed from telemetry: 12.6 m into it;
    the same state without teammates cleared it by 99 m).  With the paper's free pitch the
    plan from that state comes to 40.9 m of the surface with the push, 74.3 m without it.
    """
    o2 = ox * ox + oy * oy + oz * oz
    if o2 == 0.0:
        return rx, ry, rz
    tx, ty, tz = rx - ox, ry - oy, rz - oz
    into = (tx * ox + ty * oy + tz * oz) / o2
    if into >= 0.0:
        return rx, ry, rz
    return rx - into * ox, ry - into * oy, rz - into * oz


@njit(cache=True)
def _closing_speed(
    dx: float, dy: float, dz: float, d: float, ux: float, uy: float, uz: float
) -> float:
    """Speed at which a point moving at u approaches a vehicle at offset (dx, dy, dz)."""
    if d <= 0.0:
        return 0.0
    c = (ux * dx + uy * dy + uz * dz) / d
    return c if c > 0.0 else 0.0


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
        if not active[i]:
            continue
        speed[i] = next_motion[i, 0]
        pitch[i] = next_motion[i, 1]
        yaw[i] = next_motion[i, 2]
        cp = math.cos(pitch[i])
        pos[i, 0] += speed[i] * cp * math.cos(yaw[i]) * dt
        pos[i, 1] += speed[i] * cp * math.sin(yaw[i]) * dt
        pos[i, 2] += speed[i] * math.sin(pitch[i]) * dt
    for j in range(obs_center.shape[0]):
        for c in range(3):
            obs_center[j, c] += obs_velocity[j, c] * dt


@njit(cache=True)
def nearby_obstacles(
    pos: np.ndarray,
    obs_center: np.ndarray,
    obs_radius: np.ndarray,
    obs_velocity: np.ndarray,
    lim: KernelLimits,
    dt: float,
    horizon_steps: int,
    near_start: np.ndarray,
    near_obstacles: np.ndarray,
) -> None:
    """The obstacles each vehicle could come under the influence of within the next
    ``horizon_steps`` steps (a neighbour list, so that a step need not look at all M).

    A vehicle is influenced from at most keep_out + v_max/ω + v_max·Δt + u·T (the cheap
    bound in ``fleet_step``; one v_max/ω more for an ``airframe_limited`` one); over the
    horizon the two close by at most (v_max + u)·steps·Δt.
    Fills ``near_obstacles`` in CSR form: vehicle i's are ``near_start[i]:near_start[i+1]``.
    """
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    turns = 2.0 if airframe_limited(lim) else 1.0  # the half turn of fleet_step
    count = 0
    for i in range(pos.shape[0]):
        near_start[i] = count
        for j in range(obs_center.shape[0]):
            u = math.sqrt(
                obs_velocity[j, 0] ** 2 + obs_velocity[j, 1] ** 2 + obs_velocity[j, 2] ** 2
            )
            reach = obs_radius[j] + lim.safe_distance_obstacle + turns * lim.v_max / omega
            reach += INFLUENCE_STEPS * lim.v_max * dt + u * AVOIDANCE_TURN_ANGLE / omega
            reach += (lim.v_max + u) * horizon_steps * dt
            dx = pos[i, 0] - obs_center[j, 0]
            dy = pos[i, 1] - obs_center[j, 1]
            dz = pos[i, 2] - obs_center[j, 2]
            if dx * dx + dy * dy + dz * dz <= reach * reach:
                near_obstacles[count] = j
                count += 1
    near_start[pos.shape[0]] = count


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
) -> None:
    """Advance the fleet one step Δt in place (Eq. 3–5, 9–24).

    ``state[N]`` receives each vehicle's PPF state (1, 2, 3), ``avoiding[N]`` whether an
    obstacle or teammate repels it, ``formed[N]`` whether a wingman is within the target
    accuracy of its local target point, ``local_target[N,3]`` the wingmen's local target
    points G_i (Eq. 6).  ``direction[N,3]`` and ``next_motion[N,3]`` are scratch space.
    Vehicle i considers only the obstacles ``near_obstacles[near_start[i]:near_start[i+1]]``
    (see ``nearby_obstacles``).
    Every vehicle decides from the fleet's state at the start of the step.
    Obstacles are moved by their velocity at the end of the step.
    """
    n = pos.shape[0]
    m = obs_center.shape[0]
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    limited = airframe_limited(lim)

    # Unit velocity directions at the start of the step (Eq. 5 divided by v), the cosines
    # and sines of pitch and yaw, and the obstacles' speeds.
    trig = np.empty((n, 4))
    for i in range(n):
        cp, sp = math.cos(pitch[i]), math.sin(pitch[i])
        cy, sy = math.cos(yaw[i]), math.sin(yaw[i])
        trig[i, 0], trig[i, 1], trig[i, 2], trig[i, 3] = cp, sp, cy, sy
        direction[i, 0] = cp * cy
        direction[i, 1] = cp * sy
        direction[i, 2] = sp
    obs_speed = np.empty(m)
    for j in range(m):
        obs_speed[j] = math.sqrt(
            obs_velocity[j, 0] ** 2 + obs_velocity[j, 1] ** 2 + obs_velocity[j, 2] ** 2
        )

    # Local target points of the wingmen (Eq. 6) and whether the formation is formed.
    lcp, lsp, lcy, lsy = trig[0, 0], trig[0, 1], trig[0, 2], trig[0, 3]
    v0 = speed[0]
    lead = v0 / omega  # horizon of the wingman's estimate of its moving target point
    # The leader waits (s3) while a wingman is out of formation and has to catch up: its
    # local target point is not behind it, or it does not yet fly the leader's way.  A
    # wingman that flies the leader's way ahead of its slot cannot fall back while the
    # leader flies at v_min: then the leader leads on (s1) and the slot comes to it.
    leader_waits = False
    for i in range(n):
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

    for i in range(n):
        if not active[i]:
            continue
        vi = speed[i]
        px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
        cp, sp, cy, sy = trig[i, 0], trig[i, 1], trig[i, 2], trig[i, 3]

        # Repulsion (Eq. 12–13): ε₁ from every obstacle whose influence radius we are in.
        rx = 0.0
        ry = 0.0
        rz = 0.0
        moving_threat = False  # a repelling obstacle or teammate that moves
        hold_course = False  # a teammate conflict was only just avoided …
        hx, hy, hz = 0.0, 0.0, 0.0  # … and the miss vectors of those conflicts
        rho = vi / omega
        half_turn = rho if limited else 0.0
        for c in range(near_start[i], near_start[i + 1]):
            j = near_obstacles[c]
            dx = px - obs_center[j, 0]
            dy = py - obs_center[j, 1]
            dz = pz - obs_center[j, 2]
            d2 = dx * dx + dy * dy + dz * dz
            keep_out = obs_radius[j] + lim.safe_distance_obstacle
            u_max = obs_speed[j]
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
            closing = _closing_speed(
                dx, dy, dz, d, obs_velocity[j, 0], obs_velocity[j, 1], obs_velocity[j, 2]
            )
            radius = influence_radius(vi, omega, keep_out) + INFLUENCE_STEPS * vi * dt
            radius += closing * AVOIDANCE_TURN_ANGLE / omega + half_turn
            if d <= radius and d > 0.0:
                rx += EPSILON_1 * dx / d
                ry += EPSILON_1 * dy / d
                rz += EPSILON_1 * dz / d
                moving_threat = moving_threat or u_max > 0.0

        # Teammates of higher priority are moving obstacles (formation model): a mate
        # repels only while the two close on each other and, within a quarter turn's time,
        # would come nearer than the safe distance plus what turning at full rate could
        # take off it (closest point of approach); mates flying alongside do not.
        ox, oy, oz = rx, ry, rz  # the obstacles' repulsion alone (see away_from_obstacles)
        for k in range(n):
            if k == i or not active[k] or rank[k] >= rank[i]:
                continue
            dx = px - pos[k, 0]
            dy = py - pos[k, 1]
            dz = pz - pos[k, 2]
            wx = speed[k] * direction[k, 0] - vi * direction[i, 0]  # mate relative to us
            wy = speed[k] * direction[k, 1] - vi * direction[i, 1]
            wz = speed[k] * direction[k, 2] - vi * direction[i, 2]
            approach = wx * dx + wy * dy + wz * dz  # > 0: the gap is shrinking
            w2 = wx * wx + wy * wy + wz * wz
            if approach <= 0.0 or w2 == 0.0:  # (w2 can underflow while approach does not)
                continue
            d2 = dx * dx + dy * dy + dz * dz
            # Closest approach within the horizon (straight flight), and its time.
            t_cpa = min(approach / w2, CONFLICT_HORIZON_TURNS * AVOIDANCE_TURN_ANGLE / omega)
            miss2 = d2 - 2.0 * approach * t_cpa + w2 * t_cpa * t_cpa
            # Either vehicle may be turning at full rate meanwhile (½ v ω t² each, at most
            # one more safe distance).
            turning = min(0.5 * (vi + speed[k]) * omega * t_cpa * t_cpa, lim.safe_distance_uav)
            margin = 2.0 * vi * dt + turning
            threshold = lim.safe_distance_uav + margin
            if miss2 >= (threshold + lim.safe_distance_uav) ** 2:
                continue
            d = math.sqrt(d2)
            radius = influence_radius(vi, omega, lim.safe_distance_uav) + vi * dt
            radius += speed[k] * AVOIDANCE_TURN_ANGLE / omega
            if d > radius or d == 0.0:
                continue
            # A moving obstacle repels from where it will be at the closest approach:
            # along the miss vector, which is what widens the miss; radially when the
            # two would meet head-on (then s2 decides the way out).
            mx = dx - wx * t_cpa
            my = dy - wy * t_cpa
            mz = dz - wz * t_cpa
            miss = math.sqrt(mx * mx + my * my + mz * mz)
            if miss > 1e-6 * d:
                mx, my, mz = mx / miss, my / miss, mz / miss
            else:
                mx, my, mz = dx / d, dy / d, dz / d
            if miss2 >= threshold * threshold:
                # Just clear of a conflict: hold course rather than turn back into it
                # (otherwise the turn flips every step along the conflict's edge).
                hold_course = True
                hx += mx
                hy += my
                hz += mz
            else:
                rx += EPSILON_1 * mx
                ry += EPSILON_1 * my
                rz += EPSILON_1 * mz
                moving_threat = True

        # A teammate never pushes a vehicle into a static obstacle: the part of the
        # teammates' repulsion against the obstacles' is dropped (obstacles come first).
        rx, ry, rz = obstacles_first(rx, ry, rz, ox, oy, oz)
        repelled = rx != 0.0 or ry != 0.0 or rz != 0.0
        avoiding[i] = repelled

        # Attraction (Eq. 14): unit vector to the target point, zero while repelled.
        if repelled:
            fx, fy, fz = rx, ry, rz  # Eq. 15 with |F_g| = 0
        else:
            if i == 0:
                gx = target[0] - px
                gy = target[1] - py
                gz = target[2] - pz
            else:
                # The wingman aims where its local target point will be one turn time
                # (1/ω) ahead: its estimate of the leader's motion.
                gx = local_target[i, 0] + lead * direction[0, 0] - px
                gy = local_target[i, 1] + lead * direction[0, 1] - py
                gz = local_target[i, 2] + lead * direction[0, 2] - pz
            fx, fy, fz = follow_direction(gx, gy, gz, cy, sy)
            # Hold course only if following would turn back into the conflict: take off
            # more of the miss than flying on would (a wingman whose slot lies away from
            # the conflict turns for it at once).
            ux, uy, uz = direction[i, 0], direction[i, 1], direction[i, 2]
            if hold_course and fx * hx + fy * hy + fz * hz < ux * hx + uy * hy + uz * hz:
                fx, fy, fz = ux, uy, uz

        # Into the VCS (Eq. 16–18).
        fvx, fvy, fvz = to_vcs(fx, fy, fz, cp, sp, cy, sy)
        along_field = fvx  # F_v^x, which sets the speed trend f_l
        s = S1_FOLLOW

        # s2: repulsion (anti)parallel to the velocity leaves no turn to take; add F_add
        # along +z_v so the vehicle pulls up (Eq. 20).
        f_norm = math.sqrt(fvx * fvx + fvy * fvy + fvz * fvz)
        lateral = math.sqrt(fvy * fvy + fvz * fvz)
        if repelled and fvx < 0.0 and lateral <= f_norm * math.sin(LOCAL_MINIMUM_ANGLE):
            fvz += EPSILON_1
            s = S2_LOCAL_MINIMUM
            f_norm = math.sqrt(fvx * fvx + fvy * fvy + fvz * fvz)

        # Eq. 19 turns towards F_v; around static obstacles the turn is needed only until
        # the vehicle no longer closes on them.  So the wanted direction is the velocity
        # projected onto the plane normal to the repulsion, x − (x·F̂)F̂, while F_v^x < 0,
        # and straight ahead once F_v^x ≥ 0.  The turn's sense is still that of F_v^y and
        # F_v^z; a full turn towards F_v would end flying straight away from the obstacle
        # and then zigzag along its influence sphere.  Moving threats keep the full turn.
        tangent = repelled and not moving_threat and fvx < 0.0
        if repelled and not moving_threat:
            if fvx >= 0.0:
                fvx, fvy, fvz = 1.0, 0.0, 0.0
            else:
                k_proj = fvx / (f_norm * f_norm)
                fvx, fvy, fvz = 1.0 - k_proj * fvx, -k_proj * fvy, -k_proj * fvz

        # No steeper than MAX_AVOID_PITCH or the airframe, no descent it could not level
        # out of above the ground (see ``limit_climb``, ``lowest_climb``), then back into the VCS.
        height = pz - lim.ground - lim.safe_distance_obstacle - INFLUENCE_STEPS * vi * dt
        lowest = lowest_climb(height, vi, lim)
        dx, dy, dz = from_vcs(fvx, fvy, fvz, cp, sp, cy, sy)
        dx, dy, dz = limit_climb(dx, dy, dz, rx, ry, rz, tangent, cy, sy, lowest, lim)
        fvx, fvy, fvz = to_vcs(dx, dy, dz, cp, sp, cy, sy)

        # Trend matrix f (Eq. 19, erratum 2): pitch follows F_v^z, yaw follows F_v^y.
        elevation = math.atan2(fvz, math.sqrt(fvx * fvx + fvy * fvy))
        wanted = math.sqrt(fvx * fvx + fvy * fvy + fvz * fvz)
        azimuth = math.atan2(fvy, fvx) if abs(fvy) > SIDEWAYS_EPS * wanted else 0.0
        if fvx < 0.0 or abs(pitch[i]) > MAX_FOLLOW_PITCH or lowest > -1.0 or limited:
            # Wanted direction behind, or a steep vehicle: the sign of F_v^z would pitch
            # the nose on through the vertical (a loop; and a steep vehicle that yaws keeps
            # steepening, its z_v tilted away from the wanted direction's vertical plane),
            # which Eq. 1's pitch range [−π/2, π/2] rules out and where yaw loses its hold.
            # Go for the wanted elevation in the ICS instead and turn round by yaw (to the
            # left when straight behind).  Near the ground too: while the vehicle yaws,
            # F_v^z is not the flight-path angle still to climb, and the ground's limit
            # (``lowest_climb``) is on the flight-path angle.  So are an airframe's limits
            # (a leader climbing at 20° while it turned kept pitching up to 45° on F_v^z).
            elevation = math.atan2(dz, math.sqrt(dx * dx + dy * dy)) - pitch[i]
            if fvx < 0.0 and azimuth == 0.0:
                azimuth = math.pi
        f_pitch = trend(elevation, lim.max_pitch_rate, dt)
        f_yaw = trend(azimuth, lim.max_yaw_rate, dt)
        f_yaw = away_from_obstacles(pitch[i], yaw[i], f_pitch, f_yaw, ox, oy, oz, lim, dt)

        # Speed trend f_l (Eq. 19).
        if along_field > 0.0:
            f_speed = 1.0
        elif along_field < 0.0:
            f_speed = -1.0
        else:
            f_speed = 0.0
        if i == 0:
            if leader_waits:  # Eq. 24: the leader waits at low speed (s3)
                f_speed = -1.0
                s = S3_FORMATION
        elif not repelled and along_field > 0.0:
            # Eq. 21–23: the wingman brakes so as to arrive at the leader's speed.
            ex = local_target[i, 0] - px
            ey = local_target[i, 1] - py
            ez = local_target[i, 2] - pz
            along = ex * direction[0, 0] + ey * direction[0, 1] + ez * direction[0, 2]
            if along >= 0.0:
                v_cmd = braking_speed(v0, math.sqrt(ex * ex + ey * ey + ez * ez), lim.decel)
                if not formed[i] and vi >= v_cmd:
                    s = S3_FORMATION  # Eq. 23: d_i ≤ Δd'_i
            else:
                v_cmd = braking_speed(v0, along, lim.accel)
            a_cmd = lim.accel if v_cmd >= vi else lim.decel
            f_speed = trend(v_cmd - vi, a_cmd, dt)
        state[i] = s

        # Kinematics (Eq. 3–5): V(t) = V(t') + f · Δt · a, within the limits.
        a_l = lim.accel if f_speed > 0.0 else lim.decel
        v_new = min(max(vi + f_speed * a_l * dt, lim.v_min), lim.v_max)
        th = pitch[i] + f_pitch * lim.max_pitch_rate * dt
        th = min(max(th, -0.5 * math.pi), 0.5 * math.pi)
        ps = yaw[i] + f_yaw * lim.max_yaw_rate * dt
        if ps > math.pi:
            ps -= 2.0 * math.pi
        elif ps <= -math.pi:
            ps += 2.0 * math.pi
        next_motion[i, 0] = v_new
        next_motion[i, 1] = th
        next_motion[i, 2] = ps

    move(pos, pitch, yaw, speed, active, next_motion, obs_center, obs_velocity, dt)

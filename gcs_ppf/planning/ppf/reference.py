"""A plain-numpy reference of one PPF step, vectorised over the fleet, to check the kernel.

The same equations as ``gcs_ppf.planning.ppf.kernel.fleet_step`` written with whole-array numpy
operations, one function per equation group: slower (docs/speed.md) but
short, and independent enough of the compiled kernel to check it in tests.  Same
arguments; returns new arrays (pos, pitch, yaw, speed, state) instead of updating in place.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from gcs_ppf.planning.ppf.formation import (
    CROSSING_CLEARANCE,
    CROSSING_REACH,
    TURN_KEEPING_REACH,
    just_reaching,
)
from gcs_ppf.planning.ppf.kernel import (
    AVOIDANCE_TURN_ANGLE,
    CONFLICT_HORIZON_TURNS,
    EPSILON_1,
    FRAME_TARGET_TURNS,
    HAND_BACK_TURNS,
    INFLUENCE_STEPS,
    LOCAL_MINIMUM_ANGLE,
    MAX_FOLLOW_PITCH,
    S1_FOLLOW,
    S2_LOCAL_MINIMUM,
    S3_FORMATION,
    SIDEWAYS_EPS,
    YIELD_BACK_TURNS,
    KernelLimits,
    airframe_limited,
    leader_limits,
    leader_speed_share,
    limit_climb,
    passing_limits,
    reaching_turn_rate,
    roll_in_lead,
    turn_missed_ahead,
    turning_speed,
    way_clear,
)
from gcs_ppf.planning.scene import BoolArray, FloatArray, IntArray

Step = tuple[FloatArray, FloatArray, FloatArray, FloatArray, IntArray]


class Attitude(NamedTuple):
    """cos θ, sin θ, cos ψ, sin ψ [N] of every vehicle, its flight direction u [N,3] (Eq. 5
    divided by v) and its velocity [N,3]."""

    cp: FloatArray
    sp: FloatArray
    cy: FloatArray
    sy: FloatArray
    u: FloatArray
    vel: FloatArray


class Formation(NamedTuple):
    """Eq. 6–8: local target points g [N,3], the offset to them, which vehicles are active
    wingmen and formed, the offset's component along the leader's flight direction, and
    the speed the leader waits at (Eq. 24; 0: it does not wait)."""

    g: FloatArray
    to_g: FloatArray
    wingman: BoolArray
    formed: BoolArray
    along: FloatArray
    wait_speed: float


class Repulsion(NamedTuple):
    """Eq. 12–13: the total repulsion, the obstacles' part steering keeps away from (none
    while a vehicle gives way to a teammate first), whether a moving threat (a moving
    obstacle or a teammate) repels, whether to hold course (just clear of a teammate
    conflict that following would turn into one), and whether the leader may go round the
    obstacles repelling it at its formation's turn rate (``_obstacle_repulsion``)."""

    rep: FloatArray
    obstacles: FloatArray
    moving: BoolArray
    hold: BoolArray
    formation_turn: bool = True


def _unit(v: FloatArray) -> FloatArray:
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    unit: FloatArray = np.divide(v, norm, out=np.zeros_like(v), where=norm > 0)
    return unit


def _attitude(pitch: FloatArray, yaw: FloatArray, speed: FloatArray) -> Attitude:
    cp, sp, cy, sy = np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    u = np.stack([cp * cy, cp * sy, sp], axis=1)  # flight directions (Eq. 5)
    return Attitude(cp, sp, cy, sy, u, speed[:, None] * u)


def _frame(
    pos: FloatArray,
    target: FloatArray,
    a: Attitude,
    leader_repelled: bool,
    leader_speed: float,
    lim: KernelLimits,
) -> tuple[float, float, float, float]:
    """cos θ₀, sin θ₀, cos ψ₀, sin ψ₀ the slots are placed in: the leader's VCS, or with
    ``lim.course_frame`` while obstacles repel it far from its target, level along its way
    to its target (the kernel's ``formation_frame``)."""
    frame = (float(a.cp[0]), float(a.sp[0]), float(a.cy[0]), float(a.sy[0]))
    hx, hy = float(target[0] - pos[0, 0]), float(target[1] - pos[0, 1])
    h = math.sqrt(hx * hx + hy * hy)
    near = FRAME_TARGET_TURNS * leader_speed / min(lim.max_pitch_rate, lim.max_yaw_rate)
    if not (lim.course_frame and leader_repelled) or h < near:
        return frame
    return 1.0, 0.0, hx / h, hy / h


def _formation(
    pos: FloatArray,
    slot: FloatArray,
    active: BoolArray,
    a: Attitude,
    lim: KernelLimits,
    frame: tuple[float, float, float, float],
) -> Formation:
    """Eq. 6–8 (corrected) in ``frame`` (``_frame``): local target points, formed, and
    whether the leader waits."""
    n = pos.shape[0]
    u = a.u
    cp, sp, cy, sy = frame
    sx, sy_, sz = slot.T
    px_ = cp * sx - sp * sz
    g = np.stack([cy * px_ - sy * sy_, sy * px_ + cy * sy_, sp * sx + cp * sz], 1)
    g = g + pos[0]
    to_g = g - pos
    wingman = active & (np.arange(n) > 0)
    formed = wingman & ((to_g**2).sum(1) <= lim.target_accuracy**2)
    along = to_g @ u[0]
    same_way = u @ u[0] > 0.0
    out = wingman & ~formed
    waits = out & ((along >= 0.0) | ~same_way)
    straight_ahead = (to_g**2).sum(1) <= 2.0 * along**2  # within 45° of ahead of the slot
    ahead = -along[out & ~waits & straight_ahead]  # flying the leader's way
    gain = min(lim.max_pitch_rate, lim.max_yaw_rate)
    give_back = _closing_excess(ahead, lim.accel, gain)
    wait_speed = min(lim.v_min + float(give_back.max(initial=0.0)), lim.v_max)
    return Formation(g, to_g, wingman, formed, along, wait_speed if waits.any() else 0.0)


def _obstacle_repulsion(
    pos: FloatArray,
    speed: FloatArray,
    u: FloatArray,
    obs_center: FloatArray,
    obs_radius: FloatArray,
    obs_velocity: FloatArray,
    lim: KernelLimits,
    dt: float,
    target: FloatArray,
) -> tuple[FloatArray, BoolArray, BoolArray, bool]:
    """Eq. 10–13: obstacles inside the influence radius repel with ε₁ (the leader's
    keep-outs padded by ``lim.leader_keep_out_pad`` where that leaves its target out, its
    turn round static ones its formation's where a turn away at that rate still clears
    them: the kernel's ``obstacle_repulsion``, whose last value is returned last).  Also [N]
    whether every repelling obstacle is static and leaves room for a full-rate turn away from it
    begun ``HAND_BACK_TURNS`` quarter turns and a few steps later (the kernel's
    ``room_to_turn_away``; ``u`` [N,3] the flight directions; never for an
    ``airframe_limited`` airframe, nor where the ground limits dives: the kernel's
    ``lowest_climb`` above −1)."""
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    d_obs = pos[:, None, :] - obs_center[None]  # [N,M,3]
    dist = np.linalg.norm(d_obs, axis=-1)
    u_obs = np.linalg.norm(obs_velocity, axis=-1)
    closing = np.maximum((d_obs * obs_velocity[None]).sum(-1) / np.where(dist > 0, dist, 1), 0)
    rho = (speed / omega)[:, None]
    own_keep = obs_radius + lim.safe_distance_obstacle
    keep = np.repeat(own_keep[None], pos.shape[0], 0)
    turn = np.repeat(rho, len(obs_radius), 1)
    s = (d_obs * u[:, None, :]).sum(-1)  # < 0: closing
    lateral = np.sqrt(np.maximum(dist**2 - s**2, 0.0))
    pad = lim.leader_keep_out_pad
    slow_refused = np.zeros(len(obs_radius), dtype=bool)  # static, a slow turn not clearing
    released = np.zeros(len(obs_radius), dtype=bool)  # the leader's way to its target clear
    if pad > 0.0:  # the leader's whole formation keeps out, the leader turning as it follows
        slow = speed[0] / min(omega, lim.leader_turn_rate)
        steps = INFLUENCE_STEPS * speed[0] * dt
        # … where its target lies beyond the reach the pad gives (the kernel's ``padding``)
        slow_j = np.where(u_obs == 0, slow, rho[0, 0])
        padded = keep[0] + pad
        reach = np.sqrt((padded + slow_j) ** 2 - slow_j**2) + steps
        reach = reach + (rho[0, 0] if airframe_limited(lim) else 0.0)
        far = np.linalg.norm(target - obs_center, axis=-1) > reach
        keep[0] = np.where(far, padded, keep[0])
        # … and lets it go where its way to the target clears the padded keep-out, if
        # holding its course to the edge of the influence would miss the target
        clear_by = padded + steps
        edge = np.sqrt((padded + slow) ** 2 - slow**2) + steps
        edge = edge + (rho[0, 0] if airframe_limited(lim) else 0.0)
        released = (
            (u_obs == 0)
            & far
            & _missed_ahead(pos[0], u[0], speed[0], target, obs_center, edge, lim)
            & _way_clear(pos[0], u[0], speed[0], target, obs_center, clear_by, lim)
        )
        after = dist[0] ** 2 + 2.0 * steps * s[0] + steps**2
        clears = (s[0] >= 0) | (after + 2.0 * slow * lateral[0] >= own_keep * (own_keep + 2 * slow))
        turn[0] = np.where((u_obs == 0) & clears & far, slow, turn[0])
        slow_refused = (u_obs == 0) & ~(clears & far) & (lim.leader_turn_rate < omega)
    radius = np.sqrt((keep + turn) ** 2 - turn**2) + INFLUENCE_STEPS * (speed * dt)[:, None]
    radius = radius + closing * AVOIDANCE_TURN_ANGLE / omega
    if airframe_limited(lim):
        radius = radius + rho  # room for a half turn (the kernel's half_turn)
    inside = (dist <= radius) & (dist > 0)
    inside[0] &= ~released
    rep = EPSILON_1 * (_unit(d_obs) * inside[..., None]).sum(1)
    moving = (inside & (u_obs[None] > 0)).any(1)
    hand_back = HAND_BACK_TURNS * AVOIDANCE_TURN_ANGLE * rho  # (the kernel's ``hand_back``)
    travel = (INFLUENCE_STEPS * speed * dt)[:, None] + hand_back
    after2 = dist**2 + 2.0 * travel * s + travel**2
    turns_away = (s >= 0) | (after2 + 2.0 * rho * lateral >= keep * (keep + 2.0 * rho))
    leaves_room = turns_away & (u_obs[None] == 0)
    height = pos[:, 2] - lim.ground - lim.safe_distance_obstacle - INFLUENCE_STEPS * speed * dt
    quarter_turn = AVOIDANCE_TURN_ANGLE / lim.max_pitch_rate
    rho_up = np.minimum(speed + lim.accel * quarter_turn, lim.v_max) / lim.max_pitch_rate
    free = (height >= rho_up) & (not airframe_limited(lim))  # the ground does not limit dives
    room = ~(inside & ~leaves_room).any(1) & free
    if (inside[0] & slow_refused).any():  # the paper's leader (the kernel's)
        paper = _obstacle_repulsion(
            pos,
            speed,
            u,
            obs_center,
            obs_radius,
            obs_velocity,
            lim._replace(leader_keep_out_pad=0.0),
            dt,
            target,
        )
        rep[0], moving[0], room[0] = paper[0][0], paper[1][0], paper[2][0]
        return rep, moving, room, False
    return rep, moving, room, True


def _missed_ahead(
    p: FloatArray,
    u: FloatArray,
    speed: float,
    target: FloatArray,
    obs_center: FloatArray,
    edge: FloatArray,
    lim: KernelLimits,
) -> BoolArray:
    """[M] whether the leader held on its course to ``edge`` from each obstacle's centre
    would find its target inside its formation's turn there (the kernel's
    ``turn_missed_ahead``)."""
    v = turning_speed(speed, lim)
    lead = roll_in_lead(v, lim)
    px, py, pz = (float(x) for x in p)
    ux, uy, uz = (float(x) for x in u)
    tx, ty = float(target[0]), float(target[1])
    missed = [
        bool(
            turn_missed_ahead(
                px, py, pz, ux, uy, uz, float(c[0]), float(c[1]), float(c[2]), float(r),
                lead, v, lim.leader_turn_rate, tx, ty,
            )
        )
        for c, r in zip(obs_center, edge, strict=True)
    ]  # fmt: skip
    return np.array(missed, dtype=np.bool_)


def _way_clear(
    p: FloatArray,
    u: FloatArray,
    speed: float,
    target: FloatArray,
    obs_center: FloatArray,
    keep_out: FloatArray,
    lim: KernelLimits,
) -> BoolArray:
    """[M] whether the leader at ``p`` flying along ``u`` keeps more than ``keep_out`` from
    each obstacle's centre on its way to ``target`` (the kernel's ``way_clear``, turning as
    ``leader_limits`` lets it: ``reaching_turn_rate``)."""
    h = math.hypot(float(u[0]), float(u[1]))
    if h <= 0.0:
        return np.zeros(len(obs_center), dtype=bool)
    hx, hy = float(u[0]) / h, float(u[1]) / h
    px, py, tx, ty = float(p[0]), float(p[1]), float(target[0]), float(target[1])
    reach = reaching_turn_rate(px, py, hx, hy, speed, lim, tx, ty)
    radius = turning_speed(speed, lim) / leader_limits(lim, reach).max_yaw_rate
    return np.array(
        [
            way_clear(px, py, hx, hy, radius, tx, ty, float(c[0]), float(c[1]), float(k))
            for c, k in zip(obs_center, keep_out, strict=True)
        ],
        dtype=bool,
    )


def _conflicts(
    pos: FloatArray,
    vel: FloatArray,
    mate_vel: FloatArray,
    speed: FloatArray,
    rank: IntArray,
    active: BoolArray,
    formed: BoolArray,
    lim: KernelLimits,
    dt: float,
    horizon_turns: float = CONFLICT_HORIZON_TURNS,
) -> tuple[BoolArray, BoolArray, FloatArray]:
    """Teammates of higher priority as moving obstacles, by closest point of approach
    within ``horizon_turns`` quarter turns: [i,k] whether mate k is near (a conflict or
    just clear of one) and a conflict for vehicle i flying ``vel[i]`` (mates at
    ``mate_vel``), and the unit miss vectors [i,k,3]."""
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    d_m = pos[:, None, :] - pos[None]  # [i,k,3]: from mate k to vehicle i
    w = mate_vel[None] - vel[:, None]  # mate k relative to vehicle i
    approach = (w * d_m).sum(-1)
    w2 = (w**2).sum(-1)
    horizon = horizon_turns * AVOIDANCE_TURN_ANGLE / omega
    t_cpa = np.minimum(np.divide(approach, w2, out=np.zeros_like(approach), where=w2 > 0), horizon)
    miss2 = (d_m**2).sum(-1) - 2 * approach * t_cpa + w2 * t_cpa**2
    leader = np.zeros(pos.shape[0], dtype=bool)
    leader[0] = True
    together = formed[:, None] & (formed | leader)[None]  # a pair in formation: no turning
    turning = np.where(together, 0.0, 0.5 * (speed[:, None] + speed[None]) * omega * t_cpa**2)
    margin = 2 * speed[:, None] * dt + np.minimum(turning, lim.safe_distance_uav)
    d2 = (d_m**2).sum(-1)
    mate_radius = (
        np.sqrt((lim.safe_distance_uav + speed / omega) ** 2 - (speed / omega) ** 2) + speed * dt
    )[:, None] + speed[None] * AVOIDANCE_TURN_ANGLE / omega
    threshold = lim.safe_distance_uav + margin
    near = (
        (rank[None] < rank[:, None])
        & active[None]
        & (approach > 0)
        & (w2 > 0)
        & (miss2 < (threshold + lim.safe_distance_uav) ** 2)
        & (d2 <= mate_radius**2)
        & (d2 > 0)
    )
    miss_vec = d_m - w * t_cpa[..., None]
    miss = np.linalg.norm(miss_vec, axis=-1)
    push = np.where((miss > 1e-6 * np.sqrt(d2))[..., None], _unit(miss_vec), _unit(d_m))
    return near, near & (miss2 < threshold**2), push


def _repulsion(
    pos: FloatArray,
    speed: FloatArray,
    a: Attitude,
    follow: FloatArray,
    rank: IntArray,
    active: BoolArray,
    formed: BoolArray,
    obstacles: tuple[FloatArray, BoolArray, BoolArray, bool],
    lim: KernelLimits,
    dt: float,
) -> Repulsion:
    """Eq. 12–13 with the teammates of higher priority as moving obstacles (``_conflicts``),
    added to the obstacles' repulsion (Eq. 10–13), never pushing a vehicle into an
    obstacle (the kernel's ``obstacles_first``).  Just clear of a conflict a vehicle holds
    course if flying ``follow`` (unit, [N,3]) at its speed would make it a conflict.  A
    conflict [i,k] within ``YIELD_BACK_TURNS`` quarter turns also pushes k, the other way
    (the kernel's ``yielding_back``).  A vehicle in a teammate conflict with room among
    the obstacles gives way to its teammates alone (the kernel's ``teammates_first``)."""
    n = pos.shape[0]
    rep, moving, room, formation_turn = obstacles
    near, threat, push = _conflicts(pos, a.vel, a.vel, speed, rank, active, formed, lim, dt)
    _, threat_after, _ = _conflicts(
        pos, speed[:, None] * follow, a.vel, speed, rank, active, formed, lim, dt
    )
    _, late, push_late = _conflicts(
        pos, a.vel, a.vel, speed, rank, active, formed, lim, dt, YIELD_BACK_TURNS
    )
    late = late & active[:, None]
    hold: BoolArray = np.any(near & ~threat & threat_after, axis=1)
    back = -(push_late * late[..., None]).sum(0)
    mates = EPSILON_1 * (push * threat[..., None]).sum(1) + EPSILON_1 * back
    total = rep + mates
    o2 = (rep**2).sum(1)
    into = np.divide(((total - rep) * rep).sum(1), o2, out=np.zeros(n), where=o2 > 0)
    total = total - np.minimum(into, 0.0)[:, None] * rep
    mate = threat.any(1) | late.any(0)
    first = (mate & room & (mates != 0).any(1))[:, None]
    total, rep = np.where(first, mates, total), np.where(first, 0.0, rep)
    return Repulsion(total, rep, moving | mate, hold, formation_turn)


def _whole(r: Repulsion, lim: KernelLimits) -> bool:
    """Whether the leader passes static obstacles with its whole formation (the kernel's
    ``whole``): it turns and cruises as its formation follows."""
    return lim.leader_keep_out_pad > 0.0 and not r.moving[0] and r.formation_turn


def _crossing(
    p: FloatArray, g: FloatArray, m: FloatArray, u: FloatArray, clearance: float, reach: float
) -> tuple[float, FloatArray]:
    """The kernel's ``crossing_point``: (s of the point Q of p→g nearest to m, the point
    to make for), or (−1, g) if p→g passes ``clearance`` or more from m or Q is p or g.
    The wingman heads along the tangent from p to the sphere of that radius round m, on
    Q's side with its part ahead of m along u dropped (above m if Q is on m's track), to
    the point ``reach`` (at most |g − p|) along it."""
    seg = g - p
    if seg @ seg == 0.0:  # as the kernel: a segment whose square underflows too
        return -1.0, g
    to_m = m - p
    s = float(to_m @ seg / (seg @ seg))
    side = s * seg - to_m  # Q − m
    if not 0.0 < s < 1.0 or side @ side >= clearance**2:
        return -1.0, g
    side = side - max(float(side @ u), 0.0) * u
    dist = float(np.linalg.norm(to_m))
    if dist <= 1e-9 * clearance:  # as the kernel: on the teammate
        return -1.0, g
    b = to_m / dist
    c = side - (side @ b) * b
    if np.linalg.norm(c) <= 1e-9 * clearance:
        c = np.array([0.0, 0.0, 1.0]) - b[2] * b
        if np.linalg.norm(c) == 0.0:  # as the kernel: a length whose square underflows
            c = u.copy()
    sin_a = min(clearance / dist, 1.0)
    heading = math.sqrt(1.0 - sin_a**2) * b + sin_a * c / np.linalg.norm(c)
    point: FloatArray = p + min(float(np.linalg.norm(seg)), reach) * heading
    return s, point


def _aims(
    pos: FloatArray,
    target: FloatArray,
    speed: FloatArray,
    a: Attitude,
    f: Formation,
    rank: IntArray,
    active: BoolArray,
    lim: KernelLimits,
    dt: float,
) -> FloatArray:
    """The points made for [N,3]: the mission target (the leader), G_i or the point to
    make for to pass a teammate of higher priority (``_crossing``; a wingman)."""
    n = pos.shape[0]
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    aim = f.g.copy()
    lead = speed[0] / omega
    r_mate = np.sqrt((lim.safe_distance_uav + speed / omega) ** 2 - (speed / omega) ** 2)
    for i in range(1, n):
        clearance = CROSSING_CLEARANCE * lim.safe_distance_uav + 2.0 * speed[i] * dt
        first = 2.0
        if np.sum((f.g[i] - pos[i]) ** 2) <= lim.target_accuracy**2:
            continue  # no way to pass anyone on
        for k in range(n):
            if k == i or not active[k] or rank[k] >= rank[i]:
                continue
            reach = r_mate[i] + speed[i] * dt + speed[k] * AVOIDANCE_TURN_ANGLE / omega
            reach = min(reach, CROSSING_REACH * lim.safe_distance_uav)
            if np.sum((pos[i] - pos[k]) ** 2) > reach**2:
                continue
            s, point = _crossing(pos[i], f.g[i], pos[k], a.u[0], clearance, lead)
            if 0.0 <= s < first:
                first, aim[i] = s, point
    aim[0] = target
    return aim


def _follow(
    pos: FloatArray,
    aim: FloatArray,
    speed: FloatArray,
    a: Attitude,
    lim: KernelLimits,
    g: FloatArray,
    leader_turn: float = 0.0,
) -> FloatArray:
    """Eq. 14: the unit attraction towards the points made for (``_aims``), a wingman's one
    turn time ahead along its slot's flight (the leader's, and in a held turn at
    ``leader_turn`` rad/s the slot's swing round it, ``g`` the local target points), no
    steeper than MAX_FOLLOW_PITCH."""
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    aim = aim.copy()
    aim[1:] += (speed[0] / omega) * a.u[0]
    rel = g[1:] - pos[0]
    aim[1:, 0] -= leader_turn / omega * rel[:, 1]
    aim[1:, 1] += leader_turn / omega * rel[:, 0]
    to_aim = aim - pos
    horizontal = np.hypot(to_aim[:, 0], to_aim[:, 1])
    heading = np.where(
        (horizontal > 0)[:, None],
        to_aim[:, :2] / np.where(horizontal > 0, horizontal, 1.0)[:, None],
        np.stack([a.cy, a.sy], axis=1),
    )
    elevation = np.clip(np.arctan2(to_aim[:, 2], horizontal), -MAX_FOLLOW_PITCH, MAX_FOLLOW_PITCH)
    follow: FloatArray = np.concatenate(
        [np.cos(elevation)[:, None] * heading, np.sin(elevation)[:, None]], axis=1
    )
    return follow


def _field(follow: FloatArray, a: Attitude, r: Repulsion) -> FloatArray:
    """Eq. 15: the repulsion alone while repelled, else the attraction, or the flight
    direction while holding course."""
    repelled = (r.rep != 0).any(1)
    field = np.where(repelled[:, None], r.rep, np.where(r.hold[:, None], a.u, follow))
    unit: FloatArray = np.where((np.linalg.norm(field, axis=1) > 0)[:, None], field, a.u)
    return unit


def _wanted_direction(
    field: FloatArray,
    pos: FloatArray,
    speed: FloatArray,
    a: Attitude,
    r: Repulsion,
    lim: KernelLimits,
    dt: float,
    pitch_rate: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray, BoolArray, FloatArray]:
    """Eq. 16–18 into the VCS, Eq. 20 (s2), the slide along static obstacles and the
    flight-path and ground limits (``pitch_rate`` [N] each vehicle's ω_θ).  Returns (F_v
    [N,3], the wanted ICS direction d [N,3], the sine of the lowest flight-path angle
    allowed, s2, F_v^x before any change)."""
    cp, sp, cy, sy = a.cp, a.sp, a.cy, a.sy
    n = pos.shape[0]
    repelled = (r.rep != 0).any(1)
    bx = cy * field[:, 0] + sy * field[:, 1]
    fvx = cp * bx + sp * field[:, 2]
    fvy = -sy * field[:, 0] + cy * field[:, 1]
    fvz = -sp * bx + cp * field[:, 2]
    along_field = fvx.copy()

    # Eq. 20: local minimum → F_add along +z_v.
    norm = np.sqrt(fvx**2 + fvy**2 + fvz**2)
    s2 = repelled & (fvx < 0) & (np.hypot(fvy, fvz) <= norm * math.sin(LOCAL_MINIMUM_ANGLE))
    fvz = fvz + np.where(s2, EPSILON_1, 0.0)
    norm = np.sqrt(fvx**2 + fvy**2 + fvz**2)

    # Static obstacles: turn only until no longer closing (projection onto the tangent plane).
    project = repelled & ~r.moving
    k = np.divide(fvx, norm**2, out=np.zeros_like(fvx), where=norm > 0)
    closing_in = project & (fvx < 0)
    hold = project & (fvx >= 0)
    fvx, fvy, fvz = (
        np.where(closing_in, 1 - k * fvx, np.where(hold, 1.0, fvx)),
        np.where(closing_in, -k * fvy, np.where(hold, 0.0, fvy)),
        np.where(closing_in, -k * fvz, np.where(hold, 0.0, fvz)),
    )

    # No descent that could not level out above the ground's keep-out: pulling up at
    # ω_θ on an arc of radius v/ω_θ loses ρ(1 − cos γ) (the kernel's lowest_climb).
    height = pos[:, 2] - lim.ground - lim.safe_distance_obstacle - INFLUENCE_STEPS * speed * dt
    quarter_turn = AVOIDANCE_TURN_ANGLE / pitch_rate
    rho_up = np.minimum(speed + lim.accel * quarter_turn, lim.v_max) / pitch_rate
    ratio = np.minimum(height / rho_up, 1.0)
    lowest = np.where(
        ratio >= 0.0,
        -np.sqrt(1.0 - (1.0 - np.maximum(ratio, 0.0)) ** 2),
        np.minimum(-ratio, math.sin(MAX_FOLLOW_PITCH)),
    )

    # No steeper than MAX_AVOID_PITCH or the airframe (the kernel's limit_climb, by vehicle);
    # the leader following its target within its share of it (``leader_limits``).
    px_ = cp * fvx - sp * fvz  # VCS → ICS
    d = np.stack([cy * px_ - sy * fvy, sy * px_ + cy * fvy, sp * fvx + cp * fvz], axis=1)
    for i in range(n):
        d[i] = limit_climb(
            d[i, 0],
            d[i, 1],
            d[i, 2],
            r.rep[i, 0],
            r.rep[i, 1],
            r.rep[i, 2],
            bool(closing_in[i]),
            cy[i],
            sy[i],
            float(lowest[i]),
            leader_limits(lim) if i == 0 and (not repelled[i] or _whole(r, lim)) else lim,
        )
    bx = cy * d[:, 0] + sy * d[:, 1]  # ICS → VCS
    fv = np.stack(
        [cp * bx + sp * d[:, 2], -sy * d[:, 0] + cy * d[:, 1], -sp * bx + cp * d[:, 2]], 1
    )
    return fv, d, lowest, s2, along_field


def _turn_trends(
    fv: FloatArray,
    d: FloatArray,
    lowest: FloatArray,
    pitch: FloatArray,
    yaw: FloatArray,
    a: Attitude,
    r: Repulsion,
    lim: KernelLimits,
    dt: float,
    yaw_rate: FloatArray,
    pitch_rate: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Eq. 19 (erratum 2), saturated: the pitch and yaw entries of the trend matrix, the
    yaw never turning further towards a repelling obstacle when the other sense does not
    (the kernel's ``away_from_obstacles``), the pitch for the wanted elevation in the ICS
    where the kernel's ``trend_matrix`` takes it; ``yaw_rate`` and ``pitch_rate`` [N] each
    vehicle's ω_ψ and ω_θ."""
    fvx, fvy, fvz = fv.T
    elevation = np.arctan2(fvz, np.hypot(fvx, fvy))
    behind = np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1])) - pitch
    ics = (fvx < 0) | (np.abs(pitch) > MAX_FOLLOW_PITCH) | (lowest > -1.0)
    ics |= airframe_limited(lim)
    # Repelled, F_v^z steepening it away from the wanted elevation (the kernel's
    # ``trend_matrix``): the wanted elevation in the ICS instead.
    vcs = np.clip(elevation / (pitch_rate * dt), -1, 1)
    ics |= (r.rep != 0).any(1) & (vcs * pitch > 0) & (vcs * behind < 0)
    elevation = np.where(ics, behind, elevation)
    wanted = np.sqrt(fvx**2 + fvy**2 + fvz**2)
    azimuth = np.where(np.abs(fvy) > SIDEWAYS_EPS * wanted, np.arctan2(fvy, fvx), 0.0)
    azimuth = np.where((fvx < 0) & (azimuth == 0.0), math.pi, azimuth)
    f_pitch = np.clip(elevation / (pitch_rate * dt), -1, 1)
    f_yaw = np.clip(azimuth / (yaw_rate * dt), -1, 1)
    o = r.obstacles
    now = (a.u * o).sum(1)
    th = pitch + f_pitch * pitch_rate * dt
    turn = f_yaw * yaw_rate * dt

    def towards(psi: FloatArray) -> FloatArray:
        along: FloatArray = np.cos(th) * (np.cos(psi) * o[:, 0] + np.sin(psi) * o[:, 1])
        along = along + np.sin(th) * o[:, 2]
        return along

    after, other = towards(yaw + turn), towards(yaw - turn)
    reverse = (now < 0) & (f_yaw != 0) & (after < now) & (other > after)
    return f_pitch, np.where(reverse, -f_yaw, f_yaw)


def _speed_trend(
    along_field: FloatArray,
    pos: FloatArray,
    aim: FloatArray,
    speed: FloatArray,
    a: Attitude,
    f: Formation,
    r: Repulsion,
    state: IntArray,
    lim: KernelLimits,
    dt: float,
    leader_turn: float = 0.0,
) -> FloatArray:
    """Eq. 19's f_l with Eq. 21–24: the leader slows to its wait speed (s3); wingmen brake
    to arrive at the leader's speed, Eq. 21–23 relative to the moving local target point
    (s3 once d_i ≤ Δd'_i), or give ground back (the kernel's ``catching_up_speed`` and
    ``falling_back_speed``), also going round an obstacle with the slot behind; in a held
    turn (the leader turning at ``leader_turn`` rad/s) at the speed of their slots (the
    kernel's ``slot_point_speed``).  Sets ``state``."""
    repelled = (r.rep != 0).any(1)
    f_speed = np.sign(along_field)
    if f.wait_speed > 0.0:
        a_wait = lim.accel if f.wait_speed >= speed[0] else lim.decel
        f_speed[0] = np.clip((f.wait_speed - speed[0]) / (a_wait * dt), -1.0, 1.0)
        state[0] = S3_FORMATION
    elif (not repelled[0] or _whole(r, lim)) and lim.leader_cruise_speed < lim.v_max:
        cruise = max(lim.leader_cruise_speed, lim.v_min)
        a_cruise = lim.accel if cruise >= speed[0] else lim.decel
        f_speed[0] = np.clip((cruise - speed[0]) / (a_cruise * dt), -1.0, 1.0)
    along = (aim - pos) @ a.u[0]  # to the point made for, along the leader's track
    round_obstacle = repelled & ~r.moving  # gives the ground back (``speed_trend``)
    follow = f.wingman & (along_field > 0) & (~repelled | (round_obstacle & (along < 0)))
    gain = min(lim.max_pitch_rate, lim.max_yaw_rate)
    rel = f.g - pos[0]
    slot_vel = speed[0] * a.u[0] + leader_turn * np.stack(
        [-rel[:, 1], rel[:, 0], np.zeros(len(rel))], axis=1
    )
    v_slot = np.sqrt((slot_vel**2).sum(1))
    behind = np.maximum(along, 0.0)
    v_ahead = v_slot + _closing_excess(behind, lim.decel, gain)  # Eq. 21–23
    ahead = np.maximum(-along, 0.0)
    v_behind = np.maximum(v_slot - _closing_excess(ahead, lim.accel, gain), 0)
    slant = np.maximum(a.u @ a.u[0], 0.5)  # the angle flown to the leader's track
    v_cmd = np.where(along >= 0, v_ahead, v_behind) / slant
    brake = follow & (along >= 0) & ~f.formed & (speed >= v_cmd)
    state[brake] = S3_FORMATION
    a_cmd = np.where(v_cmd >= speed, lim.accel, lim.decel)
    braked: FloatArray = np.where(follow, np.clip((v_cmd - speed) / (a_cmd * dt), -1, 1), f_speed)
    return braked


def _closing_excess(distance: FloatArray, accel: float, gain: float) -> FloatArray:
    """The kernel's ``closing_speed_excess`` for every distance at once."""
    d = np.maximum(distance, 0.0)
    linear_m = accel / (gain * gain)
    root = np.sqrt(np.maximum(2.0 * accel * d - accel * linear_m, 0.0))
    out: FloatArray = np.where(d <= linear_m, gain * d, root)
    return out


def _kinematics(
    pos: FloatArray,
    pitch: FloatArray,
    yaw: FloatArray,
    speed: FloatArray,
    active: BoolArray,
    f_speed: FloatArray,
    f_pitch: FloatArray,
    f_yaw: FloatArray,
    lim: KernelLimits,
    dt: float,
    yaw_rate: FloatArray,
    pitch_rate: FloatArray,
    speed_share: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Eq. 3–5: the new speed, pitch and yaw within their limits (``yaw_rate`` and
    ``pitch_rate`` [N] each vehicle's ω_ψ and ω_θ, ``speed_share`` [N] the share of accel
    and decel it changes speed at), and one step of flight; inactive vehicles keep theirs."""
    a_l = np.where(f_speed > 0, lim.accel, lim.decel) * speed_share
    new_speed = np.clip(speed + f_speed * a_l * dt, lim.v_min, lim.v_max)
    new_pitch = np.clip(pitch + f_pitch * pitch_rate * dt, -math.pi / 2, math.pi / 2)
    new_yaw = yaw + f_yaw * yaw_rate * dt
    new_yaw = np.where(new_yaw > math.pi, new_yaw - 2 * math.pi, new_yaw)
    new_yaw = np.where(new_yaw <= -math.pi, new_yaw + 2 * math.pi, new_yaw)
    keep_old = ~active
    new_speed[keep_old], new_pitch[keep_old], new_yaw[keep_old] = (
        speed[keep_old],
        pitch[keep_old],
        yaw[keep_old],
    )
    step = new_speed[:, None] * np.stack(
        [
            np.cos(new_pitch) * np.cos(new_yaw),
            np.cos(new_pitch) * np.sin(new_yaw),
            np.sin(new_pitch),
        ],
        axis=1,
    )
    new_pos = pos + np.where(active[:, None], step * dt, 0.0)
    return new_pos, new_pitch, new_yaw, new_speed


def _formation_turn_rate(
    turn: float,
    field: FloatArray,
    pos: FloatArray,
    speed: FloatArray,
    active: BoolArray,
    a: Attitude,
    f: Formation,
    lim: KernelLimits,
    reach_floor: float = 0.0,
) -> float:
    """The leader's ``turn`` (rad/s) kept to what its wingmen follow (the kernel's
    ``formation_turn_rate``): no station-keeping wingman's slot speed taken further from the
    wingman's than its ``slot_speed_room`` (or its present mismatch), and the turn eased out
    towards the heading ``field`` (ICS) wants."""
    u = a.u[0, :2] / max(float(np.hypot(a.u[0, 0], a.u[0, 1])), 1e-12)
    rel = f.g[1:, :2] - pos[0, :2]
    y = u[0] * rel[:, 1] - u[1] * rel[:, 0]
    wingmen = active[1:]
    if not wingmen.any():
        return turn
    accel = min(lim.accel, lim.decel)
    to_slot = f.g[1:, :2] - pos[1:, :2]
    keeping = (to_slot**2).sum(1) <= (TURN_KEEPING_REACH * lim.target_accuracy) ** 2
    held = wingmen & keeping & (np.abs(y) >= 1e-9)
    gap = speed[0] - speed[1:]
    behind = to_slot @ u  # the kernel's ``slot_speed_room``
    half = 0.5 * lim.target_accuracy
    faster = np.sqrt(2.0 * accel * np.maximum(half - behind, 0.0))
    slower = np.sqrt(2.0 * accel * np.maximum(half + behind, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        ends = np.stack([(gap - np.maximum(faster, gap)) / y, (gap + np.maximum(slower, -gap)) / y])
    low = float(np.max(ends.min(0)[held], initial=-math.inf))
    high = float(np.min(ends.max(0)[held], initial=math.inf))
    eased = min(max(turn, low), high)
    if abs(eased) < reach_floor:  # never eased below the turn that reaches the target
        eased = math.copysign(min(reach_floor, abs(turn)), turn)
    turn = eased
    widest = float(np.max(np.abs(y[wingmen]), initial=0.0))
    if widest > 0.0:
        left = math.atan2(
            a.cy[0] * field[1] - a.sy[0] * field[0], a.cy[0] * field[0] + a.sy[0] * field[1]
        )
        settle = math.sqrt(2.0 * accel / widest * abs(left))
        turn = min(max(turn, -settle), settle)
    return turn


def reference_step(
    pos: FloatArray,
    pitch: FloatArray,
    yaw: FloatArray,
    speed: FloatArray,
    slot: FloatArray,
    rank: IntArray,
    active: BoolArray,
    obs_center: FloatArray,
    obs_radius: FloatArray,
    obs_velocity: FloatArray,
    target: FloatArray,
    lim: KernelLimits,
    dt: float,
) -> Step:
    """One step Δt of the whole fleet (Eq. 3–24), in numpy."""
    a = _attitude(pitch, yaw, speed)
    obstacles = _obstacle_repulsion(
        pos, speed, a.u, obs_center, obs_radius, obs_velocity, lim, dt, target
    )
    leader_repelled = bool(active[0]) and bool((obstacles[0][0] != 0).any())
    f = _formation(
        pos, slot, active, a, lim, _frame(pos, target, a, leader_repelled, float(speed[0]), lim)
    )
    aim = _aims(pos, target, speed, a, f, rank, active, lim, dt)

    def steered(
        leader_turn: float,
    ) -> tuple[Repulsion, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, IntArray]:
        """The field and the turn trends with the wingmen led by ``leader_turn``."""
        follow = _follow(pos, aim, speed, a, lim, f.g, leader_turn)
        r = _repulsion(pos, speed, a, follow, rank, active, f.formed, obstacles, lim, dt)
        field = _field(follow, a, r)
        pitch_rate = np.full(pos.shape[0], lim.max_pitch_rate)
        if (r.rep[0] != 0).any() and _whole(r, lim):  # the kernel's ``passing_limits``
            pitch_rate[0] = passing_limits(lim).max_pitch_rate
        fv, d, lowest, s2, along_field = _wanted_direction(
            field, pos, speed, a, r, lim, dt, pitch_rate
        )
        state = np.where(s2, S2_LOCAL_MINIMUM, S1_FOLLOW).astype(np.int64)
        yaw_rate = np.full(pos.shape[0], lim.max_yaw_rate)
        if not (r.rep[0] != 0).any() or _whole(r, lim):  # the leader (``leader_limits``)
            reaching = reaching_turn_rate(
                float(pos[0, 0]),
                float(pos[0, 1]),
                float(a.cy[0]),
                float(a.sy[0]),
                float(speed[0]),
                lim,
                float(target[0]),
                float(target[1]),
            )
            yaw_rate[0] = leader_limits(lim, reaching).max_yaw_rate
        f_pitch, f_yaw = _turn_trends(
            fv, d, lowest, pitch, yaw, a, r, lim, dt, yaw_rate, pitch_rate
        )
        if active[0] and not (r.rep[0] != 0).any() and lim.leader_turn_rate < math.inf:
            turn = _formation_turn_rate(
                float(f_yaw[0] * yaw_rate[0]),
                field[0],
                pos,
                speed,
                active,
                a,
                f,
                lim,
                just_reaching(reaching, lim),
            )
            f_yaw[0] = turn / yaw_rate[0]
        return r, along_field, f_pitch, f_yaw, yaw_rate, pitch_rate, state

    r, along_field, f_pitch, f_yaw, yaw_rate, pitch_rate, state = steered(0.0)
    held_turn = bool(active[0]) and lim.leader_turn_rate < math.inf
    leader_turn = float(f_yaw[0] * yaw_rate[0]) if held_turn else 0.0
    if leader_turn != 0.0:  # the leader decides first; its wingmen lead its turn
        r, along_field, f_pitch, f_yaw, yaw_rate, pitch_rate, state = steered(leader_turn)
    f_speed = _speed_trend(along_field, pos, aim, speed, a, f, r, state, lim, dt, leader_turn)
    speed_share = np.ones(pos.shape[0])
    if not (r.rep[0] != 0).any() or _whole(r, lim):  # the leader (``leader_limits``)
        speed_share[0] = leader_speed_share(lim)
    new = _kinematics(
        pos,
        pitch,
        yaw,
        speed,
        active,
        f_speed,
        f_pitch,
        f_yaw,
        lim,
        dt,
        yaw_rate,
        pitch_rate,
        speed_share,
    )
    return (*new, state)

"""Repulsion from obstacles and from teammates of higher priority (Eq. 10–13 of the paper).

* ``obstacle_repulsion``  Eq. 10–13: ε₁ from every obstacle whose influence radius we are in
* ``teammate_conflict``   Eq. 12–13 for one teammate of higher priority, a moving obstacle
* ``teammate_conflicts``  the same summed over the teammates a vehicle looks at
* ``teammates_first``     a teammate conflict before the obstacles while they leave room
* ``yielding_back``       a conflict left unsolved near its closest approach: the teammate
  of higher priority gives way too
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gcs_ppf.planning.ppf.primitives import (
    AVOIDANCE_TURN_ANGLE,
    CONFLICT_HORIZON_TURNS,
    EPSILON_1,
    HAND_BACK_TURNS,
    INFLUENCE_STEPS,
    YIELD_BACK_TURNS,
    KernelLimits,
    airframe_limited,
    closing_speed,
    influence_radius,
    leader_limits,
    lowest_climb,
    obstacles_first,
    reaching_turn_rate,
    roll_in_lead,
    room_to_turn_away,
    turn_missed_ahead,
    turning_speed,
    way_clear,
)

NO_CONFLICT = 0  # a teammate that does not repel
JUST_CLEAR = 1  # a teammate conflict only just avoided: hold course
CONFLICT = 2  # a teammate that repels (a moving obstacle)


@njit(cache=True, inline="always")
def padding(
    target: np.ndarray,
    obs_center: np.ndarray,
    j: int,
    keep_out: float,
    pad: float,
    turn_radius: float,
    beyond: float,
) -> float:
    """``pad``, or 0 where the target lies within the reach the pad gives obstacle j: its
    influence radius (``influence_radius``) round ``keep_out + pad`` at a turn of
    ``turn_radius`` (the formation's, round a static one), ``beyond`` more (the steps of
    travel and a half turn the radius grows by).  A leader kept that far out could never
    reach it: repelled with ε₁ wherever it is within that radius, Table 3's leader passing
    its last sphere as a formation (the target 1,803 m from the centre, the pad's reach
    2,231 m) circled the target 325–800 m off it for ever."""
    dx = target[0] - obs_center[j, 0]
    dy = target[1] - obs_center[j, 1]
    dz = target[2] - obs_center[j, 2]
    padded = keep_out + pad  # (``influence_radius`` at that turn radius)
    reach = math.sqrt((padded + turn_radius) ** 2 - turn_radius**2) + beyond
    return 0.0 if dx * dx + dy * dy + dz * dz <= reach * reach else pad


@njit(cache=True, inline="always")
def obstacle_repulsion(
    i: int,
    pos: np.ndarray,
    speed: np.ndarray,
    direction: np.ndarray,
    obs_center: np.ndarray,
    obs_radius: np.ndarray,
    obs_velocity: np.ndarray,
    near_start: np.ndarray,
    near_obstacles: np.ndarray,
    lim: KernelLimits,
    dt: float,
    target: np.ndarray,
) -> tuple[float, float, float, bool, bool, bool]:
    """``obstacles_repelling`` with the leader's pad (``lim.leader_keep_out_pad``) for the
    leader, i = 0; where an obstacle repelling it refuses the turn at its formation's rate,
    without: the paper's leader, all its influence radii the paper's.  Summed with the
    grown radius of an obstacle further off, the repulsion of the one it flew at pointed
    beside its track, the slide along static obstacles held its course, and a paper-scale
    leader flew 310 m into a sphere (sweep scene 66308, seed 2)."""
    pad = lim.leader_keep_out_pad if i == 0 else 0.0
    out = obstacles_repelling(
        i,
        pos,
        speed,
        direction,
        obs_center,
        obs_radius,
        obs_velocity,
        near_start,
        near_obstacles,
        lim,
        dt,
        target,
        pad,
    )
    if pad > 0.0 and not out[5]:
        rx, ry, rz, moving, room, _ = obstacles_repelling(
            i,
            pos,
            speed,
            direction,
            obs_center,
            obs_radius,
            obs_velocity,
            near_start,
            near_obstacles,
            lim,
            dt,
            target,
            0.0,
        )
        return rx, ry, rz, moving, room, False
    return out


@njit(cache=True, inline="always")
def lets_go(
    p: np.ndarray,
    u: np.ndarray,
    center: np.ndarray,
    keep_out: float,
    slow: float,
    steps: float,
    half_turn: float,
    speed: float,
    lim: KernelLimits,
    target: np.ndarray,
) -> bool:
    """Whether the padded leader at ``p`` flying along ``u`` lets go of the static obstacle
    at ``center`` (``keep_out`` its keep-out with the ``pad``): where holding its course to
    the edge of the obstacle's influence (at its formation's turn radius ``slow``, a few
    ``steps`` and a ``half_turn`` more) would leave its target inside its formation's turn
    (``turn_missed_ahead``, with the roll-in's way, ``roll_in_lead``), once its way to the
    target (``way_clear``: the turn onto it ``leader_limits`` gives, the line on) clears the
    padded keep-out.  Held until it cleared it by one more pad, the V of five flew on 48°
    off its target for 20 s after its turn away, its target fell inside its formation's
    turn, and it came round onto it at 1.3–1.5°/s where its wingmen follow 1°/s (planned
    with the ground: its outer wingmen 16–19 m off their slots)."""
    h = math.sqrt(u[0] * u[0] + u[1] * u[1])
    if h <= 0.0:
        return False
    v = turning_speed(speed, lim)
    edge = influence_radius(speed, speed / slow, keep_out) + steps + half_turn
    if not turn_missed_ahead(
        p[0], p[1], p[2], u[0], u[1], u[2], center[0], center[1], center[2], edge,
        roll_in_lead(v, lim), v, lim.leader_turn_rate, target[0], target[1],
    ):  # fmt: skip
        return False
    hx, hy = u[0] / h, u[1] / h
    onto = reaching_turn_rate(p[0], p[1], hx, hy, speed, lim, target[0], target[1])
    radius = v / leader_limits(lim, onto).max_yaw_rate
    return way_clear(
        p[0], p[1], hx, hy, radius, target[0], target[1], center[0], center[1],
        keep_out + steps,
    )  # fmt: skip


@njit(cache=True, inline="always")
def obstacles_repelling(
    i: int,
    pos: np.ndarray,
    speed: np.ndarray,
    direction: np.ndarray,
    obs_center: np.ndarray,
    obs_radius: np.ndarray,
    obs_velocity: np.ndarray,
    near_start: np.ndarray,
    near_obstacles: np.ndarray,
    lim: KernelLimits,
    dt: float,
    target: np.ndarray,
    pad: float,
) -> tuple[float, float, float, bool, bool, bool]:
    """Repulsion on vehicle i from the obstacles (Eq. 10–13): ε₁ along the outward normal
    from every obstacle whose influence radius R_j (Eq. 10–11, erratum 4: see
    ``influence_radius``) the vehicle is in.  R_j grows by a few steps of travel, by the
    obstacle's closing speed times a quarter-turn time, and for an ``airframe_limited``
    vehicle by one turn radius.  Only ``near_obstacles[near_start[i]:near_start[i+1]]``
    are looked at.  ``direction[N,3]`` holds the flight directions (``unit_velocities``).

    Returns (F_r, whether a repelling obstacle moves, whether every repelling obstacle
    leaves vehicle i room to give way to a teammate first: static, and cleared by a
    full-rate turn away begun ``HAND_BACK_TURNS`` quarter turns and ``INFLUENCE_STEPS``
    steps of travel later, ``room_to_turn_away``; never for an
    ``airframe_limited`` vehicle, which needs its half turn, nor one whose dives the
    ground limits, ``lowest_climb``: either may not be able to turn away).

    With a ``pad`` (the leader's) it keeps that much more from every obstacle whose
    padded keep-out leaves its ``target`` out, so that its slots keep out of it too, and
    goes round a static obstacle at the turn rate its formation follows
    (``leader_turn_rate``), its influence radius grown to that turn's (the half turn
    kept at full rate: the pad is more room than it), wherever a turn away at that rate
    begun a few steps on still clears the obstacle's own keep-out (``room_to_turn_away``);
    elsewhere as the paper's leader.  Started inside that grown radius and closing, a
    paper-scale leader turning at its formation's 2.4°/s flew 210 m into a sphere (sweep
    scene 98867, seed 2).  Where holding its course to the edge of a static obstacle's
    influence would leave its target inside its formation's turn, it lets go of the
    obstacle as soon as its way to the target clears the padded keep-out (``lets_go``).
    The last value returned: whether every repelling obstacle lets it turn at its
    formation's rate (``fleet_step``'s ``whole``).
    """
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    vi = speed[i]
    px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
    rx, ry, rz = 0.0, 0.0, 0.0
    moving_threat = False
    formation_turn = True
    rho = vi / omega
    half_turn = rho if airframe_limited(lim) else 0.0
    steps = INFLUENCE_STEPS * vi * dt  # a few steps of travel
    height = pz - lim.ground - lim.safe_distance_obstacle - steps
    room = not airframe_limited(lim) and lowest_climb(height, vi, lim) == -1.0
    ux, uy, uz = direction[i, 0], direction[i, 1], direction[i, 2]
    # What a vehicle giving way to a teammate first keeps in hand (``HAND_BACK_TURNS``).
    hand_back = steps + HAND_BACK_TURNS * AVOIDANCE_TURN_ANGLE * rho
    for c in range(near_start[i], near_start[i + 1]):
        j = near_obstacles[c]
        dx = px - obs_center[j, 0]
        dy = py - obs_center[j, 1]
        dz = pz - obs_center[j, 2]
        d2 = dx * dx + dy * dy + dz * dz
        own_keep_out = obs_radius[j] + lim.safe_distance_obstacle
        keep_out = own_keep_out
        u_max = math.sqrt(
            obs_velocity[j, 0] ** 2 + obs_velocity[j, 1] ** 2 + obs_velocity[j, 2] ** 2
        )
        turn = rho
        slow = rho
        padded = 0.0
        if pad > 0.0:  # the leader's whole formation keeps out, where its target is not
            if u_max == 0.0:
                slow = vi / min(omega, lim.leader_turn_rate)
            padded = padding(target, obs_center, j, keep_out, pad, slow, steps + half_turn)
            keep_out += padded
            # the leader turns as its formation can follow, where that still clears it
            if (
                padded > 0.0
                and u_max == 0.0
                and room_to_turn_away(dx, dy, dz, ux, uy, uz, steps, slow, own_keep_out)
            ):
                turn = slow
        reach = keep_out + turn + steps + u_max * AVOIDANCE_TURN_ANGLE / omega + half_turn
        if d2 > reach * reach:  # cheap rejection: R ≤ keep_out + ρ
            continue
        d = math.sqrt(d2)
        closing = closing_speed(
            dx, dy, dz, d, obs_velocity[j, 0], obs_velocity[j, 1], obs_velocity[j, 2]
        )
        radius = influence_radius(vi, vi / turn, keep_out) + steps
        radius += closing * AVOIDANCE_TURN_ANGLE / omega + half_turn
        if (
            d <= radius
            and d > 0.0
            and not (  # the padded leader let go (``lets_go``)
                padded > 0.0
                and u_max == 0.0
                and lets_go(pos[i], direction[i], obs_center[j], keep_out, slow,
                            steps, half_turn, vi, lim, target)
            )
        ):  # fmt: skip
            formation_turn = formation_turn and turn == slow
            rx += EPSILON_1 * dx / d
            ry += EPSILON_1 * dy / d
            rz += EPSILON_1 * dz / d
            moving_threat = moving_threat or u_max > 0.0
            room = (
                room
                and u_max == 0.0
                and room_to_turn_away(dx, dy, dz, ux, uy, uz, hand_back, rho, keep_out)
            )
    return rx, ry, rz, moving_threat, room, formation_turn


@njit(cache=True, inline="always")
def closest_approach(
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
    in_formation: bool,
    horizon_turns: float = CONFLICT_HORIZON_TURNS,
) -> tuple[bool, float, float, float]:
    """The closest approach of ``teammate_conflict`` (its arguments): (whether the two
    close on each other, its time t_cpa within the horizon of ``horizon_turns`` quarter
    turns, the squared miss distance then, the distance under which the mate repels);
    only the first is set when they do not close."""
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    approach = wx * dx + wy * dy + wz * dz  # > 0: the gap is shrinking
    w2 = wx * wx + wy * wy + wz * wz
    if approach <= 0.0 or w2 == 0.0:  # (w2 can underflow while approach does not)
        return False, 0.0, 0.0, 0.0
    d2 = dx * dx + dy * dy + dz * dz
    # Closest approach within the horizon (straight flight), and its time.
    t_cpa = min(approach / w2, horizon_turns * AVOIDANCE_TURN_ANGLE / omega)
    miss2 = d2 - 2.0 * approach * t_cpa + w2 * t_cpa * t_cpa
    # Either vehicle may be turning at full rate meanwhile (½ v ω t² each, at most one
    # more safe distance).
    turning = 0.0
    if not in_formation:
        turning = min(0.5 * (vi + vk) * omega * t_cpa * t_cpa, lim.safe_distance_uav)
    return True, t_cpa, miss2, lim.safe_distance_uav + (2.0 * vi * dt + turning)


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
    own_reach: float,
    lim: KernelLimits,
    dt: float,
    in_formation: bool = False,
    horizon_turns: float = CONFLICT_HORIZON_TURNS,
) -> tuple[int, float, float, float]:
    """One teammate k of higher priority as a moving obstacle (Eq. 12–13, formation model).

    (dx, dy, dz) is vehicle i's offset from k, (wx, wy, wz) k's velocity relative to i,
    ``own_reach`` vehicle i's R(v_i) + v_i·Δt (the influence radius of the safe distance,
    ``influence_radius``, and a step).
    The mate repels (``CONFLICT``) only while the two close on each other and, within a
    quarter turn's time, would come nearer than the safe distance plus what turning at
    full rate could take off it (closest point of approach); mates flying alongside do
    not (``NO_CONFLICT``).  A moving obstacle repels from where it will be at the closest
    approach: along the miss vector, which is what widens the miss; radially when the two
    would meet head-on (then s2 decides the way out).  Within one more safe distance of a
    conflict it is ``JUST_CLEAR``: hold course rather than turn back into it (otherwise the
    turn flips every step along the conflict's edge).  Two vehicles ``in_formation`` (both
    in their slots, or one in its slot and the other the leader) follow the same leader
    and are not taken to turn into each other: without that allowance (with the closed-loop
    margin, 180 m at ArduPlane's 28 m/s) the slots 141 m apart of a five-vehicle formation
    were conflicts whenever two neighbours closed at all, and on real ArduPlane each wingman
    entered avoidance 20–39 times in a run and the formation never held 10 s.
    ``horizon_turns`` is the horizon in quarter turns (``CONFLICT_HORIZON_TURNS``; a
    vehicle giving way back, ``YIELD_BACK_TURNS``: see ``yielding_back``).
    Returns (kind, unit miss vector; zero unless ``CONFLICT``).
    """
    closing, t_cpa, miss2, threshold = closest_approach(
        dx, dy, dz, wx, wy, wz, vi, vk, lim, dt, in_formation, horizon_turns
    )
    if not closing or miss2 >= (threshold + lim.safe_distance_uav) ** 2:
        return NO_CONFLICT, 0.0, 0.0, 0.0
    d = math.sqrt(dx * dx + dy * dy + dz * dz)
    radius = own_reach + vk * AVOIDANCE_TURN_ANGLE / min(lim.max_pitch_rate, lim.max_yaw_rate)
    if d > radius or d == 0.0:
        return NO_CONFLICT, 0.0, 0.0, 0.0
    if miss2 >= threshold * threshold:  # (no miss vector: nothing is pushed)
        return JUST_CLEAR, 0.0, 0.0, 0.0
    mx, my, mz = dx - wx * t_cpa, dy - wy * t_cpa, dz - wz * t_cpa
    miss = math.sqrt(mx * mx + my * my + mz * mz)
    if miss > 1e-6 * d:
        mx, my, mz = mx / miss, my / miss, mz / miss
    else:
        mx, my, mz = dx / d, dy / d, dz / d
    return CONFLICT, mx, my, mz


@njit(cache=True, inline="always")
def teammate_conflicts(
    i: int,
    rx: float,
    ry: float,
    rz: float,
    fx: float,
    fy: float,
    fz: float,
    pos: np.ndarray,
    speed: np.ndarray,
    trig: np.ndarray,
    mate_start: np.ndarray,
    mates: np.ndarray,
    formed: np.ndarray,
    own_reach: float,
    lim: KernelLimits,
    dt: float,
) -> tuple[float, float, float, bool, bool]:
    """The repulsion (rx, ry, rz) on vehicle i with that of its teammates of higher
    priority (lower rank) added (Eq. 12–13; each one by ``teammate_conflict``), and that
    of the teammates of lower priority it gives way back to (``trig[i, 7:11]``, from
    ``yielding_back``).  Only ``mates[mate_start[i]:mate_start[i+1]]`` are looked at (see
    ``nearby_teammates``);
    ``trig[:, 4:7]`` are the velocities (``unit_velocities``); ``formed`` whether each
    wingman is in its slot (a pair in formation: ``teammate_conflict``); ``own_reach``
    vehicle i's R(v_i) + v_i·Δt (``teammate_conflict``).

    Just clear of a conflict the vehicle holds its course rather than turn back into it
    (otherwise the turn flips every step along the conflict's edge), but only if flying
    the way it wants to, (fx, fy, fz) at its speed, would make that mate a conflict: a
    hold whenever following took off some of the miss kept wingmen from their slots for
    the rest of a flight, beside a teammate at the edge of the conflict band.

    Returns (F_r, whether a mate repels, whether to hold course).
    """
    vi = speed[i]
    px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
    repelled_by_mate = False
    hold_course = False
    for c in range(mate_start[i], mate_start[i + 1]):
        k = mates[c]
        dx, dy, dz = px - pos[k, 0], py - pos[k, 1], pz - pos[k, 2]
        wx, wy, wz = trig[k, 4], trig[k, 5], trig[k, 6]
        together = formed[i] and (k == 0 or formed[k])
        kind, mx, my, mz = teammate_conflict(
            dx,
            dy,
            dz,
            wx - trig[i, 4],
            wy - trig[i, 5],
            wz - trig[i, 6],
            vi,
            speed[k],
            own_reach,
            lim,
            dt,
            together,
        )
        if kind == JUST_CLEAR and not hold_course:
            # Were it to follow: a conflict if it closes to within the threshold (the mate
            # is within reach, the distance being the same).
            wx, wy, wz = wx - vi * fx, wy - vi * fy, wz - vi * fz
            closing, _, miss2, threshold = closest_approach(
                dx, dy, dz, wx, wy, wz, vi, speed[k], lim, dt, together
            )
            hold_course = closing and miss2 < threshold * threshold
        elif kind == CONFLICT:
            rx, ry, rz = rx + EPSILON_1 * mx, ry + EPSILON_1 * my, rz + EPSILON_1 * mz
            repelled_by_mate = True
    if trig[i, 10] > 0.0:  # it gives way back (``yielding_back``)
        rx, ry, rz = (
            rx + EPSILON_1 * trig[i, 7],
            ry + EPSILON_1 * trig[i, 8],
            rz + EPSILON_1 * trig[i, 9],
        )
        repelled_by_mate = True
    return rx, ry, rz, repelled_by_mate, hold_course


@njit(cache=True, inline="always")
def teammates_first(
    px: float,
    py: float,
    pz: float,
    mate: bool,
    ox: float,
    oy: float,
    oz: float,
    room: bool,
) -> tuple[float, float, float, float, float, float]:
    """The repulsion on a vehicle from the teammates' part (px, py, pz) (``mate``: whether
    one repels, ``teammate_conflicts``) and the obstacles' (ox, oy, oz) (Eq. 12–13), and the
    obstacles' part steering is to keep away from (``away_from_obstacles``, the slide).

    A vehicle in a teammate conflict and an obstacle's influence at once gives way to the
    teammate alone while the obstacles leave it ``room`` (``obstacle_repulsion``: a
    full-rate turn away from them begun ``HAND_BACK_TURNS`` quarter turns later still
    clears them, for the field handed back, the teammate's push still in it, does not
    turn the vehicle away at once); without room, the obstacles first
    (``obstacles_first``).  The teammate is then the nearer danger (its closest approach
    within a quarter turn), and the obstacle's radial push added to it, stripped of its
    part towards the obstacle, left a field that pointed back at the vehicle, whose turn
    then went round whichever way a few per cent of it said, or was reversed away from
    the obstacle: into the teammate.  The feasible sweep of 100,000 scenes (seed 2) drew
    three such: a vehicle at 220–300 m/s, entering an obstacle's influence 300–430 m from
    its surface, turned into a teammate and passed it at 17.8 m and 48.9 m (safe 50 m),
    as did an overtaking wingman at 24.1 m.
    """
    if mate and room and (px != 0.0 or py != 0.0 or pz != 0.0):
        return px, py, pz, 0.0, 0.0, 0.0
    rx, ry, rz = obstacles_first(ox + px, oy + py, oz + pz, ox, oy, oz)
    return rx, ry, rz, ox, oy, oz


@njit(cache=True, inline="always")
def yielding_back(
    pos: np.ndarray,
    speed: np.ndarray,
    trig: np.ndarray,
    active: np.ndarray,
    mate_start: np.ndarray,
    mates: np.ndarray,
    formed: np.ndarray,
    lim: KernelLimits,
    dt: float,
) -> None:
    """Which vehicles give way back to a teammate of lower priority that gives way to them
    (Eq. 12–13 the other way round): into ``trig[k, 7:10]`` the sum of the unit vectors
    vehicle k is pushed along, into ``trig[k, 10]`` how many (``trig[:, 4:7]`` the
    velocities, ``unit_velocities``; the lists as for ``teammate_conflicts``).

    Vehicle i gives way to its teammate k of higher priority from a quarter turn before
    their closest approach (``teammate_conflict``).  A conflict that is still there within
    ``YIELD_BACK_TURNS`` quarter turns of it (the same test, as i sees it, over that
    shorter horizon) is one i has not solved alone: flying at v_min it cannot out-turn k
    closing from behind at 150 m/s, or k turns or dives towards it (following its slot, or
    avoiding an obstacle) where i's straight-line prediction of k saw a miss.  Then k
    gives way too, along the opposite miss vector, so the two separate along one line
    (it never holds course for i).  Without it the sweeps drew such breaches in 1–2 of
    10,000 feasible scenes, down to 39.4 m (safe 50 m), and the property tests one more.
    """
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    n = pos.shape[0]
    for k in range(n):
        trig[k, 7], trig[k, 8], trig[k, 9], trig[k, 10] = 0.0, 0.0, 0.0, 0.0
    for i in range(n):
        if not active[i]:
            continue
        vi = speed[i]
        own_reach = influence_radius(vi, omega, lim.safe_distance_uav) + vi * dt
        for c in range(mate_start[i], mate_start[i + 1]):
            k = mates[c]
            dx, dy, dz = pos[i, 0] - pos[k, 0], pos[i, 1] - pos[k, 1], pos[i, 2] - pos[k, 2]
            kind, mx, my, mz = teammate_conflict(
                dx,
                dy,
                dz,
                trig[k, 4] - trig[i, 4],
                trig[k, 5] - trig[i, 5],
                trig[k, 6] - trig[i, 6],
                vi,
                speed[k],
                own_reach,
                lim,
                dt,
                formed[i] and (k == 0 or formed[k]),
                YIELD_BACK_TURNS,
            )
            if kind == CONFLICT:
                trig[k, 7], trig[k, 8], trig[k, 9] = (
                    trig[k, 7] - mx,
                    trig[k, 8] - my,
                    trig[k, 9] - mz,
                )
                trig[k, 10] += 1.0

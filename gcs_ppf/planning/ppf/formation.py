"""Formation forming and maintenance: the wingmen's local target points (Eq. 6–8), the
attraction towards a target point (Eq. 14–15) and the speed law (Eq. 21–24).

* ``formation_targets``  Eq. 6–8: local target points G_i; Eq. 24's condition (leader waits)
* ``attraction``         Eq. 14–15: towards the target point while nothing repels, passing
  teammates behind or above them on the way to a slot (``crossing_point``)
* ``speed_trend``        Eq. 19's f_l with Eq. 21–24 (wingman braking, leader waiting)
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gcs_ppf.planning.ppf.primitives import (
    AVOIDANCE_TURN_ANGLE,
    REACH_TIGHTER,
    S3_FORMATION,
    KernelLimits,
    catching_up_speed,
    falling_back_speed,
    follow_direction,
    slot_to_ics,
    trend,
)

CROSSING_CLEARANCE = 2.5  # safe distances (+ 2 steps): a wingman passes a teammate this far
CROSSING_REACH = 3.0  # safe distances: teammates this near are passed at CROSSING_CLEARANCE
TURN_KEEPING_REACH = 3.0
"""Target accuracies: a wingman this near its slot, level, keeps station and the leader's
turn keeps to what it follows (``formation_turn_rate``)."""


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
    frame: tuple[float, float, float, float],
) -> float:
    """The wingmen's local target points G_i = P_0 + A_vf(ψ₀) B_vf(θ₀) s_i (Eq. 6–8) into
    ``local_target[N,3]``, whether each wingman is formed (within the target accuracy of
    G_i) into ``formed[N]``, and the speed the leader waits at (s3, Eq. 24; 0: it does not
    wait).  ``frame``: cos θ₀, sin θ₀, cos ψ₀, sin ψ₀ of the frame the slots are in
    (``formation_frame``).

    The leader waits while a wingman is out of formation and has to catch up: its local
    target point is not behind it, or it does not yet fly the leader's way.  A wingman
    that flies the leader's way ahead of its slot cannot fall back while the leader flies
    at v_min: then the leader leads on (s1) and the slot comes to it, or, if it waits for
    another, it waits at v_min plus the speed the one furthest ahead gives ground back at
    (``falling_back_speed``); at v_min they would wait for each other for ever.  Only for
    a wingman at most 45° off straight ahead of its slot: one further to the side loses
    the ground by turning in, and the leader waits at v_min for it as the paper's does.
    """
    lcp, lsp, lcy, lsy = frame
    gain = min(lim.max_pitch_rate, lim.max_yaw_rate)
    leader_waits = False
    give_back = 0.0
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
        if not formed[i] and (along >= 0.0 or not same_way):
            leader_waits = True
        elif not formed[i] and gx * gx + gy * gy + gz * gz <= 2.0 * along * along:
            give_back = max(
                give_back, lim.v_min - falling_back_speed(lim.v_min, -along, lim.accel, gain)
            )
    return min(lim.v_min + give_back, lim.v_max) if leader_waits else 0.0


@njit(cache=True, inline="always")
def crossing_point(
    px: float,
    py: float,
    pz: float,
    gx: float,
    gy: float,
    gz: float,
    mx: float,
    my: float,
    mz: float,
    ux: float,
    uy: float,
    uz: float,
    clearance: float,
    reach: float,
) -> tuple[float, float, float, float]:
    """How a wingman at P bound for G passes a teammate at M (formation maintenance; the
    paper is silent).  Returns (the parameter s ∈ (0, 1) of the point Q of P→G nearest to
    M, the point to make for instead of G), or (−1, G) if the straight way passes
    ``clearance`` or more from M or M is not between (Q is P or G).

    The formation moves together, so the way to a slot on the other side of a teammate
    is seen at the instant: the segment P→G.  If it passes closer than ``clearance``, the
    wingman heads along the tangent from P to the sphere of that radius round M, on the
    side where Q lies, and makes for the point ``reach`` along it (at most as far as G);
    inside the sphere it heads across the line to M.  The side is Q − M without its part
    ahead of M along the formation's direction u (the leader's, who does not avoid
    wingmen): behind M, or above or below it; a way straight through M's track passes
    above it.  Made for afresh every step, the point slides round M until the straight
    way is clear.
    """
    sx, sy, sz = gx - px, gy - py, gz - pz
    length2 = sx * sx + sy * sy + sz * sz
    if length2 == 0.0:
        return -1.0, gx, gy, gz
    bx, by, bz = mx - px, my - py, mz - pz  # towards M
    s = (bx * sx + by * sy + bz * sz) / length2
    if s <= 0.0 or s >= 1.0:
        return -1.0, gx, gy, gz
    ex, ey, ez = s * sx - bx, s * sy - by, s * sz - bz  # Q − M
    if ex * ex + ey * ey + ez * ez >= clearance * clearance:
        return -1.0, gx, gy, gz
    ahead = max(ex * ux + ey * uy + ez * uz, 0.0)
    ex, ey, ez = ex - ahead * ux, ey - ahead * uy, ez - ahead * uz  # the side to pass on
    d = math.sqrt(bx * bx + by * by + bz * bz)
    if d <= 1e-9 * clearance:  # on the teammate: no line to pass it by (repulsion's case)
        return -1.0, gx, gy, gz
    bx, by, bz = bx / d, by / d, bz / d
    k = ex * bx + ey * by + ez * bz
    cx, cy, cz = ex - k * bx, ey - k * by, ez - k * bz  # the side, across the line to M
    c = math.sqrt(cx * cx + cy * cy + cz * cz)
    if c <= 1e-9 * clearance:  # straight through M's track: above it
        cx, cy, cz = -bz * bx, -bz * by, 1.0 - bz * bz
        c = math.sqrt(cx * cx + cy * cy + cz * cz)
        if c == 0.0:
            cx, cy, cz, c = ux, uy, uz, 1.0
    sin_a = min(clearance / d, 1.0)  # the tangent's angle from the line to M
    cos_a = math.sqrt(1.0 - sin_a * sin_a)
    hx = cos_a * bx + sin_a * cx / c
    hy = cos_a * by + sin_a * cy / c
    hz = cos_a * bz + sin_a * cz / c
    far = min(math.sqrt(length2), reach)
    return s, px + far * hx, py + far * hy, pz + far * hz


@njit(cache=True, inline="always")
def attraction(
    i: int,
    gx: float,
    gy: float,
    gz: float,
    ux: float,
    uy: float,
    uz: float,
    pos: np.ndarray,
    speed: np.ndarray,
    mate_start: np.ndarray,
    mates: np.ndarray,
    own_reach: float,
    lim: KernelLimits,
    dt: float,
    cy: float,
    sy: float,
    turn_rate: float = 0.0,
) -> tuple[float, float, float, float, float, float]:
    """The unit attraction F_g on vehicle i (Eq. 14, ``follow_direction``) towards its
    target point G = (gx, gy, gz) (the mission's target for the leader, index 0; G_i for a
    wingman), the field while nothing repels it (Eq. 15 with F_r = 0), and the point it
    makes for (G, or the ``crossing_point`` that passes a teammate; ``speed_trend``
    matches the leader's speed there).  (ux, uy, uz) is the leader's flight direction.

    A wingman aims where that point will be one turn time 1/ω ahead along its slot's
    flight: the leader's, and in a held turn (``turn_rate``, the leader's, rad/s) the
    slot's swing round it too (v₀u₀ + ω ẑ × r, ``slot_point_speed``).  Led along the
    leader's flight alone, a wingman pursuing its slot round a held turn sat 10–13 m off it
    (ArduPlane's routes, offline: RMS 11.6 m in the turns, in formation 65 % of the flight;
    led along the swing, 2.5 m and 99 %).  The teammates it passes are those of
    higher priority within ``CROSSING_REACH`` safe distances (and within reach of
    ``teammate_conflict``, so that they are in its list
    ``mates[mate_start[i]:mate_start[i+1]]``); of those the way passes too close to, the
    first along the way decides.  ``own_reach`` is vehicle i's R(v_i) + v_i·Δt (as for
    ``teammate_conflict``).
    """
    px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    lead = speed[0] / omega if i > 0 else 0.0
    ax, ay, az = gx, gy, gz
    first = 2.0
    vi = speed[i]
    clearance = CROSSING_CLEARANCE * lim.safe_distance_uav + 2.0 * vi * dt
    # A wingman within the target accuracy of G has no way to pass anyone on.
    way2 = (gx - px) ** 2 + (gy - py) ** 2 + (gz - pz) ** 2
    last = mate_start[i + 1] if i > 0 and way2 > lim.target_accuracy**2 else mate_start[i]
    farthest = CROSSING_REACH * lim.safe_distance_uav
    for c in range(mate_start[i], last):
        k = mates[c]
        dx, dy, dz = px - pos[k, 0], py - pos[k, 1], pz - pos[k, 2]
        d2 = dx * dx + dy * dy + dz * dz
        if d2 > farthest * farthest:  # (beyond the reach below whatever the speeds)
            continue
        reach = min(own_reach + speed[k] * AVOIDANCE_TURN_ANGLE / omega, farthest)
        if d2 > reach * reach:
            continue
        s, vx, vy, vz = crossing_point(
            px, py, pz, gx, gy, gz, pos[k, 0], pos[k, 1], pos[k, 2], ux, uy, uz, clearance, lead
        )
        if 0.0 <= s < first:
            first, ax, ay, az = s, vx, vy, vz
    swing = turn_rate / omega
    rx, ry = gx - pos[0, 0], gy - pos[0, 1]
    fx, fy, fz = follow_direction(
        ax + lead * ux - swing * ry - px,
        ay + lead * uy + swing * rx - py,
        az + lead * uz - pz,
        cy,
        sy,
    )
    return fx, fy, fz, ax, ay, az


@njit(cache=True, inline="always")
def slot_point_speed(
    leader_speed: float, ux: float, uy: float, uz: float, turn_rate: float, rx: float, ry: float
) -> float:
    """The speed of a slot (r = (rx, ry) from the leader, plan view) of a leader flying at
    ``leader_speed`` along (ux, uy, uz) and turning at ``turn_rate`` (rad/s, +: left): its
    velocity is v₀u₀ + ω ẑ × r (``gcs_ppf.planning.turns``); the leader's speed when it
    flies straight."""
    vx = leader_speed * ux - turn_rate * ry
    vy = leader_speed * uy + turn_rate * rx
    vz = leader_speed * uz
    return math.sqrt(vx * vx + vy * vy + vz * vz)


@njit(cache=True, inline="always")
def speed_trend(
    i: int,
    along_field: float,
    repelled: bool,
    wait_speed: float,
    pos: np.ndarray,
    speed: np.ndarray,
    ax: float,
    ay: float,
    az: float,
    direction: np.ndarray,
    formed: np.ndarray,
    lim: KernelLimits,
    dt: float,
    state: int,
    slot_speed: float,
    round_obstacle: bool = False,
) -> tuple[float, int]:
    """The speed entry f_l of the trend matrix (Eq. 19): the sign of F_v^x (``along_field``),
    except that the leader slows to ``wait_speed`` while the formation forms (s3, Eq. 24;
    see ``formation_targets``) and otherwise, nothing repelling it, keeps its
    ``leader_cruise_speed`` when it has one (``gcs_ppf.planning.turns``), and
    a wingman that nothing repels brakes so as to arrive at the leader's speed (Eq. 21–23
    relative to its moving local target point, ``catching_up_speed``; s3 once
    d_i ≤ Δd'_i) or, with its slot behind it, gives the ground back (``falling_back_speed``);
    d_i is measured along the leader's track, to the point the wingman makes for
    (``attraction``: G_i or a crossing point), and the speed is what makes that good at
    the angle the wingman flies to the track.  The speed matched is ``slot_speed``, the
    speed of the slot (``slot_point_speed``): the leader's, but in a held turn
    (``gcs_ppf.planning.turns``) that of the slot swinging round with it.

    A wingman going ``round_obstacle`` (static obstacles or zones repel it, no teammate)
    with its slot behind it gives the ground back as well, where Eq. 19 would speed it up
    along the field (the paper is silent): round the sphere on the line-abreast missions'
    way, the wingman whose slot was inside its keep-out flew at v_max while the leader
    waited at v_min, came out 50–60 m ahead of its slot and took 20–30 s to fall back
    (offline, ``arduplane_5``: in formation 49 % of the flight after forming; 56 % with
    this).  Returns (f_l, the vehicle's state: ``state`` or s3).
    """
    f_speed = 1.0 if along_field > 0.0 else (-1.0 if along_field < 0.0 else 0.0)
    if i == 0:
        if wait_speed > 0.0:
            a_cmd = lim.accel if wait_speed >= speed[0] else lim.decel
            return trend(wait_speed - speed[0], a_cmd, dt), S3_FORMATION
        if not repelled and lim.leader_cruise_speed < lim.v_max:  # turning in formation
            cruise = max(lim.leader_cruise_speed, lim.v_min)
            a_cmd = lim.accel if cruise >= speed[0] else lim.decel
            return trend(cruise - speed[0], a_cmd, dt), state
        return f_speed, state
    if not along_field > 0.0:
        return f_speed, state
    ux, uy, uz = direction[0, 0], direction[0, 1], direction[0, 2]
    along = (ax - pos[i, 0]) * ux + (ay - pos[i, 1]) * uy + (az - pos[i, 2]) * uz
    if repelled and not (round_obstacle and along < 0.0):
        return f_speed, state
    vi, v0 = speed[i], slot_speed
    gain = min(lim.max_pitch_rate, lim.max_yaw_rate)
    # The speed that makes good the leader's speed (plus or minus) along its track, at the
    # angle the wingman flies to it (sideways corrections need more speed).
    slant = max(direction[i, 0] * ux + direction[i, 1] * uy + direction[i, 2] * uz, 0.5)
    if along >= 0.0:
        v_cmd = catching_up_speed(v0, along, lim.decel, gain) / slant
        if not formed[i] and vi >= v_cmd:
            state = S3_FORMATION  # Eq. 23: d_i ≤ Δd'_i
    else:
        v_cmd = falling_back_speed(v0, -along, lim.accel, gain) / slant
    a_cmd = lim.accel if v_cmd >= vi else lim.decel
    return trend(v_cmd - vi, a_cmd, dt), state


@njit(cache=True)
def slot_speed_room(behind: float, accel: float, target_accuracy: float) -> tuple[float, float]:
    """How much faster and how much slower (m/s) than a wingman keeping station its slot may fly,
    the wingman ``behind`` m behind it along the leader's track (< 0: ahead), if it is to
    stay within ε/2 of it (ε the target accuracy) making the difference good at ``accel``:
    a slot faster by g leaves it g²/2a further behind, so g ≤ √(2a(ε/2 − behind)), and
    slower, √(2a(ε/2 + behind)).

    A fixed √(a·ε) either way (the room of a wingman in its slot) let the leader roll into
    its turn as fast as its wingmen's speeds followed, a slot's speed running √(a·ε) ahead
    of its wingman's all the way: planned on the formation takeoff of five, the outer
    wingman fell 19 m behind its slot as its leader turned onto the target at 1.5°/s."""
    half = 0.5 * target_accuracy
    faster = math.sqrt(2.0 * accel * max(half - behind, 0.0))
    slower = math.sqrt(2.0 * accel * max(half + behind, 0.0))
    return faster, slower


@njit(cache=True)
def just_reaching(reaching: float, lim: KernelLimits) -> float:
    """The turn rate (rad/s) that just reaches the leader's target where it lies inside its
    formation's turn (``reaching_turn_rate`` less its ``REACH_TIGHTER``); 0 elsewhere.
    Eased below it (``formation_turn_rate``), the turn that reaches the target only
    tightens: the line abreast of five, passing its sphere whole, eased onto its target
    as its outer wingman fell behind, missed it by 124 m and circled away."""
    if reaching > lim.leader_turn_rate:
        return reaching / (1.0 + REACH_TIGHTER)
    return 0.0


@njit(cache=True)
def formation_turn_rate(
    turn_rate: float,
    heading_left: float,
    pos: np.ndarray,
    speed: np.ndarray,
    active: np.ndarray,
    local_target: np.ndarray,
    ux: float,
    uy: float,
    lim: KernelLimits,
    reach_floor: float = 0.0,
) -> float:
    """The leader's ``turn_rate`` (rad/s, +: left) in a formation that turns
    (``gcs_ppf.planning.turns``), eased in and out as its wingmen's speeds follow, never
    below ``reach_floor`` (``just_reaching``) where it asks that much.

    A slot y to the side of a leader turning at ω flies ω·y slower or faster than the
    leader (``slot_point_speed``), and a wingman changes speed at a (the smaller of accel
    and decel) only.  Started or stopped at once, the turn leaves it (ω·y)²/2a off its
    slot (7.6 m for slots 100 m abreast at 2°/s), and the straight leg after the turn began
    with the wingmen settling: the loiter route's plan 13.0 m off at worst right after its
    first turn, its straight legs 3.4 m RMS.  So the turn is kept to where no wingman
    keeping station (level with its slot within ``TURN_KEEPING_REACH``: a wingman climbing
    into its slot as the leader levels off still follows its turn; held to the formed
    alone, the formation takeoff's leader rolled into a 1.5°/s turn at once as its wingmen
    fell 13 m above their slots, and the outer one fell 16 m behind) sees its slot run away
    from it by more than ``slot_speed_room`` (or its present mismatch, if larger: flying
    straight is always allowed), and it is eased out as the
    heading wanted comes near (``heading_left``, rad): no faster than √(2·a/|y|·|Δψ|),
    |y| the widest slot's, so the slots' speeds come back to the leader's at a.  (u_x,
    u_y) is the leader's direction; the wingmen's local target points are their slots."""
    h = math.sqrt(ux * ux + uy * uy)
    if h <= 0.0:
        return turn_rate
    hx, hy = ux / h, uy / h
    a = min(lim.accel, lim.decel)
    low, high, widest = -math.inf, math.inf, 0.0
    for i in range(1, pos.shape[0]):
        if not active[i]:
            continue
        y = hx * (local_target[i, 1] - pos[0, 1]) - hy * (local_target[i, 0] - pos[0, 0])
        widest = max(widest, abs(y))
        dx, dy = local_target[i, 0] - pos[i, 0], local_target[i, 1] - pos[i, 1]
        if abs(y) < 1e-9 or dx * dx + dy * dy > (TURN_KEEPING_REACH * lim.target_accuracy) ** 2:
            continue
        gap = speed[0] - speed[i]  # the slot's speed, straight, less the wingman's
        behind = hx * dx + hy * dy
        faster, slower = slot_speed_room(behind, a, lim.target_accuracy)
        ends_a = (gap - max(faster, gap)) / y  # ω·y = gap − (slot less wingman speed)
        ends_b = (gap + max(slower, -gap)) / y
        low = max(low, min(ends_a, ends_b))
        high = min(high, max(ends_a, ends_b))
    rate = min(max(turn_rate, low), high)
    if abs(rate) < reach_floor:
        rate = math.copysign(min(reach_floor, abs(turn_rate)), turn_rate)
    if widest > 0.0:
        settle = math.sqrt(2.0 * a / widest * abs(heading_left))
        rate = min(max(rate, -settle), settle)
    return rate

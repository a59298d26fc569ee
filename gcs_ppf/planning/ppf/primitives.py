"""The small formulas the PPF step is built from: frames, the influence radius, the
saturated trend, the braking speed, and the flight-path limits.

* ``influence_radius``      Eq. 10–11, corrected (CONVENTIONS §2 erratum 4)
* ``room_to_turn_away``     the same geometry off the axis: room left to turn away
* ``to_vcs``                Eq. 16–18 (ICS → VCS)
* ``slot_to_ics``           Eq. 6–8 (VCS → ICS, erratum 1: the pitch matrix transposed)
* ``trend``                 Eq. 19 (one entry of the trend matrix f, erratum 2)
* ``catching_up_speed``     Eq. 21–23 relative to the moving local target point (as printed:
  ``braking_speed``)
* ``falling_back_speed``    a wingman ahead of its slot gives the ground back
* ``lowest_climb``, ``limit_climb``, ``follow_direction``, ``away_from_obstacles``,
  ``obstacles_first``: choices where the paper is silent (see their docstrings)

The equation groups that use them, and the step itself, are in ``gcs_ppf.planning.ppf.kernel``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from numba import njit

S1_FOLLOW = 1  # target following and obstacle avoidance
S2_LOCAL_MINIMUM = 2  # local-minimum escape (Eq. 20)
S3_FORMATION = 3  # formation forming: leader waits, wingman brakes (Eq. 21–24)

EPSILON_1 = 1.0e6  # |F_j| inside an influence radius, ε₁ ≫ 1 (Eq. 13)
EPSILON_3 = 1.0e9  # braking vector of s3, ε₃ ≫ |F_v^sx| (Eq. 24)
LOCAL_MINIMUM_ANGLE = math.radians(1.0)  # repulsion this close to antiparallel → s2
AVOIDANCE_TURN_ANGLE = math.pi / 2  # a moving obstacle is out-turned in a quarter turn
MAX_FOLLOW_PITCH = math.pi / 4  # steepest flight path target following asks for
TAN_MAX_FOLLOW_PITCH = math.tan(MAX_FOLLOW_PITCH)
MAX_AVOID_PITCH = math.pi / 3  # steepest flight path any wanted direction may have
INFLUENCE_STEPS = 3.0  # steps of travel added to the influence radius (discrete turning)
SIDEWAYS_EPS = 1e-9  # |F_v^y| below this fraction of |F_v| counts as 0 in Eq. 19 (round-off)
CONFLICT_HORIZON_TURNS = 1.0  # teammate conflicts are looked for this many quarter turns ahead
# A conflict this many quarter turns from its closest approach is one the vehicle giving way
# has not solved alone: the one it gives way to gives way too (``teammate_conflicts``).
YIELD_BACK_TURNS = 0.25
HAND_BACK_TURNS = 0.25
"""Quarter turns of flight (0.75 s at the paper's 30°/s: an arc of ρ·π/8) that a vehicle
giving way to a teammate first keeps in hand for handing the way back to the obstacles
(``repulsion.teammates_first``): the room test (``room_to_turn_away``) begins the turn away
from them that much further on, besides the ``INFLUENCE_STEPS`` of discrete turning.

When the room runs out the teammate still repels, and the field handed back
(``obstacles_first``: the obstacle's push plus the teammate's less its part into the
obstacle) points behind the vehicle, whose pitch then follows that field's elevation: it
does not turn away at full rate at once.  In the feasible sweep of 100,000 scenes (seed 2)
a wingman at 100 m/s pitched towards the obstacle for 0.3 s after the hand-back (scene
47127), and one at 200 m/s held its pitch for 1.2 s, the conflict on and off step by step,
turning away by yaw alone (38269): with only the three steps in hand they came to 20.1 m
and 20.9 m of the surface (safe 25 m).  Counted in quarter turns, as the turn away is, the
margin grows with the turn radius: 1/12 kept those two at 25.0 m and 37.4 m, 1/6 at
31.3 m and 60.4 m, 1/4 at 38.6 m and 64.2 m."""
TRIG_COLUMNS = 11
"""The kernel's ``trig[N,11]``: cos θ, sin θ, cos ψ, sin ψ, the velocity, and who gives
way back (``repulsion.yielding_back``)."""


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
    leader_cruise_speed: float = math.inf
    """The speed the leader keeps while it follows its target (∞: the paper's leader, which
    speeds up to v_max once formed); ``gcs_ppf.planning.turns`` for a formation that turns."""
    leader_turn_rate: float = math.inf
    """The fastest the leader turns while it follows its target (∞: ``max_yaw_rate``)."""
    course_frame: bool = False
    """While obstacles or zones repel the leader, the slots are placed level along its way
    to its target instead of in its VCS (``kernel.formation_frame``; the mission's
    ``formation_frame: "course"``)."""
    leader_keep_out_pad: float = 0.0
    """Metres the leader keeps beyond every obstacle's keep-out, its farthest slot's
    distance, so that every slot keeps out too and the formation passes whole (the mission's
    ``obstacle_passage: "formation"``; ``repulsion.obstacle_repulsion``); 0: the paper."""


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


LEADER_PATH_ANGLE_SHARE = 0.75
"""Share of the airframe's flight-path limits the leader climbs and dives at while it
follows its target (``leader_limits``)."""
LEADER_SPEED_CHANGE_SHARE = 0.5
"""Share of the airframe's accel and decel the leader changes speed at while it follows its
target, where the vehicles fly the plan's speed changes (``leader_speed_share``)."""
FOLLOWED_ACCEL_M_S2 = 2.0
"""The fastest planned speed change (m/s², the mission's accel and decel) an autopilot is
taken to follow: ArduPlane's TECS flew 1.9–2.4 m/s² when asked for more."""


@njit(cache=True)
def inside_turn(
    px: float, py: float, cy: float, sy: float, speed: float, rate: float, tx: float, ty: float
) -> bool:
    """Whether the point (tx, ty) lies inside the circle a vehicle at (px, py) heading
    (cos ψ, sin ψ) = (cy, sy) flies turning towards it at ``rate`` (plan view): no turn at
    that rate ever reaches it."""
    if not 0.0 < rate < math.inf:
        return False
    r = speed / rate
    dx, dy = tx - px, ty - py
    left = cy * dy - sy * dx >= 0.0
    nx, ny = (-sy, cy) if left else (sy, -cy)
    ex, ey = dx - r * nx, dy - r * ny
    return ex * ex + ey * ey < r * r


REACH_TIGHTER = 0.1
"""The leader turns onto a target inside its formation's turn this fraction faster than the
turn that just reaches it (``reaching_turn_rate``)."""


@njit(cache=True)
def turning_speed(speed: float, lim: KernelLimits) -> float:
    """The speed the leader at ``speed`` turns at: its own, or the cruise speed it makes for
    (``leader_cruise_speed``, at most v_max) if faster."""
    return max(speed, min(lim.leader_cruise_speed, lim.v_max))


@njit(cache=True)
def reaching_turn_rate(
    px: float,
    py: float,
    cy: float,
    sy: float,
    speed: float,
    lim: KernelLimits,
    tx: float,
    ty: float,
) -> float:
    """The turn rate the leader at (px, py) heading (cos ψ, sin ψ) = (cy, sy) at ``speed``
    turns towards the point (tx, ty) at: its formation's (``leader_turn_rate``) where that
    turn reaches it, else the turn that does, ``REACH_TIGHTER`` faster, at its
    ``turning_speed`` (0 where its turns are not held).

    The circle tangent to its heading through a point ``a`` ahead and ``b`` to the side has
    radius (a² + b²) / 2|b|, less than v/ω wherever ``inside_turn``.  Turned at the full
    rate instead, the line abreast of five, pushed aside by the sphere it passes as a
    formation, turned onto its target at 4–6°/s where its formation follows 1°/s, and its
    outer wingman fell 115 m off its slot (flown on real ArduPlane).  At its own speed
    rather than the one it makes for, the paper-scale leader of Table 3's route, speeding
    up from 107 to 200 m/s in that turn, missed the target and flew a 100 s loop."""
    rate = lim.leader_turn_rate
    if not 0.0 < rate < math.inf:
        return 0.0
    v = turning_speed(speed, lim)
    if not inside_turn(px, py, cy, sy, v, rate, tx, ty):
        return rate
    dx, dy = tx - px, ty - py
    side = abs(cy * dy - sy * dx)
    radius = (dx * dx + dy * dy) / (2.0 * side)  # side > 0 inside the turn
    return (1.0 + REACH_TIGHTER) * v / radius


@njit(cache=True)
def with_turn_limits(
    lim: KernelLimits,
    max_pitch_rate: float,
    max_yaw_rate: float,
    max_climb_angle: float,
    max_dive_angle: float,
    accel: float,
    decel: float,
) -> KernelLimits:
    """``lim`` with these rates, flight-path limits and speed changes (NamedTuple's
    ``_replace`` does not compile)."""
    return KernelLimits(
        lim.v_min,
        lim.v_max,
        accel,
        decel,
        max_pitch_rate,
        max_yaw_rate,
        lim.target_accuracy,
        lim.safe_distance_uav,
        lim.safe_distance_obstacle,
        lim.ground,
        max_climb_angle,
        max_dive_angle,
        lim.leader_cruise_speed,
        lim.leader_turn_rate,
        lim.course_frame,
        lim.leader_keep_out_pad,
    )


@njit(cache=True)
def leader_speed_share(lim: KernelLimits) -> float:
    """The share of accel and decel the leader changes speed at while it follows its target:
    ``LEADER_SPEED_CHANGE_SHARE`` where the vehicles fly the plan's speed changes, 1 (the
    paper's leader) where they cannot (``FOLLOWED_ACCEL_M_S2``).

    A wingman keeps its slot by changing speed relative to it, at its own accel and decel;
    a leader changing speed as fast leaves it nothing to close or give back ground with.
    At ArduPlane's scale (0.6 / 0.8 m/s²) the leader slowed from 25.6 m/s after its
    takeoff as its formation turned onto the loiter route's first leg, and its wingmen,
    matching it, ran 20–30 m through their slots (the straight legs after the takeoff 6.3
    m RMS; with the share, 4.5 m)."""
    if max(lim.accel, lim.decel) <= FOLLOWED_ACCEL_M_S2:
        return LEADER_SPEED_CHANGE_SHARE
    return 1.0


@njit(cache=True)
def leader_limits(lim: KernelLimits, turn_rate: float = 0.0) -> KernelLimits:
    """The limits the leader follows its target with: its climb and dive angles kept to
    ``LEADER_PATH_ANGLE_SHARE`` of the airframe's where those bind (``airframe_limited``),
    its accel and decel to ``leader_speed_share`` of them.

    The slots lie in the leader's climbing frame (Eq. 6): climbing at θ₀, a slot 300 m
    behind it is 300 sin θ₀ below it.  A wingman below its slot while the leader climbs at
    the airframe's limit can never climb faster than the slot does, as a wingman behind it
    could never catch up a leader at v_max; the paper's leader waits at low speed (Eq. 24)
    and, in the same way, leaves its wingmen room to climb and dive.  Planned with
    ArduPlane's +20°/−25°, neither Table 2 nor Table 3 formed offline (a wingman stayed
    ~100 m below its slot through the climb).  Avoiding an obstacle, it keeps the whole
    envelope (``fleet_step``).  Its yaw rate is kept to ``leader_turn_rate``, the turn its
    formation can follow (``gcs_ppf.planning.turns``), or to ``turn_rate`` where that is
    faster: the turn that reaches a target inside it (``reaching_turn_rate``; a waypoint
    500 m off a leader whose formation turns on 633 m was circled for ever)."""
    climb, dive = lim.max_climb_angle, lim.max_dive_angle
    if airframe_limited(lim):
        climb = min(lim.max_climb_angle, MAX_AVOID_PITCH) * LEADER_PATH_ANGLE_SHARE
        dive = min(lim.max_dive_angle, MAX_AVOID_PITCH) * LEADER_PATH_ANGLE_SHARE
    yaw_rate = min(lim.max_yaw_rate, max(lim.leader_turn_rate, turn_rate))
    share = leader_speed_share(lim)
    return with_turn_limits(
        lim, lim.max_pitch_rate, yaw_rate, climb, dive, lim.accel * share, lim.decel * share
    )


@njit(cache=True)
def passing_limits(leader_lim: KernelLimits) -> KernelLimits:
    """The limits a leader passes obstacles with its whole formation in
    (``leader_keep_out_pad``): its ``leader_limits`` with the pitch rate held to its
    formation's turn rate as the yaw rate is.  A slot |x| behind rises or sinks at ω_θ·|x|
    as the leader pitches; planned in free space, the line abreast's leader dived under the
    sphere at the full pitch rate while it turned at the held one, and its formation broke."""
    lim = leader_lim
    pitch_rate = min(lim.max_pitch_rate, lim.leader_turn_rate)
    return with_turn_limits(
        lim,
        pitch_rate,
        lim.max_yaw_rate,
        lim.max_climb_angle,
        lim.max_dive_angle,
        lim.accel,
        lim.decel,
    )


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
    √(v_0² + 2 a_i d_i).  This is the equation as printed; the kernel uses it relative to
    the moving local target point (``catching_up_speed``).
    """
    v2 = leader_speed * leader_speed + 2.0 * accel * distance
    return math.sqrt(v2) if v2 > 0.0 else 0.0


@njit(cache=True)
def closing_speed_excess(distance: float, accel: float, gain: float) -> float:
    """The speed (m/s) a wingman ``distance`` metres from its local target point keeps over
    the point's, to arrive on it at the point's speed changing speed at ``accel`` at most:
    ``gain``·d near the point, √(2·a·d − a²/gain²) beyond a/gain² (Eq. 21–22 from there).

    Both pieces ask at most ``accel``: the relative speed g·d closes at g²·d, a at d = a/g²,
    where the two meet in value and slope (ArduPilot's ``sqrt_controller`` shape).  The
    smaller of g·d and √(2·a·d) asked 2a where they met (d = 2a/g²): at ArduPlane's scale
    (a = 0.6 m/s², g = 0.3 /s) the wingman was asked 1.2 m/s² 13 m from its slot, lagged the
    law and came through its slot 3–5 m/s off the leader's speed (the loiter route's first
    straight leg, wingmen overshooting 18 m, 12 m, 8 m).
    """
    d = max(distance, 0.0)
    if not gain < math.inf:
        return math.sqrt(2.0 * accel * d)
    linear_m = accel / (gain * gain)
    if d <= linear_m:
        return gain * d
    return math.sqrt(2.0 * accel * d - accel * linear_m)


@njit(cache=True)
def catching_up_speed(leader_speed: float, distance: float, decel: float, gain: float) -> float:
    """Speed from which a wingman ``distance`` metres from its local target point (the
    point not behind it) can just match the leader's speed there: Eq. 21–23 relative to
    the moving point (``closing_speed_excess``).

    The point moves at v_0, so the wingman closes on it at v_i − v_0, and Eq. 22 with that
    closing speed, Δd' = (v_i − v_0)Δt' − a_iΔt'²/2 with Δt' = (v_i − v_0)/a_i (Eq. 21), is
    (v_i − v_0)²/2a_i: Eq. 23 brakes once d_i ≤ Δd', so v_i ≤ v_0 + √(2·a_i·d_i).  Near
    the point the excess is ``gain``·d_i (the wingman's other corrections settle in 1/ω
    too), so that the speed does not jump by √(2·a·d) over the last metres.  As
    printed (``braking_speed``), Eq. 22 counts the wingman's own distance in the ICS and
    brakes from v_i² − v_0² = 2a_iΔd': 20 m behind at ArduPlane's 16 m/s and 0.8 m/s² it
    closed at 1 m/s, 15 s for the last 10 m.
    """
    return leader_speed + closing_speed_excess(distance, decel, gain)


@njit(cache=True)
def falling_back_speed(leader_speed: float, distance: float, accel: float, gain: float) -> float:
    """Speed at which a wingman ``distance`` metres ahead of its local target point gives
    the ground back and just matches the leader's speed there (where the paper is silent):
    ``catching_up_speed`` the other way, v_0 less ``closing_speed_excess`` with the
    acceleration a that restores its speed.
    """
    return max(leader_speed - closing_speed_excess(distance, accel, gain), 0.0)


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


@njit(cache=True, inline="always")
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
    the current heading (cos ψ, sin ψ) is kept.  Within the limit the attraction is the
    direction itself, G/|G| (no angle is taken: without ``atan2`` and its cosine and sine
    Table 3 plans 15–20 % faster); steeper, the limit's elevation in G's heading.
    """
    h2 = gx * gx + gy * gy
    if h2 > 0.0 and gz * gz <= TAN_MAX_FOLLOW_PITCH**2 * h2:
        g = math.sqrt(h2 + gz * gz)
        return gx / g, gy / g, gz / g
    if h2 == 0.0 and gz == 0.0:
        return cy, sy, 0.0
    h = math.sqrt(h2)
    cx_, cy_ = (gx / h, gy / h) if h > 0.0 else (cy, sy)
    ce = math.cos(MAX_FOLLOW_PITCH)
    return ce * cx_, ce * cy_, math.copysign(math.sin(MAX_FOLLOW_PITCH), gz)


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
    if ox * ox + oy * oy + oz * oz == 0.0 or f_yaw == 0.0:
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
def closing_speed(
    dx: float, dy: float, dz: float, d: float, ux: float, uy: float, uz: float
) -> float:
    """Speed at which a point moving at u approaches a vehicle at offset (dx, dy, dz)."""
    if d <= 0.0:
        return 0.0
    c = (ux * dx + uy * dy + uz * dz) / d
    return c if c > 0.0 else 0.0


@njit(cache=True)
def room_to_turn_away(
    dx: float,
    dy: float,
    dz: float,
    ux: float,
    uy: float,
    uz: float,
    travel: float,
    rho: float,
    keep_out: float,
) -> bool:
    """Whether a vehicle at offset (dx, dy, dz) from a static obstacle's centre, flying
    along the unit u, still clears the keep-out sphere (radius ``keep_out``) by a full-rate
    turn away from it on a circle of radius ρ begun ``travel`` metres further on (Fig. 2's
    geometry, as ``influence_radius``).

    The circle's centre lies ρ from the vehicle, normal to u in the plane of u and the
    offset, on the side away from the obstacle; with l the offset's part normal to u and
    d' the distance after the straight ``travel``, it keeps the keep-out if
    √(d'² + 2ρl + ρ²) − ρ ≥ keep_out, i.e. d'² + 2ρl ≥ keep_out·(keep_out + 2ρ).  Head-on
    (l = 0) that is d' ≥ R of ``influence_radius``; a vehicle not closing on the obstacle
    has room.
    """
    s = dx * ux + dy * uy + dz * uz  # < 0: closing
    if s >= 0.0:
        return True
    d2 = dx * dx + dy * dy + dz * dz
    lateral = math.sqrt(max(d2 - s * s, 0.0))
    after2 = d2 + 2.0 * travel * s + travel * travel
    return after2 + 2.0 * rho * lateral >= keep_out * (keep_out + 2.0 * rho)


@njit(cache=True)
def way_clear(
    px: float,
    py: float,
    hx: float,
    hy: float,
    radius: float,
    tx: float,
    ty: float,
    ox: float,
    oy: float,
    keep_out: float,
) -> bool:
    """Whether a vehicle at (px, py) heading along the horizontal unit (hx, hy), turning
    towards the point (tx, ty) on a circle of ``radius`` until it heads at it and flying
    straight on to it, keeps more than ``keep_out`` (plan view) from (ox, oy): the way
    the leader flies to its target once an obstacle lets it go (``leader_limits`` gives
    the turn).  False where that turn never heads at the point (it lies inside it).

    The turn's centre C lies ``radius`` to the side of the point; it heads at the point
    from Q, where the line from the point touches the circle (at acos(r/|T − C|) round
    from the point's bearing from C, back against the turn).  The way is the arc from the
    vehicle to Q and the segment from Q to the point."""
    dx, dy = tx - px, ty - py
    left = hx * dy - hy * dx >= 0.0
    nx, ny = (-hy, hx) if left else (hy, -hx)
    cx, cy = px + radius * nx, py + radius * ny
    ux, uy = tx - cx, ty - cy
    d = math.sqrt(ux * ux + uy * uy)
    if d <= radius:
        return False
    back = math.acos(radius / d) * (-1.0 if left else 1.0)
    bearing = math.atan2(uy, ux) + back
    qx, qy = cx + radius * math.cos(bearing), cy + radius * math.sin(bearing)
    # the arc: from the vehicle's bearing round C to Q's, in the turn's direction
    start = math.atan2(py - cy, px - cx)
    sweep = (bearing - start) if left else (start - bearing)
    sweep = sweep % (2.0 * math.pi)
    at = math.atan2(oy - cy, ox - cx)
    into = ((at - start) if left else (start - at)) % (2.0 * math.pi)
    if into <= sweep:
        near = abs(math.sqrt((ox - cx) ** 2 + (oy - cy) ** 2) - radius)
    else:
        near = min(math.hypot(ox - px, oy - py), math.hypot(ox - qx, oy - qy))
    # the segment from Q to the point
    sx, sy = tx - qx, ty - qy
    length2 = sx * sx + sy * sy
    f = 0.0 if length2 == 0.0 else ((ox - qx) * sx + (oy - qy) * sy) / length2
    f = min(max(f, 0.0), 1.0)
    near = min(near, math.hypot(ox - qx - f * sx, oy - qy - f * sy))
    return near > keep_out


@njit(cache=True)
def turn_missed_ahead(
    px: float,
    py: float,
    pz: float,
    ux: float,
    uy: float,
    uz: float,
    ox: float,
    oy: float,
    oz: float,
    radius: float,
    lead: float,
    speed: float,
    rate: float,
    tx: float,
    ty: float,
) -> bool:
    """Whether a vehicle at (px, py, pz) flying straight along the unit (ux, uy, uz) until
    it leaves the sphere of ``radius`` round (ox, oy, oz), and ``lead`` metres on, would
    find the point (tx, ty) inside its turn at ``rate`` there (``inside_turn``, at
    ``speed``): held on its course by an obstacle's influence to its edge, the leader
    would then have to turn faster than its formation follows.  The lead is the way it
    flies while its turn is eased in (``roll_in_lead``)."""
    dx, dy, dz = px - ox, py - oy, pz - oz
    along = dx * ux + dy * uy + dz * uz
    rest = along * along - (dx * dx + dy * dy + dz * dz - radius * radius)
    s = max(-along + math.sqrt(rest), 0.0) if rest > 0.0 else 0.0
    s += lead
    h = math.sqrt(ux * ux + uy * uy)
    if h <= 0.0:
        return False
    return inside_turn(px + s * ux, py + s * uy, ux / h, uy / h, speed, rate, tx, ty)


@njit(cache=True)
def roll_in_lead(speed: float, lim: KernelLimits) -> float:
    """The way (m) a leader at ``speed`` flies while its formation's turn is eased in: its
    wingmen's speeds change by up to √(2aε) (the roll-in limit of
    ``gcs_ppf.planning.turns``) at a, in √(2ε/a).  Let go just where holding on to the
    edge of the obstacle's influence would leave its target inside the formation's turn,
    the V of five turned in slower than that turn while it eased in, its target fell
    inside it, and it came round on a 110° arc with a wingman 12–16 m off (real
    ArduPlane, formation takeoff of five: in formation 63–69 % of the flight after
    forming)."""
    a = min(lim.accel, lim.decel)
    return speed * math.sqrt(2.0 * lim.target_accuracy / a)

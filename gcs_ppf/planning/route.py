"""The leader's route: its legs, and when the leader has flown one.

A mission's route (``Mission.route``) is the waypoints the leader flies through before its
target.  Leg k ends at waypoint k (the last leg at the target).  A leg is flown when the
leader passes within the waypoint's acceptance radius or, as ArduPlane counts a waypoint
passed wide, crosses its finish line: the vertical plane through the waypoint square to
the leg.  The target has no finish line: it is reached within the target accuracy.

A waypoint with a loiter (``Waypoint.loiter``) ends its leg once the leader has flown its
circles round it, as ArduPlane flies ``NAV_LOITER_TURNS``: from the leg's start the leader
is steered to the circle's tangent point, and near it to a point on the circle a little
ahead of it (``loiter_point``), which brings it onto the circle along a tangent; the turns
are counted by the angle it sweeps round the waypoint while on the circle (``swept_rad``),
the time from when it first came onto it.
The waypoint's acceptance radius does not apply.

A leader that holds its turns to what its formation follows cannot turn onto a waypoint
that lies inside that turn: it flies straight on to a turn point first, from which that
turn reaches the waypoint (``onto_target``), as a pilot flies out before turning back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from gcs_ppf.mission import Loiter, Mission
from gcs_ppf.planning.scene import FloatArray, kernel_limits
from gcs_ppf.planning.turns import formation_turn_limits, turn_envelope

LOITER_LEAD_RAD = math.radians(30.0)
"""How far round the circle, ahead of the leader, the point it is steered to lies."""
ON_CIRCLE = 0.25
"""The leader is on the circle within this fraction of its radius of it."""
TURN_POINT_WIDER = 0.1
"""From its turn point (``onto_target``) the waypoint lies this fraction of the turn's
radius outside the turn: the aircraft flies that turn no tighter than planned."""


@dataclass(frozen=True)
class Leg:
    """One leg of the route: from ``start_m`` to ``end_m`` (ICS), reached within
    ``radius_m`` or across the plane through ``end_m`` square to ``finish_normal``
    (horizontal unit vector along the leg; zeros for the target's leg); ``loiter``, the
    circles flown round ``end_m`` instead (the module docstring), on a circle of
    ``loiter_radius_m`` (its radius, or the tightest turn the formation holds if wider).
    ``turn_rate_rad_s`` is the fastest the leader turns (its formation's; ∞: as it can),
    and ``turn_point_m`` the point it flies straight on to first (``onto_target``), across
    the plane square to ``turn_heading`` there; ``turned_point``, that it has passed one."""

    index: int
    start_m: FloatArray
    end_m: FloatArray
    radius_m: float
    finish_normal: FloatArray
    loiter: Loiter | None = None
    loiter_radius_m: float = 0.0
    turn_rate_rad_s: float = math.inf
    turn_point_m: FloatArray | None = None
    turn_heading: FloatArray | None = None
    turned_point: bool = False

    @property
    def final(self) -> bool:
        return not bool(np.any(self.finish_normal))

    @property
    def aim_m(self) -> FloatArray:
        """Where the leader makes for: the turn point while it has one, else the end."""
        return self.end_m if self.turn_point_m is None else self.turn_point_m


def legs(mission: Mission) -> list[Leg]:
    """The route's legs in order, from the leader's start; one leg without a route.  A
    loiter is flown no tighter than the formation turns in formation (``turns``) when
    the leader holds its turns to that."""
    held_m, rate = 0.0, math.inf
    if mission.holds_turns and mission.wingmen:
        slots = np.array([w.slot for w in mission.wingmen], dtype=float)
        lim = kernel_limits(mission.limits, mission.ground)
        held_m = turn_envelope(slots, lim).turn_radius_m
        if mission.route:  # (``onto_target``)
            rate = formation_turn_limits(lim, slots).leader_turn_rate
    points = [np.array(w.position, dtype=float) for w in mission.route]
    radii = [w.acceptance_radius for w in mission.route]
    loiters = [w.loiter for w in mission.route]
    points.append(np.array(mission.target, dtype=float))
    radii.append(mission.limits.target_accuracy)
    loiters.append(None)
    out: list[Leg] = []
    start = np.array(mission.leader.position, dtype=float)
    for k, (end, radius, loiter) in enumerate(zip(points, radii, loiters, strict=True)):
        final = k == len(points) - 1
        normal = np.zeros(3) if final else _along(start, end)
        circle_m = 0.0 if loiter is None else max(loiter.radius_m, held_m)
        out.append(Leg(k, start, end, radius, normal, loiter, circle_m, rate))
        start = end
    return out


def _along(start: FloatArray, end: FloatArray) -> FloatArray:
    """The horizontal unit vector from ``start`` to ``end`` (zeros if one is above the other:
    such a leg ends within its radius only)."""
    d = np.array([end[0] - start[0], end[1] - start[1], 0.0])
    n = math.hypot(d[0], d[1])
    return d / n if n > 0.0 else np.zeros(3)


def turn_point(
    end_m: FloatArray, position_m: FloatArray, yaw_rad: float, radius_m: float
) -> FloatArray | None:
    """The point straight on from ``position_m`` (heading ``yaw_rad``, ICS) from which a turn
    of ``radius_m`` towards ``end_m`` passes ``TURN_POINT_WIDER`` of the radius outside it,
    at ``end_m``'s altitude; None if that turn reaches it from here (it lies outside).

    In the leader's frame the end lies ``a`` ahead and ``b`` to the side; the turn towards
    it is the circle of radius r centred r to that side, which holds it while
    a² + (|b| − r)² < r².  Flown s further, the end lies (1 + w)·r from that circle's
    centre when (a − s)² + (|b| − r)² = ((1 + w)·r)²: s = a + √(((1 + w)·r)² − (|b| − r)²)."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    dx, dy = float(end_m[0] - position_m[0]), float(end_m[1] - position_m[1])
    ahead, side = dx * c + dy * s, abs(-dx * s + dy * c)
    r = radius_m
    if ahead * ahead + (side - r) ** 2 >= r * r:
        return None
    run = ahead + math.sqrt(((1.0 + TURN_POINT_WIDER) * r) ** 2 - (side - r) ** 2)
    return np.array([position_m[0] + run * c, position_m[1] + run * s, end_m[2]])


def onto_target(leg: Leg, position_m: FloatArray, yaw_rad: float, speed_m_s: float) -> Leg:
    """``leg`` with the leader's turn point decided, or passed: a leader that holds its
    turns (``turn_rate_rad_s``) and finds its waypoint inside the turn it flies at
    ``speed_m_s`` flies straight on to the ``turn_point`` first (kept until it crosses the
    plane square to its heading there, so that it does not turn early); a loiter's waypoint
    it is steered round (``loiter_point``).

    Turned onto at the airframe's full rate, the loiter route's target (1 km on from the
    last waypoint, inside the 633 m turn the V follows) broke the formation for 25 s (the
    worst wingman 46–115 m off its slot planned, 50–91 m flown).  Judged afresh at every
    step instead, the leader came out of its straight run with the target on the turn's
    edge, where flying straight and turning both keep it, and circled it for ever.

    A leg has one turn point at most: past it, the turn's radius is the leader's speed over
    its turn rate, and a leader faster than when the point was laid out (more than the
    point's 10 % of radius) found its waypoint inside the turn again and flew out to a new
    point, and again: ArduPlane's airspeed, 1 m/s behind its demand and overshooting after
    it, set four in turn on the loiter route's last leg, which ran out of time 79 m short.
    Past its point the leader turns onto its waypoint; inside its turn still, at the
    airframe's rate.

    Only a route's legs have turn points (``legs``): a mission without one flies to its
    target as it can once an obstacle has turned it away (the line abreast of five, whose
    formation turns on 1.27 km, took more than 400 s round to a target 1.3 km off where it
    takes 179 s)."""
    if leg.loiter is not None or not 0.0 < leg.turn_rate_rad_s < math.inf or leg.turned_point:
        return leg
    if leg.turn_point_m is not None and leg.turn_heading is not None:
        if float((position_m - leg.turn_point_m) @ leg.turn_heading) < 0.0:
            return leg  # not there yet
        return replace(leg, turn_point_m=None, turn_heading=None, turned_point=True)
    point = turn_point(leg.end_m, position_m, yaw_rad, speed_m_s / leg.turn_rate_rad_s)
    if point is None:
        return leg
    heading = np.array([math.cos(yaw_rad), math.sin(yaw_rad), 0.0])
    return replace(leg, turn_point_m=point, turn_heading=heading)


def leg_flown(leg: Leg, previous_m: FloatArray | None, position_m: FloatArray) -> bool:
    """Whether the leader, from ``previous_m`` (None: not known) to ``position_m``, came
    within the leg's radius of its end or crossed its finish line.  The whole segment
    counts: telemetry at 10 Hz can step over a 10 m sphere."""
    end = leg.end_m
    if previous_m is None:
        return bool(np.linalg.norm(position_m - end) <= leg.radius_m)
    seg = position_m - previous_m
    length2 = float(seg @ seg)
    s = 0.0 if length2 == 0.0 else min(max(float((end - previous_m) @ seg) / length2, 0.0), 1.0)
    if np.linalg.norm(previous_m + s * seg - end) <= leg.radius_m:
        return True
    if leg.final:
        return False
    n = leg.finish_normal
    return bool(float((previous_m - end) @ n) < 0.0 <= float((position_m - end) @ n))


def loiter_point(leg: Leg, position_m: FloatArray) -> FloatArray:
    """Where the leader loitering round ``leg``'s end is steered: on the circle, round from
    its own bearing from the centre in the direction of circling, at the centre's altitude
    (from the centre itself, along the leg).  Near the circle the point lies
    ``LOITER_LEAD_RAD`` round; further out than where that point is the tangent point, at
    the tangent point, which stays where it is as the leader flies to it: the approach is
    a straight line, as each tick's plan sees it (steered ``LOITER_LEAD_RAD`` round from afar,
    the leader curves in slowly where each plan sees it fly straight, and its wingmen fall
    inside that turn)."""
    assert leg.loiter is not None
    c = leg.end_m
    r = leg.loiter_radius_m
    dx, dy = float(position_m[0] - c[0]), float(position_m[1] - c[1])
    d = math.hypot(dx, dy)
    if d < 1e-6:
        dx, dy = float(leg.finish_normal[0]), float(leg.finish_normal[1])
    round_rad = max(LOITER_LEAD_RAD, math.acos(r / d)) if d > r else LOITER_LEAD_RAD
    lead = -round_rad if leg.loiter.clockwise else round_rad  # ENU: x east, y north
    a = math.atan2(dy, dx) + lead
    return np.array([c[0] + r * math.cos(a), c[1] + r * math.sin(a), c[2]])


def leader_target(leg: Leg, position_m: FloatArray | None) -> FloatArray:
    """Where the leader at ``position_m`` (None: not known) is steered on ``leg``: round a
    loiter's circle (``loiter_point``), else to its turn point while it has one
    (``onto_target``), else to the leg's end."""
    if leg.loiter is not None and position_m is not None:
        return loiter_point(leg, position_m)
    return leg.aim_m


def on_circle(leg: Leg, position_m: FloatArray) -> bool:
    """Whether the leader is on ``leg``'s loiter circle (within ``ON_CIRCLE`` of its radius,
    horizontally)."""
    d = math.hypot(float(position_m[0] - leg.end_m[0]), float(position_m[1] - leg.end_m[1]))
    return abs(d - leg.loiter_radius_m) <= ON_CIRCLE * leg.loiter_radius_m


def swept_rad(leg: Leg, previous_m: FloatArray, position_m: FloatArray) -> float:
    """The angle the leader swept round ``leg``'s end from ``previous_m`` to ``position_m``
    in the loiter's direction (negative the other way); 0 unless both are on the circle
    (``on_circle``)."""
    assert leg.loiter is not None
    if not (on_circle(leg, previous_m) and on_circle(leg, position_m)):
        return 0.0
    a, b = previous_m[:2] - leg.end_m[:2], position_m[:2] - leg.end_m[:2]
    turn = math.atan2(float(a[0] * b[1] - a[1] * b[0]), float(a @ b))  # anticlockwise
    return -turn if leg.loiter.clockwise else turn


@dataclass(frozen=True)
class Loitering:
    """A loiter leg under way: the leader's last position, when it first came onto the
    circle (mission time; None: not yet) and the angle swept round the waypoint since
    (``swept_rad``)."""

    last_m: FloatArray
    began_s: float | None = None
    swept: float = 0.0

    def on(self, leg: Leg, path_m: FloatArray, t_s: float) -> Loitering:
        """After the leader flew through ``path_m`` ([K,3], in order) to mission time
        ``t_s``."""
        swept, last, began = self.swept, self.last_m, self.began_s
        for position in path_m:
            swept += swept_rad(leg, last, position)
            if began is None and on_circle(leg, position):
                began = t_s
            last = position
        return Loitering(np.array(last, dtype=float), began, swept)

    def flown(self, loiter: Loiter, t_s: float) -> bool:
        """Whether it is done at mission time ``t_s``: its turns swept, or its time out."""
        if loiter.turns is not None:
            return self.swept >= 2.0 * math.pi * loiter.turns
        return self.began_s is not None and t_s - self.began_s >= (loiter.time_s or 0.0)

"""Where a vehicle holds once the service stops planning for it (completion, abort, failure):
a loiter circle, at a radius it can fly, that cuts no obstacle's keep-out and is reached
without crossing one; and how the service flies a vehicle onto it and round it
(``loiter_course``) until it is on it (``on_ring``) and the circle can be handed to the
autopilot (``service.hold_flight``).

Pure. Flown closed loop, vehicles left circling a point straight ahead of them flew through
an obstacle after the run had ended (issue 10: Table 3 at 10×, 4 of 6 runs). Candidates are
tried nearest the vehicle's heading first, then further out; the first circle whose ring (at the
radius asked and at the wider one ArduPlane flies, radius / η) and whose approach keep the
safe distance wins.  The approach is flown as the service flies it (``loiter_course``,
turning at the vehicle's turn rate, climbing at its limits) when its ``Motion`` is given; a
straight line from the vehicle to the ring otherwise (a vehicle at
210 m/s turning 400 m wide onto a circle checked as a straight line flew 46 m into a sphere
after a run had ended, issue 10 (d)); and the ring is checked as wide as the capture can
swing out, a turn's radius beyond radius / η (at 200 m/s, a wingman captured on a 525 m
circle flew 240 m outside it, into a sphere, campaign (c)).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gcs_ppf.guidance.vehicle_motion import Motion
from gcs_ppf.mavlink.ardupilot import TURN_EFFICIENCY
from gcs_ppf.planning.scene import FloatArray, Obstacles
from gcs_ppf.planning.zones import Zones, zone_clearances

#: Bearings tried, off the vehicle's heading (radians), nearest first.
BEARINGS = tuple(math.radians(b) for b in (0, 30, -30, 60, -60, 90, -90, 120, -120, 150, -150, 180))
#: Distances of the circle's centre tried, in loiter radii beyond the first ``ahead_m``.
REACH_STEPS = (0.0, 2.0, 4.0, 8.0)
#: Points sampled along the approach.
APPROACH_SAMPLES = 24
#: Points sampled round a ring, for the zones (a chord sags 0.1 % of the radius).
RING_SAMPLES = 72
#: Seconds between the points of a flown approach, and the longest approach flown.
APPROACH_STEP_S = 0.5
APPROACH_MAX_S = 180.0
#: A vehicle flies its hold (``on_ring``) within this of its height (m) …
SETTLED_HEIGHT_M = 10.0
#: … level within this (m/s) …
SETTLED_CLIMB_M_S = 2.0
#: … and its course within this of the ring's tangent (radians).
SETTLED_COURSE_RAD = math.radians(30.0)


@dataclass(frozen=True, slots=True)
class Hold:
    """A loiter circle: centre (ICS x, y), height, radius; and its smallest clearance to an
    obstacle's or a zone's surface along the ring and the approach (inf without either)."""

    x_m: float
    y_m: float
    z_m: float
    radius_m: float
    clearance_m: float


def ring_clearance(x: float, y: float, z: float, r: float, obstacles: Obstacles) -> float:
    """Smallest distance from the horizontal circle (centre x, y at height z, radius r) to
    any obstacle's surface."""
    if obstacles.radius.shape[0] == 0:
        return math.inf
    c = obstacles.center
    horizontal = np.hypot(c[:, 0] - x, c[:, 1] - y)
    gap = np.hypot(horizontal - r, c[:, 2] - z) - obstacles.radius
    return float(gap.min())


def path_clearance(a: FloatArray, b: FloatArray, obstacles: Obstacles) -> float:
    """Smallest distance from the segment a → b to any obstacle's surface."""
    if obstacles.radius.shape[0] == 0:
        return math.inf
    ab = b - a
    rel = obstacles.center - a
    s = np.clip((rel @ ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0)
    closest = a + s[:, None] * ab
    return float((np.linalg.norm(obstacles.center - closest, axis=1) - obstacles.radius).min())


def clear_run_m(
    start: FloatArray,
    direction: FloatArray,
    obstacles: Obstacles,
    zones: Zones | None,
    keep_m: float,
    max_m: float,
    step_m: float = 10.0,
) -> float:
    """How far from ``start`` along the unit ``direction`` a straight path stays ``keep_m``
    or more from every obstacle's and zone's surface, at most ``max_m``: spheres exactly
    (the first crossing of the sphere grown by ``keep_m``; within it, 0 unless the path
    leads away), zones at every ``step_m`` (0 where it starts within ``keep_m``)."""
    run = max_m
    for c, r in zip(obstacles.center, obstacles.radius, strict=True):
        rel = start - c
        grown = r + keep_m
        far = float(rel @ rel) - grown * grown
        along = float(rel @ direction)
        if far <= 0.0:
            if along < 0.0:  # within it and closing
                return 0.0
            continue
        disc = along * along - far
        if along < 0.0 and disc >= 0.0:  # closing, and the line cuts the grown sphere
            run = min(run, -along - math.sqrt(disc))
    if zones is not None and len(zones):
        s = np.arange(0.0, run + step_m, step_m)
        points = start + np.minimum(s, run)[:, None] * direction
        inside = np.flatnonzero(zone_clearances(points, zones) < keep_m)
        if inside.size:
            run = float(max(s[inside[0]] - step_m, 0.0))
    return run


def clear_course(
    start: FloatArray,
    course_rad: float,
    obstacles: Obstacles,
    zones: Zones | None,
    keep_m: float,
    max_m: float,
    enough_m: float,
) -> tuple[float, float]:
    """A level course (ICS yaw, rad) nearest ``course_rad`` (``BEARINGS`` off it, in order)
    along which ``clear_run_m`` runs ``enough_m`` or more, and that run; where none does,
    the one that runs furthest."""
    best = (course_rad, -1.0)
    for bearing in BEARINGS:
        yaw = course_rad + bearing
        way = np.array([math.cos(yaw), math.sin(yaw), 0.0])
        run = clear_run_m(start, way, obstacles, zones, keep_m, max_m)
        if run >= enough_m:
            return yaw, run
        if run > best[1]:
            best = (yaw, run)
    return best


def flown_radius_m(radius_m: float) -> float:
    """The radius a loiter of ``radius_m`` is flown at: ArduPlane's turns give η of a
    coordinated one's rate (``TURN_EFFICIENCY``), so its circle is radius / η."""
    return radius_m / TURN_EFFICIENCY


def loiter_course(
    pos_m: Sequence[float] | FloatArray,
    x: float,
    y: float,
    ring_radius_m: float,
    speed_m_s: float,
    turn_rate_rad_s: float,
    heading_tau_s: float,
) -> float:
    """The course (ICS yaw) that flies a vehicle onto the ring of radius ``ring_radius_m``
    round (x, y) and clockwise round it: a vector field (Nelson et al., "Vector field path
    following for miniature air vehicles", 2007) straight at the centre from afar, the
    ring's tangent on it, 45° off the tangent a turn's radius (``speed_m_s`` /
    ``turn_rate_rad_s``) off the ring; on and near the ring led by the turn the ring asks ×
    ``heading_tau_s`` (GUIDED's course P-controller turns at the course error over that
    time constant, so a vehicle told the tangent itself settles outside the ring)."""
    dx, dy = float(pos_m[0]) - x, float(pos_m[1]) - y
    out_from_centre = math.atan2(dy, dx)
    turn_radius = max(speed_m_s, 1.0) / max(turn_rate_rad_s, 1e-6)
    off = (math.hypot(dx, dy) - ring_radius_m) / turn_radius
    near = 1.0 / (1.0 + off * off)
    lead = near * heading_tau_s * max(speed_m_s, 1.0) / max(ring_radius_m, 1.0)
    return math.remainder(out_from_centre - math.pi / 2.0 - math.atan(off) - lead, math.tau)


def on_ring(
    pos_m: Sequence[float] | FloatArray,
    yaw_rad: float,
    climb_rate_m_s: float,
    hold: Hold,
    speed_m_s: float,
    turn_rate_rad_s: float,
) -> bool:
    """Whether a vehicle flies its hold: at its height (``SETTLED_HEIGHT_M``, level within
    ``SETTLED_CLIMB_M_S``), within half a turn's radius of the ring as flown
    (``flown_radius_m``) and along it, clockwise (``SETTLED_COURSE_RAD``)."""
    dx, dy = float(pos_m[0]) - hold.x_m, float(pos_m[1]) - hold.y_m
    turn_radius = max(speed_m_s, 1.0) / max(turn_rate_rad_s, 1e-6)
    off = abs(math.hypot(dx, dy) - flown_radius_m(hold.radius_m))
    tangent = math.atan2(dy, dx) - math.pi / 2.0
    return (
        abs(float(pos_m[2]) - hold.z_m) <= SETTLED_HEIGHT_M
        and abs(climb_rate_m_s) <= SETTLED_CLIMB_M_S
        and off <= 0.5 * turn_radius
        and abs(math.remainder(yaw_rad - tangent, math.tau)) <= SETTLED_COURSE_RAD
    )


def approach_path(m: Motion, x: float, y: float, z: float, radius_m: float) -> FloatArray:
    """Where a vehicle flies [k,3] from its state ``m`` to the loiter ring of ``radius_m``
    round (x, y) at height z, as the service flies it there (``loiter_course``, the course
    followed first order with its heading time constant at most at its turn rate), climbing
    or sinking at its limits, until it is on the ring, then once around the ring's first
    half (the capture swings out)."""
    px, py, pz = m.pos_m
    yaw = m.yaw_rad
    dt = APPROACH_STEP_S
    out = [(px, py, pz)]
    t, on_ring_s = 0.0, None
    half_turn_s = math.pi * radius_m / max(m.speed_m_s, 1.0)
    turn_radius = max(m.speed_m_s, 1.0) / max(m.turn_rate_rad_s, 1e-6)
    while t < APPROACH_MAX_S:
        if on_ring_s is None and abs(math.hypot(x - px, y - py) - radius_m) <= 0.5 * turn_radius:
            on_ring_s = t
        if on_ring_s is not None and t - on_ring_s >= half_turn_s:
            break
        aim = loiter_course(
            (px, py), x, y, radius_m, m.speed_m_s, m.turn_rate_rad_s, m.heading_tau_s
        )
        err = math.remainder(aim - yaw, math.tau)
        rate = max(-m.turn_rate_rad_s, min(m.turn_rate_rad_s, err / max(m.heading_tau_s, dt)))
        yaw += rate * dt
        px += m.speed_m_s * math.cos(yaw) * dt
        py += m.speed_m_s * math.sin(yaw) * dt
        pz += max(-m.sink_m_s * dt, min(m.climb_m_s * dt, z - pz))
        out.append((px, py, pz))
        t += dt
    return np.array(out)


def points_clearance(points: FloatArray, obstacles: Obstacles) -> float:
    """Smallest distance from any of ``points`` [k,3] to any obstacle's surface."""
    if obstacles.radius.shape[0] == 0:
        return math.inf
    gap = np.linalg.norm(points[:, None] - obstacles.center[None], axis=-1) - obstacles.radius
    return float(gap.min())


def zones_clearance(points: FloatArray, zones: Zones | None) -> float:
    """Smallest distance from any of ``points`` [k,3] to any zone's surface (its free
    side positive); inf without zones."""
    if zones is None or not len(zones) or not len(points):
        return math.inf
    return float(zone_clearances(points, zones).min())


def ring_points(x: float, y: float, z: float, r: float) -> FloatArray:
    """``RING_SAMPLES`` points round the horizontal circle (centre x, y at height z, radius r)."""
    a = np.linspace(0.0, math.tau, RING_SAMPLES, endpoint=False)
    return np.column_stack((x + r * np.cos(a), y + r * np.sin(a), np.full(RING_SAMPLES, z)))


def ring_gap(x: float, y: float, wide_m: float, taken: Sequence[tuple[Hold, float]]) -> float:
    """Smallest horizontal gap between the ring flown at centre (x, y), ``wide_m`` wide, and
    the rings already ``taken`` (each with the width it is flown at); inf without any."""
    gaps = [math.hypot(x - h.x_m, y - h.y_m) - wide_m - w for h, w in taken]
    return min(gaps, default=math.inf)


def flown_width_m(radius_m: float, motion: Motion | None) -> float:
    """How wide a circle of ``radius_m`` is flown: radius / η, and the capture swings out by
    up to a turn's radius beyond it."""
    wide = flown_radius_m(radius_m)
    if motion is not None:
        wide += motion.speed_m_s / max(motion.turn_rate_rad_s, 1e-6)
    return wide


def hold_at(
    pos_m: FloatArray,
    z_m: float,
    radius_m: float,
    x: float,
    y: float,
    heading: float,
    obstacles: Obstacles,
    motion: Motion | None,
    zones: Zones | None = None,
) -> Hold:
    """The circle centred at (x, y), ``heading`` the way from the vehicle to it, with its
    clearance along the ring (as asked and as flown) and the approach, from the obstacles
    and the ``zones`` (a hold after a run once circled through a no-fly zone's wall the
    spheres alone had let it cut: ``examples/scene_u_pocket.json`` under load)."""
    start = np.asarray(pos_m, dtype=float)
    if motion is None:
        entry = np.array([x - radius_m * math.cos(heading), y - radius_m * math.sin(heading), z_m])
        approach = path_clearance(start, entry, obstacles)
        way = start + np.linspace(0.0, 1.0, APPROACH_SAMPLES)[:, None] * (entry - start)
    else:
        way = approach_path(motion, x, y, z_m, flown_radius_m(radius_m))
        approach = points_clearance(way, obstacles)
    wide = flown_width_m(radius_m, motion)
    clear = min(
        ring_clearance(x, y, z_m, radius_m, obstacles),
        ring_clearance(x, y, z_m, wide, obstacles),
        approach,
    )
    if zones is not None and len(zones):
        rings = (ring_points(x, y, z_m, radius_m), ring_points(x, y, z_m, wide))
        clear = min(clear, zones_clearance(np.concatenate((*rings, way)), zones))
    return Hold(x, y, z_m, radius_m, clear)


@dataclass(frozen=True, slots=True)
class HoldRequest:
    """A vehicle to hold: where it is, its heading, the height and radius of its circle,
    and its response (None: approached in a straight line)."""

    pos_m: FloatArray
    yaw_rad: float
    z_m: float
    radius_m: float
    motion: Motion | None


def formation_holds(
    requests: Sequence[HoldRequest],
    yaw_rad: float,
    ahead_m: float,
    obstacles: Obstacles,
    keep_out_m: float,
    zones: Zones | None = None,
) -> list[Hold] | None:
    """Every vehicle's circle at its own position moved by one same vector (``ahead_m``
    or further, nearest the bearing ``yaw_rad`` first): the formation as it flies now,
    translated, so the approaches are parallel and the circles — all flown clockwise, each
    vehicle starting it where its teammates start theirs — keep the vehicles' present
    spacing (circles chosen one vehicle at a time, clear of each other, made two wingmen
    cross on the way to them, 7.1 m apart on real ArduPlane); None if no vector keeps every
    circle and approach ``keep_out_m`` from the obstacles."""
    if not requests:
        return []
    reach = max(r.radius_m for r in requests)
    for step in REACH_STEPS:
        d = ahead_m + step * reach
        for bearing in BEARINGS:
            heading = yaw_rad + bearing
            dx, dy = d * math.cos(heading), d * math.sin(heading)
            centres = [(float(r.pos_m[0]) + dx, float(r.pos_m[1]) + dy, heading) for r in requests]
            holds = _clear_holds(requests, centres, obstacles, keep_out_m, zones)
            if holds is not None:
                return holds
    return None


def spread_holds(
    requests: Sequence[HoldRequest],
    yaw_rad: float,
    ahead_m: float,
    separation_m: float,
    obstacles: Obstacles,
    keep_out_m: float,
    zones: Zones | None = None,
) -> list[Hold] | None:
    """Every vehicle's circle on a grid ahead of the fleet (the nearest row ``ahead_m`` or
    further beyond its foremost vehicle, nearest the bearing ``yaw_rad`` first) whose rings,
    as flown (``flown_width_m``), are ``separation_m`` apart: no two circles cross at any
    height, so none is stacked above another and no vehicle climbs to its hold
    (``grid_centres``); None if no placement keeps every circle and approach ``keep_out_m``
    from the obstacles."""
    if not requests:
        return []
    pos = np.array([r.pos_m[:2] for r in requests], dtype=float)
    wide = max(flown_width_m(r.radius_m, r.motion) for r in requests)
    pitch = 2.0 * wide + separation_m
    for step in REACH_STEPS:
        for bearing in BEARINGS:
            grid = grid_centres(pos, yaw_rad + bearing, ahead_m + step * wide, pitch)
            centres = [
                (x, y, math.atan2(y - float(r.pos_m[1]), x - float(r.pos_m[0])))
                for r, (x, y) in zip(requests, grid, strict=True)
            ]
            holds = _clear_holds(requests, centres, obstacles, keep_out_m, zones)
            if holds is not None:
                return holds
    return None


def _clear_holds(
    requests: Sequence[HoldRequest],
    centres: Sequence[tuple[float, float, float]],
    obstacles: Obstacles,
    keep_out_m: float,
    zones: Zones | None,
) -> list[Hold] | None:
    """Each request's circle round its centre (x, y), approached along the bearing ``way``
    of ``centres`` [(x, y, way)] (``hold_at``); None as soon as one comes nearer the
    obstacles than ``keep_out_m``: that placement fails, the caller tries the next."""
    holds = []
    for r, (x, y, way) in zip(requests, centres, strict=True):
        hold = hold_at(r.pos_m, r.z_m, r.radius_m, x, y, way, obstacles, r.motion, zones)
        if hold.clearance_m < keep_out_m:
            return None
        holds.append(hold)
    return holds


def grid_centres(
    pos_m: FloatArray, heading_rad: float, ahead_m: float, pitch_m: float
) -> list[tuple[float, float]]:
    """Centres [n] for vehicles at ``pos_m`` [n,2] on a square grid ``pitch_m`` apart, its
    nearest row ``ahead_m`` beyond the foremost vehicle along ``heading_rad``, its rows
    centred across the fleet.  The grid keeps the fleet's order: its foremost vehicles to the
    furthest row, and each row in their order across, so that the ways out fan apart."""
    n = len(pos_m)
    cols = math.ceil(math.sqrt(n))
    rows = math.ceil(n / cols)
    fwd = np.array([math.cos(heading_rad), math.sin(heading_rad)])
    side = np.array([-fwd[1], fwd[0]])
    along, across = pos_m @ fwd, pos_m @ side
    nearest, middle = float(along.max()) + ahead_m, float(across.mean())
    foremost = sorted(range(n), key=lambda i: -along[i])
    centres: list[tuple[float, float]] = [(0.0, 0.0)] * n
    for k in range(rows):
        row = sorted(foremost[k * cols : (k + 1) * cols], key=lambda i: across[i])
        row_along = nearest + (rows - 1 - k) * pitch_m
        for c, i in enumerate(row):
            x, y = row_along * fwd + (middle + (c - (len(row) - 1) / 2.0) * pitch_m) * side
            centres[i] = (float(x), float(y))
    return centres


def holding_circle(
    pos_m: FloatArray,
    yaw_rad: float,
    z_m: float,
    radius_m: float,
    ahead_m: float,
    obstacles: Obstacles,
    keep_out_m: float,
    motion: Motion | None = None,
    taken: Sequence[tuple[Hold, float]] = (),
    separation_m: float = 0.0,
    zones: Zones | None = None,
) -> Hold:
    """The loiter circle for a vehicle at ``pos_m`` heading ``yaw_rad``: centred ``ahead_m``
    (or further) off its nose, as near the heading as keeps ``keep_out_m`` from every
    obstacle along the ring and the way there, and whose ring stays ``separation_m`` clear
    of the rings ``taken`` by teammates (whatever their heights: an ArduPlane climbs its
    100 m of the stack in 20 s, and two wingmen on overlapping circles 31 m apart in height
    came to 46.5 m of each other); if none does, the one with most to spare."""
    best: Hold | None = None
    best_spare = -math.inf
    for step in REACH_STEPS:
        d = ahead_m + step * radius_m
        for bearing in BEARINGS:
            heading = yaw_rad + bearing
            x = float(pos_m[0]) + d * math.cos(heading)
            y = float(pos_m[1]) + d * math.sin(heading)
            hold = hold_at(pos_m, z_m, radius_m, x, y, heading, obstacles, motion, zones)
            wide = flown_width_m(radius_m, motion)
            spare = min(hold.clearance_m - keep_out_m, ring_gap(x, y, wide, taken) - separation_m)
            if spare >= 0.0:
                return hold
            if best is None or spare > best_spare:
                best, best_spare = hold, spare
    assert best is not None
    return best

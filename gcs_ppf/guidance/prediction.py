"""The run-time assurance's prediction, compiled: where a vehicle flies holding a command,
its escape turns from there, and how far a predicted path stays outside the keep-outs.

Pure, ``@njit`` (numba) on plain floats and arrays: ``gcs_ppf.guidance.assurance`` packs a
``Motion`` into the vector ``m`` below (``motion_vector``) and reads the results back.
Interpreted, one command's score (its hold and both escapes) took 0.2–0.4 ms, and a vehicle
in trouble tries up to 36 of them: 7 ms a tick for each one escaping, at the very moment
the tick had to be on time (×10 under load the service's loop then fell seconds behind its
telemetry and the escapes came late).  The model is the one ``assurance`` documents.

``m``: x, y, z, yaw, speed, turn rate, climb, sink, heading τ, yaw rate, roll lag, roll rate,
vertical speed, climb lag, height gain.
A predicted flight ``f``: x, y, z, yaw, bank (+ left), vertical speed, TECS's height demand.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit

from gcs_ppf.guidance.airframe import G_M_S2
from gcs_ppf.mavlink.ardupilot import TURN_EFFICIENCY
from gcs_ppf.planning.scene import FloatArray, IntArray
from gcs_ppf.planning.zones import nearest_zone_clearance

X, Y, Z, YAW, SPEED, TURN, CLIMB, SINK, TAU, YAW_RATE, ROLL_LAG, ROLL_RATE = range(12)
VZ, CLIMB_LAG, HEIGHT_GAIN = 12, 13, 14
MOTION_SIZE = 15
BANK, FLIGHT_VZ, HEIGHT_DEMAND = 4, 5, 6  # in a predicted flight, after x, y, z, yaw
FLIGHT_SIZE = 7

STEP_S = 0.125
"""Seconds between predicted samples (the roll loop's lag is ~0.2 s: integrated exactly)."""
ROLLED_IN_RAD = math.radians(0.5)
"""An escape's bank this near full (rad) is flown on as a circle."""
_LIFT = TURN_EFFICIENCY * G_M_S2

NO_KEEP_OUT, OBSTACLE, GROUND, TEAMMATE, ZONE = 0, 1, 2, 3, 4
"""Which keep-out a margin is to (``margin``'s second result)."""


@njit(cache=True)
def wrap(a: float) -> float:
    """An angle in [−π, π)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@njit(cache=True)
def bank_for(m: FloatArray, yaw_rate_rad_s: float) -> float:
    """The bank (rad, + left) that turns at ``yaw_rate_rad_s`` (a coordinated turn, at the
    airframe's measured ``TURN_EFFICIENCY``)."""
    return math.atan(yaw_rate_rad_s * max(m[SPEED], 1e-6) / _LIFT)


@njit(cache=True)
def yaw_rate_for(m: FloatArray, bank_rad: float) -> float:
    """The turn (rad/s, + left) that ``bank_rad`` gives."""
    return float(_LIFT * math.tan(bank_rad) / max(m[SPEED], 1e-6))


@njit(cache=True)
def demand_lead(m: FloatArray, vz: float) -> float:
    """How far TECS's height demand leads the altitude of a vehicle at vertical speed
    ``vz``: the climb-rate demand's lead, and as much again as the vertical speed lags
    (at the limits the demand runs on ahead: against the SITL, a dive at 84 m/s told to
    climb dipped 47 m; with the lead vz / gain alone the prediction said 31 m); 0 for an
    airframe whose vertical speed changes at once."""
    if math.isinf(m[HEIGHT_GAIN]):
        return 0.0
    return float(vz * (1.0 / m[HEIGHT_GAIN] + m[CLIMB_LAG]))


@njit(cache=True)
def height_demand_now(m: FloatArray) -> float:
    """TECS's height demand as the vertical speed the vehicle flies gives it
    (``demand_lead``); also the height it would level off at, told to hold where it is."""
    return float(m[Z] + demand_lead(m, m[VZ]))


@njit(cache=True)
def climb(m: FloatArray, f: FloatArray, z_demand: float, dt: float) -> None:
    """``dt`` seconds of the height loop, ``f`` in place, as ``sitl.physics`` flies it
    (calibrated to ArduPlane): TECS's height demand moves towards ``z_demand`` at the climb
    and sink limits, its climb-rate demand is the gain × the demand's lead on the altitude
    (within the limits), and the vertical speed lags behind that (first order).  With an
    infinite gain and no lag (an airframe not known to be ArduPlane) the altitude goes
    straight at ``z_demand`` at the limits, as if the vertical speed could change at once."""
    gain = m[HEIGHT_GAIN]
    if math.isinf(gain):
        wanted = max(-m[SINK], min(m[CLIMB], (z_demand - f[Z]) / dt))
    else:
        f[HEIGHT_DEMAND] += max(-m[SINK] * dt, min(m[CLIMB] * dt, z_demand - f[HEIGHT_DEMAND]))
        wanted = max(-m[SINK], min(m[CLIMB], gain * (f[HEIGHT_DEMAND] - f[Z])))
    vz = wanted
    if m[CLIMB_LAG] > 0.0:
        vz = f[FLIGHT_VZ] + (wanted - f[FLIGHT_VZ]) * (1.0 - math.exp(-dt / m[CLIMB_LAG]))
    f[FLIGHT_VZ] = vz
    f[Z] += vz * dt


@njit(cache=True)
def step(m: FloatArray, f: FloatArray, bank_demand: float, z_demand: float, dt: float) -> None:
    """``dt`` seconds of flight, ``f`` in place: the bank towards its demand (first order,
    rate limited), the turn it gives, the altitude towards ``z_demand`` (``climb``)."""
    gap = bank_demand - f[BANK]
    if m[ROLL_LAG] > 0.0:
        gap *= 1.0 - math.exp(-dt / m[ROLL_LAG])
    limit = m[ROLL_RATE] * dt
    bank = f[BANK] + max(-limit, min(limit, gap))
    rate = 0.5 * (yaw_rate_for(m, f[BANK]) + yaw_rate_for(m, bank))
    f[BANK] = bank
    mid = f[YAW] + 0.5 * rate * dt
    f[YAW] += rate * dt
    f[X] += m[SPEED] * math.cos(mid) * dt
    f[Y] += m[SPEED] * math.sin(mid) * dt
    climb(m, f, z_demand, dt)


@njit(cache=True)
def _fly(m: FloatArray, f: FloatArray, course: float, z: float, dt: float, k: int) -> FloatArray:
    """``k`` steps of ``dt`` flying the course and altitude from ``f`` (in place), under
    GUIDED's P-only heading demand (the course error over τ, at most the airframe's bank):
    the positions [k+1,3], ``f``'s first."""
    most = bank_for(m, m[TURN])
    out = np.empty((k + 1, 3))
    out[0] = f[:3]
    for i in range(1, k + 1):
        wanted = wrap(course - f[YAW]) / max(m[TAU], dt)
        step(m, f, max(-most, min(most, bank_for(m, wanted))), z, dt)
        out[i] = f[:3]
    return out


@njit(cache=True)
def hold_steps(hold_s: float) -> int:
    """How many steps a hold of ``hold_s`` is predicted in (``fly_hold``)."""
    return max(1, math.ceil(hold_s / STEP_S))


@njit(cache=True)
def fly_hold(
    m: FloatArray, course: float, z: float, hold_s: float
) -> tuple[FloatArray, FloatArray]:
    """Positions [k+1,3] (from now, every ``STEP_S`` or less) while the vehicle flies the
    course and altitude for ``hold_s`` (``_fly``), and the predicted flight at the end."""
    k = hold_steps(hold_s)
    f = np.empty(FLIGHT_SIZE)
    f[X], f[Y], f[Z], f[YAW] = m[X], m[Y], m[Z], m[YAW]
    f[BANK] = bank_for(m, m[YAW_RATE])
    f[FLIGHT_VZ] = m[VZ]
    f[HEIGHT_DEMAND] = height_demand_now(m)
    return _fly(m, f, course, z, hold_s / k, k), f


@njit(cache=True)
def fly_on(m: FloatArray, end: FloatArray, course: float, z: float, k: int) -> FloatArray:
    """Positions [k+1,3], ``STEP_S`` apart from ``end`` (a hold's end: the instants of an
    escape arc), flying on the same course and altitude."""
    return _fly(m, end.copy(), course, z, STEP_S, k)


@njit(cache=True)
def escape_s(m: FloatArray) -> float:
    """The longest an escape takes: a half turn at the full rate, after rolling from full
    bank one way to full bank the other."""
    roll_over = 2.0 * bank_for(m, m[TURN]) / m[ROLL_RATE] + 3.0 * m[ROLL_LAG]
    return float(math.pi / max(m[TURN], 1e-6) + roll_over)


@njit(cache=True)
def escape_arc(m: FloatArray, end: FloatArray, side: float, z_demand: float) -> FloatArray:
    """The escape flown from ``end`` at full bank to ``side`` (+1 left, −1 right), rolled
    into from the bank it has, until the vehicle has turned 180°, its height loop told
    ``z_demand`` (``climb``; ``end``'s altitude: levelling off from the vertical speed it
    has): positions [k,3], ``STEP_S`` apart.  Once the bank is within ``ROLLED_IN_RAD`` of
    full, a circle."""
    most = bank_for(m, m[TURN])
    steps = math.ceil(escape_s(m) / STEP_S) + 1
    rolled = np.empty((steps + 1, 3))
    f = end.copy()
    rolled[0] = f[:3]
    n = 0
    while n < steps and abs(side * most - f[BANK]) > ROLLED_IN_RAD:
        step(m, f, side * most, z_demand, STEP_S)
        n += 1
        rolled[n] = f[:3]
    left = math.pi - side * (f[YAW] - end[YAW])  # still to turn
    rate = abs(yaw_rate_for(m, f[BANK]))
    if not (left > 0.0 and rate > 1e-9):
        return rolled[: n + 1].copy()
    r = m[SPEED] / rate
    count = math.ceil(left / (rate * STEP_S))
    out = np.empty((n + 1 + count, 3))
    out[: n + 1] = rolled[: n + 1]
    cx = f[X] - side * r * math.sin(f[YAW])
    cy = f[Y] + side * r * math.cos(f[YAW])
    for i in range(count):
        a = f[YAW] - side * math.pi / 2.0 + side * min(rate * STEP_S * (i + 1), left)
        climb(m, f, z_demand, STEP_S)
        out[n + 1 + i, 0] = cx + r * math.cos(a)
        out[n + 1 + i, 1] = cy + r * math.sin(a)
        out[n + 1 + i, 2] = f[Z]
    return out


@njit(cache=True)
def longest_step(path: FloatArray) -> float:
    """The longest step (m) between consecutive instants of ``path`` [k,3]: how far it can
    move from one instant to the next (``margin`` skips instants by it)."""
    most = 0.0
    for i in range(1, path.shape[0]):
        d = math.sqrt(
            (path[i, 0] - path[i - 1, 0]) ** 2
            + (path[i, 1] - path[i - 1, 1]) ** 2
            + (path[i, 2] - path[i - 1, 2]) ** 2
        )
        most = max(most, d)
    return most


SKIP_TOLERANCE_M = 1e-6
"""What ``margin``'s skipping leaves for rounding (m): far more than the error of a
distance of 100 km in float64 (~1e-11 m), so the skipping changes no result."""


@njit(cache=True)
def _nearest_teammate(
    path: FloatArray,
    pool: FloatArray,
    steps: FloatArray,
    which: IntArray,
    start: int,
    last: int,
    beyond_m: float,
) -> float:
    """The least distance (m) from ``path`` to the teammates' flights (``margin``), exact
    where it is less than ``beyond_m``; otherwise some distance of at least ``beyond_m``.

    Instants that cannot come nearer than the nearest so far are skipped: two points that
    move at most ``own`` and ``steps[j]`` (m) an instant close by at most their sum an
    instant (the triangle inequality).  A teammate far off is looked at every few instants
    instead of at every one: the sum is the same, and the result, to the bit."""
    own = longest_step(path)
    n = path.shape[0]
    gap2 = math.inf
    for jj in range(which.shape[0]):  # the first instant first: the nearest so far is near
        j = which[jj]
        gap2 = min(
            gap2,
            (path[0, 0] - pool[j, start, 0]) ** 2
            + (path[0, 1] - pool[j, start, 1]) ** 2
            + (path[0, 2] - pool[j, start, 2]) ** 2,
        )
    for jj in range(which.shape[0]):
        j = which[jj]
        closing = own + steps[j]
        i = 0
        while i < n:
            k = start + min(i, last)
            d2 = (
                (path[i, 0] - pool[j, k, 0]) ** 2
                + (path[i, 1] - pool[j, k, 1]) ** 2
                + (path[i, 2] - pool[j, k, 2]) ** 2
            )
            gap2 = min(gap2, d2)
            i += 1
            if closing > 0.0:
                ahead = math.sqrt(d2) - min(math.sqrt(gap2), beyond_m) - SKIP_TOLERANCE_M
                if ahead > 0.0:
                    i += int(ahead / closing)
    return math.sqrt(gap2)


Around = tuple[
    FloatArray, FloatArray, float, float, FloatArray, FloatArray, IntArray, float,
    IntArray, FloatArray, IntArray, FloatArray,
]  # fmt: skip
"""The keep-outs and the teammates a path is judged against (``margin``, ``judge``): the
spheres' centres and radii, ``safe_obstacle``, ``ground_z``; the teammates' flights
``pool``, their ``steps`` and the rows ``which``, ``safe_uav``; the zones' arrays."""


@njit(cache=True)
def margin(
    path: FloatArray, around: Around, start: int, last: int, cap: float
) -> tuple[float, int]:
    """How far ``path`` [k,3] (``STEP_S`` apart) stays outside every keep-out ``around``
    (m; negative: inside), and which one is nearest (``OBSTACLE``, ``GROUND``, ``TEAMMATE``,
    ``ZONE``).
    A sphere's keep-out is its surface plus ``safe_obstacle``; a zone's (the arrays of
    ``gcs_ppf.planning.zones``: cylinders and polygons, exclusion or inclusion) its surface
    plus the same, on its free side; the ground's (``ground_z``, NaN: none)
    the same above it; a teammate's ``safe_uav`` around where it is at each instant: of the
    flights ``pool`` [P,L,3], those in rows ``which`` [n], ``path``'s instant i at their
    ``start + min(i, last)`` (the last instant held on); ``steps`` [P]: each row's
    ``longest_step``.  Exact below ``cap``; at or above it, some margin at or above it
    (what a caller that needs only to know that is spared).

    The teammates' distance is the square root of the least square distance (the square
    root is monotonic and correctly rounded: the least of the square roots, exactly, one
    root instead of one per instant)."""
    centers, radii, safe_obstacle, ground_z, pool, steps, which, safe_uav = around[:8]
    zone_kind, zone_geom, zone_vstart, zone_verts = around[8:]
    best, reason = math.inf, NO_KEEP_OUT
    if radii.shape[0]:
        gap = math.inf
        for i in range(path.shape[0]):
            for j in range(radii.shape[0]):
                d = (
                    math.sqrt(
                        (path[i, 0] - centers[j, 0]) ** 2
                        + (path[i, 1] - centers[j, 1]) ** 2
                        + (path[i, 2] - centers[j, 2]) ** 2
                    )
                    - radii[j]
                )
                gap = min(gap, d)
        if gap - safe_obstacle < best:
            best, reason = gap - safe_obstacle, OBSTACLE
    if zone_kind.shape[0]:
        gap = math.inf
        for i in range(path.shape[0]):
            d, _ = nearest_zone_clearance(
                path[i, 0], path[i, 1], path[i, 2], zone_kind, zone_geom, zone_vstart, zone_verts
            )
            gap = min(gap, d)
        if gap - safe_obstacle < best:
            best, reason = gap - safe_obstacle, ZONE
    if not math.isnan(ground_z):
        low = path[:, 2].min()
        if low - ground_z - safe_obstacle < best:
            best, reason = low - ground_z - safe_obstacle, GROUND
    if which.shape[0]:
        beyond = min(best, cap) + safe_uav  # nearer than this, a teammate decides
        gap = _nearest_teammate(path, pool, steps, which, start, last, beyond)
        if gap - safe_uav < best:
            best, reason = gap - safe_uav, TEAMMATE
    return best, reason


@njit(cache=True)
def escape_steps(m: FloatArray) -> int:
    """At most how many ``STEP_S`` an escape arc (``escape_arc``) has after its start: its
    roll-in and its circle."""
    return 2 * math.ceil(escape_s(m) / STEP_S) + 2


@njit(cache=True)
def climb_out_z(m: FloatArray, end: FloatArray) -> float:
    """The height a climbing escape asks for from ``end``: as high as the climb limit takes
    it in an escape's time (TECS's demand then rises at that limit throughout)."""
    return float(end[Z] + m[CLIMB] * escape_s(m))


Flights = tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]
"""A command's hold and its escapes: level to the left and to the right, then climbing as
fast as it can to the left and to the right (``flights``)."""


@njit(cache=True)
def flights(m: FloatArray, course: float, z: float, hold_s: float) -> Flights:
    """A command's predicted flights: its hold (``fly_hold``), and from the hold's end the
    escapes (``escape_arc``) to the left and to the right, level and climbing
    (``climb_out_z``), as ``judge`` takes them.  Level escapes alone could not keep a
    formation at the paper's scale: a half turn at 100–300 m/s and 30°/s sweeps 382–1,146 m
    across, and one towards a neighbour 141–150 m away flying on comes within 32–58 m of it
    (the safe distance 50 m, the slack another 50), so a wingman with a neighbour on each
    side had no level escape and was sent an escape instead of its plan, tick after tick."""
    path, end = fly_hold(m, course, z, hold_s)
    up = climb_out_z(m, end)
    return (
        path,
        escape_arc(m, end, 1.0, end[Z]),
        escape_arc(m, end, -1.0, end[Z]),
        escape_arc(m, end, 1.0, up),
        escape_arc(m, end, -1.0, up),
    )


@njit(cache=True)
def judge(
    path: FloatArray,
    left: FloatArray,
    right: FloatArray,
    up_left: FloatArray,
    up_right: FloatArray,
    around: Around,
) -> tuple[float, int]:
    """A command's margin from its ``flights``: along its hold (the teammates along theirs:
    rows ``which`` of ``pool`` [P,L,3], their flights, ``vehicle_motion.Track``, the first
    ``hold_steps`` + 1 instants at the same instants; ``steps`` [P] each row's
    ``longest_step``), then along the best of its escapes, in ``flights``' order (the
    teammates flying on meanwhile, from their hold's end, ``STEP_S`` apart, the last held
    on); with the keep-out it is to.  An escape at least as good as the hold decides nothing
    (the hold's margin is the command's): the escapes after it are then not looked at, and
    an escape only as far as it could fall below the hold's margin (``margin``'s ``cap``)."""
    k = path.shape[0] - 1
    held, reason = margin(path, around, 0, k, math.inf)
    escape, escape_reason = -math.inf, NO_KEEP_OUT
    after = around[4].shape[1] - k - 1  # the pool's instants after the hold
    for arc in (left, right, up_left, up_right):
        e, r = margin(arc, around, k, after, held)
        if e > escape:
            escape, escape_reason = e, r
        if escape >= held:
            break
    if escape < held:
        return escape, escape_reason
    return held, reason


@njit(cache=True)
def judge_each(
    path: FloatArray,
    left: FloatArray,
    right: FloatArray,
    up_left: FloatArray,
    up_right: FloatArray,
    around: Around,
) -> FloatArray:
    """``judge``'s margin with each teammate of ``which`` alone: [n], the flights predicted
    once for all of them."""
    which = around[6]
    out = np.empty(which.shape[0])
    for jj in range(which.shape[0]):
        alone = (*around[:6], which[jj : jj + 1], *around[7:])
        out[jj], _ = judge(path, left, right, up_left, up_right, alone)
    return out


@njit(cache=True)
def judge_in_turn(
    m: FloatArray,
    courses: FloatArray,
    altitudes: FloatArray,
    ends: npt.NDArray[np.bool_],
    hold_s: float,
    slack: float,
    around: Around,
) -> FloatArray:
    """``judge``'s margins [n] of candidate commands (``courses``, ``altitudes``), flown
    (``flights``) and judged in turn until the first that may end the search (``ends``)
    has ``slack`` or more; NaN after it.  One call for an escape's whole search."""
    out = np.full(courses.shape[0], np.nan)
    for c in range(courses.shape[0]):
        path, left, right, up_left, up_right = flights(m, courses[c], altitudes[c], hold_s)
        out[c], _ = judge(path, left, right, up_left, up_right, around)
        if ends[c] and out[c] >= slack:
            break
    return out


@njit(cache=True)
def track_path(m: FloatArray, course: float, z: float, hold_s: float, after: int) -> FloatArray:
    """Positions [k+1+after,3]: the hold (``fly_hold``), then ``after`` more ``STEP_S``
    on the same course and altitude (``fly_on``)."""
    path, end = fly_hold(m, course, z, hold_s)
    on = fly_on(m, end, course, z, after)
    out = np.empty((path.shape[0] + after, 3))
    out[: path.shape[0]] = path
    out[path.shape[0] :] = on[1:]
    return out


@njit(cache=True)
def track_into(
    m: FloatArray,
    course: float,
    z: float,
    hold_s: float,
    pool: FloatArray,
    steps: FloatArray,
    row: int,
) -> None:
    """``track_path`` as long as ``pool``'s rows, written into row ``row``, and its
    ``longest_step`` into ``steps[row]``."""
    path = track_path(m, course, z, hold_s, pool.shape[1] - hold_steps(hold_s) - 1)
    pool[row] = path
    steps[row] = longest_step(path)


@njit(cache=True)
def judge_flown(
    m: FloatArray, course: float, z: float, hold_s: float, around: Around
) -> tuple[float, int, Flights]:
    """``judge`` of a command's ``flights``, flown here: its margin, the keep-out it is to,
    and the flights (kept by the caller for the next time the command is judged)."""
    flown = flights(m, course, z, hold_s)
    s, reason = judge(*flown, around)
    return s, reason, flown

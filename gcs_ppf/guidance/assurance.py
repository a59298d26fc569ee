"""Run-time assurance: a command is sent only if the vehicle, holding it until the next one
can take effect, can still escape every keep-out; otherwise it gets the nearest command that
can (the simplex architecture: the planner is the advanced controller, this the safety one).

Pure: arrays in, verdicts out.  The prediction is ArduPlane's response as the built-in SITL
is calibrated to it (``sitl/calibration.py``, ``gcs_ppf.mavlink.ardupilot``): the turn is what
the bank gives, the bank follows GUIDED's P-only demand (the course error over the heading
time constant, at most the airframe's turn rate) with the roll loop's lag and rate limit,
from the bank the vehicle flies now (a vehicle turning hard one way first rolls out: at
100 m/s, 1.5 s and 150 m the other way, measured on a lossy link under load); the altitude
at TECS's climb and sink limits, the speed held.  A command is *recoverable* when, from
where the vehicle is at the end of ``hold_s`` (the lag of the telemetry, the link and the
next tick), a turn to either side at the full bank through 180° (the way back is the way
it came), rolled into from the bank it then has, keeps out of every keep-out: an
obstacle's surface plus ``safe_distance_obstacle``, the ground plus the same, a teammate
of higher priority (earlier in the order; the leader first) or one it is overtaking, plus
``safe_distance_uav``, with ``SLACK_S`` of flight to spare.
Teammates are predicted on their own (assured) commands, straight on after their hold.
Moving obstacles are taken where they are now (their motion over a few seconds is inside
the planner's margins).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from gcs_ppf.guidance.airframe import G_M_S2
from gcs_ppf.mavlink.ardupilot import TURN_EFFICIENCY
from gcs_ppf.planning.scene import FloatArray, Obstacles

#: Course offsets tried for an escape, nearest the command first (radians).
ESCAPE_OFFSETS = tuple(
    math.radians(d) for d in (30, -30, 60, -60, 90, -90, 120, -120, 150, -150, 180)
)
#: Seconds between predicted samples (the roll loop's lag is ~0.2 s: integrated exactly).
STEP_S = 0.125
#: An escape's bank this near full (rad) is flown on as a circle.
ROLLED_IN_RAD = math.radians(0.5)
#: A replacement that is not safe either must beat the command by this much (m).
BETTER_BY_M = 1.0
ESCAPE_COMMIT_M = 10.0
"""An escape in force is kept unless another does better by this much (m) or has the slack
it lacks: choosing afresh each tick among escapes of nearly equal margin, a wingman flying
at 100 m/s turned left and right by turns every half second, ×10 on a lossy link, and went
71 m into an obstacle."""
SLACK_S = 0.5
"""A command counts as recoverable only with this many seconds of flight (× its speed) to
spare beyond the keep-out: slack for what the prediction does not know (a late tick, a lost
command, a teammate's turn).  Without it the switch to an escape came at zero margin, and
under load on a lossy link the escapes' margins then fell 50–80 m within half a second
(Table 3, ×5, 300 ms, 20 % loss: 5 of 20 runs entered a keep-out)."""


@dataclass(frozen=True, slots=True)
class Command:
    """What a vehicle is told: a course (ICS yaw, rad) and an altitude (ICS z, m)."""

    course_rad: float
    z_m: float


@dataclass(frozen=True, slots=True)
class Motion:
    """How a vehicle answers a command: its state now and its airframe's limits."""

    pos_m: tuple[float, float, float]
    yaw_rad: float
    speed_m_s: float
    turn_rate_rad_s: float
    """Steepest turn (rad/s) at its speed: the bank limit, and the mission's yaw rate."""
    climb_m_s: float
    sink_m_s: float
    heading_tau_s: float = 1.0
    """First-order time constant of the course (ArduPlane's GUIDED P-controller)."""
    yaw_rate_rad_s: float = 0.0
    """How fast it turns now (+: left), i.e. the bank it flies: a turn the other way first
    rolls out of it."""
    roll_lag_s: float = 0.0
    """The bank's first-order lag behind its demand (ArduPlane: ``ROLL_LAG_PER_TCONST`` ×
    RLL2SRV_TCONST); 0: the bank is where it is asked at once."""
    roll_rate_rad_s: float = math.inf
    """The fastest roll (rad/s)."""

    def bank_for(self, yaw_rate_rad_s: float) -> float:
        """The bank (rad, + left) that turns at ``yaw_rate_rad_s``."""
        v = max(self.speed_m_s, 1e-6)
        return math.atan(yaw_rate_rad_s * v / (TURN_EFFICIENCY * G_M_S2))

    def velocity(self, yaw_rad: float | None = None) -> FloatArray:
        """Its level velocity (m/s, ICS) along ``yaw_rad`` (default: its yaw now)."""
        yaw = self.yaw_rad if yaw_rad is None else yaw_rad
        return self.speed_m_s * np.array([math.cos(yaw), math.sin(yaw), 0.0])

    def yaw_rate_for(self, bank_rad: float) -> float:
        """The turn (rad/s, + left) that ``bank_rad`` gives."""
        return TURN_EFFICIENCY * G_M_S2 * math.tan(bank_rad) / max(self.speed_m_s, 1e-6)


@dataclass(frozen=True, slots=True)
class KeepOut:
    """Where no vehicle may go."""

    obstacles: Obstacles
    ground_z_m: float | None
    safe_distance_obstacle: float
    safe_distance_uav: float


@dataclass(frozen=True, slots=True)
class Verdict:
    """One vehicle's command after assurance: ``replaced`` when the planned one was not
    recoverable (``reason``: obstacle, ground or teammate; ``margin_m``: how far the
    planned one would have come inside, negative; ``chosen_margin_m``: the one sent)."""

    command: Command
    replaced: bool
    reason: str | None
    margin_m: float
    chosen_margin_m: float


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@dataclass(slots=True)
class _Flight:
    """Where the predicted vehicle is: position, yaw and bank (+ left)."""

    x: float
    y: float
    z: float
    yaw: float
    bank: float


def _step(m: Motion, f: _Flight, bank_demand: float, z_demand: float, dt: float) -> None:
    """``dt`` seconds of flight: the bank towards its demand (first order, rate limited),
    the turn it gives, the altitude towards ``z_demand`` within the climb and sink limits."""
    gap = bank_demand - f.bank
    if m.roll_lag_s > 0.0:
        gap *= 1.0 - math.exp(-dt / m.roll_lag_s)
    limit = m.roll_rate_rad_s * dt
    bank = f.bank + max(-limit, min(limit, gap))
    rate = 0.5 * (m.yaw_rate_for(f.bank) + m.yaw_rate_for(bank))
    f.bank = bank
    mid = f.yaw + 0.5 * rate * dt
    f.yaw += rate * dt
    f.x += m.speed_m_s * math.cos(mid) * dt
    f.y += m.speed_m_s * math.sin(mid) * dt
    f.z += max(-m.sink_m_s * dt, min(m.climb_m_s * dt, z_demand - f.z))


def _start(m: Motion) -> _Flight:
    x, y, z = m.pos_m
    return _Flight(x, y, z, m.yaw_rad, m.bank_for(m.yaw_rate_rad_s))


def _fly_hold(m: Motion, c: Command, hold_s: float) -> tuple[FloatArray, _Flight]:
    k = max(1, math.ceil(hold_s / STEP_S))
    dt = hold_s / k
    f = _start(m)
    most = m.bank_for(m.turn_rate_rad_s)
    out = np.empty((k + 1, 3))
    out[0] = (f.x, f.y, f.z)
    for i in range(1, k + 1):
        wanted = _wrap(c.course_rad - f.yaw) / max(m.heading_tau_s, dt)  # GUIDED's P demand
        _step(m, f, max(-most, min(most, m.bank_for(wanted))), c.z_m, dt)
        out[i] = (f.x, f.y, f.z)
    return out, f


def hold_path(m: Motion, c: Command, hold_s: float) -> tuple[FloatArray, float]:
    """Positions [k,3] (from now, every ``STEP_S`` or less) while the vehicle flies ``c``
    for ``hold_s``, and its yaw at the end."""
    path, f = _fly_hold(m, c, hold_s)
    return path, f.yaw


def advance(m: Motion, c: Command, dt_s: float) -> Motion:
    """The vehicle ``dt_s`` later, flying ``c`` as predicted (its position, yaw and turn)."""
    path, f = _fly_hold(m, c, dt_s)
    x, y, z = (float(v) for v in path[-1])
    return replace(m, pos_m=(x, y, z), yaw_rad=_wrap(f.yaw), yaw_rate_rad_s=m.yaw_rate_for(f.bank))


def escape_s(m: Motion) -> float:
    """The longest an escape takes: a half turn at the full rate, after rolling from full
    bank one way to full bank the other."""
    roll_over = 2.0 * m.bank_for(m.turn_rate_rad_s) / m.roll_rate_rad_s + 3.0 * m.roll_lag_s
    return math.pi / max(m.turn_rate_rad_s, 1e-6) + roll_over


def escape_arcs(m: Motion, end: _Flight) -> list[tuple[FloatArray, FloatArray]]:
    """The two escapes flown from ``end``: full bank to the left and to the right, rolled
    into from the bank it has, until the vehicle has turned 180°, level.  Each as positions
    [k,3] every ``STEP_S`` and their times [k] from the escape's start.  The roll-in is
    integrated; once the bank is within ``ROLLED_IN_RAD`` of full, the rest is a circle."""
    most = m.bank_for(m.turn_rate_rad_s)
    steps = math.ceil(escape_s(m) / STEP_S) + 1
    arcs = []
    for side in (1.0, -1.0):
        f = _Flight(end.x, end.y, end.z, end.yaw, end.bank)
        out = [(f.x, f.y, f.z)]
        n = 0
        while n < steps and abs(side * most - f.bank) > ROLLED_IN_RAD:
            _step(m, f, side * most, end.z, STEP_S)
            out.append((f.x, f.y, f.z))
            n += 1
        left = math.pi - side * (f.yaw - end.yaw)  # still to turn
        rate = abs(m.yaw_rate_for(f.bank))
        if left > 0.0 and rate > 1e-9:
            r = m.speed_m_s / rate
            turned = rate * STEP_S * np.arange(1, math.ceil(left / (rate * STEP_S)) + 1)
            turned = np.minimum(turned, left)
            cx = f.x - side * r * math.sin(f.yaw)
            cy = f.y + side * r * math.cos(f.yaw)
            a = f.yaw - side * math.pi / 2.0 + side * turned
            circle = np.column_stack([cx + r * np.cos(a), cy + r * np.sin(a),
                                      np.full(turned.shape[0], f.z)])  # fmt: skip
            path = np.vstack([np.array(out), circle])
        else:
            path = np.array(out)
        arcs.append((path, STEP_S * np.arange(path.shape[0], dtype=float)))
    return arcs


@dataclass(frozen=True, slots=True)
class Track:
    """A teammate's predicted flight: its hold path (the same instants as every other's)
    and its velocity at the end, along which it is carried on during an escape."""

    path: FloatArray
    velocity_m_s: FloatArray


def margin(path: FloatArray, keep: KeepOut, others: FloatArray | None) -> tuple[float, str | None]:
    """How far ``path`` [k,3] stays outside every keep-out (m; negative: inside), and which
    keep-out is nearest.  ``others`` [n,k,3] are teammates' positions at the same instants."""
    best, reason = math.inf, None
    obs = keep.obstacles
    if obs.radius.shape[0]:
        gap = np.linalg.norm(path[:, None] - obs.center[None], axis=-1) - obs.radius[None]
        d = float(gap.min()) - keep.safe_distance_obstacle
        if d < best:
            best, reason = d, "obstacle"
    if keep.ground_z_m is not None:
        d = float(path[:, 2].min()) - keep.ground_z_m - keep.safe_distance_obstacle
        if d < best:
            best, reason = d, "ground"
    if others is not None and others.shape[0]:
        d = float(np.linalg.norm(others - path[None], axis=-1).min()) - keep.safe_distance_uav
        if d < best:
            best, reason = d, "teammate"
    return best, reason


def score(
    m: Motion, c: Command, hold_s: float, keep: KeepOut, others: list[Track]
) -> tuple[float, str | None, Track]:
    """A command's margin: along its hold, then along the better of its two escapes (the
    teammates carried straight on meanwhile); with the vehicle's predicted track."""
    path, end = _fly_hold(m, c, hold_s)
    held_others = np.stack([o.path for o in others]) if others else None  # same instants
    held, reason = margin(path, keep, held_others)
    escapes = []
    for arc, t in escape_arcs(m, end):
        ahead = None
        if others:
            ends = np.stack([o.path[-1] for o in others])[:, None, :]
            velocities = np.stack([o.velocity_m_s for o in others])[:, None, :]
            ahead = ends + velocities * t[None, :, None]
        escapes.append(margin(arc, keep, ahead))
    escape, escape_reason = max(escapes, key=lambda e: e[0])
    track = Track(path, m.velocity(end.yaw))
    if escape < held:
        return escape, escape_reason, track
    return held, reason, track


def overtaking(a: Motion, b: Motion) -> bool:
    """Whether ``a`` closes on ``b`` from behind: ``b`` ahead of it, flying the same way
    (within 90°; head on, the one of lower priority turns), and the gap shrinking.
    The overtaking vehicle gives way, whatever their priorities (the rule of the air): a
    wingman of higher priority caught up with one flying ahead of it and came to 44.6 m of it
    on real ArduPlane, where only the one ahead was to yield."""
    gap = np.subtract(b.pos_m, a.pos_m)
    va, vb = a.velocity(), b.velocity()
    return bool(gap @ va > 0.0 and va @ vb > 0.0 and gap @ (va - vb) > 0.0)


def straight_track(m: Motion, hold_s: float) -> Track:
    """A teammate not yet assured this tick, flying straight on at its speed (the positions
    every ``STEP_S`` over ``hold_s``, like a hold path)."""
    k = max(1, math.ceil(hold_s / STEP_S))  # as many instants as ``hold_path``'s
    velocity = m.velocity()
    t = np.linspace(0.0, hold_s, k + 1)[:, None]
    return Track(np.asarray(m.pos_m, dtype=float)[None] + velocity[None] * t, velocity)


def within_reach(a: Motion, b: Motion, hold_s: float, keep: KeepOut) -> bool:
    """Whether two vehicles can come within the safe distance of each other during a hold
    and an escape (both at full speed towards each other): the others are not checked (at
    50 vehicles, checking every pair made a tick's p99 224 ms)."""
    horizon = hold_s + max(escape_s(a), escape_s(b))
    gap = math.dist(a.pos_m, b.pos_m)
    return gap < (a.speed_m_s + b.speed_m_s) * horizon + keep.safe_distance_uav


def escape_altitudes(
    m: Motion, c: Command, reason: str | None, hold_s: float, keep: KeepOut
) -> list[float]:
    """The altitudes an escape may fly at, in order: the command's (raised clear of the
    ground when the ground is the reason), level where the vehicle is (if that is higher),
    and climbing as fast as it can through the hold and an escape.  Measured on a lossy link
    under load: a wingman diving at 47 m/s towards an obstacle's sphere had no level escape
    left at the altitude it was told to descend to, and went 14.5 m into the keep-out."""
    z = c.z_m
    if reason == "ground" and keep.ground_z_m is not None:
        z = max(z, keep.ground_z_m + 2.0 * keep.safe_distance_obstacle, m.pos_m[2])
    out = [z]
    for alt in (m.pos_m[2], m.pos_m[2] + m.climb_m_s * (hold_s + escape_s(m))):
        if alt > z and all(abs(alt - a) > 1.0 for a in out):
            out.append(alt)
    return out


def assure(
    motions: list[Motion], commands: list[Command], hold_s: float, keep: KeepOut,
    escaping: Sequence[Command | None] | None = None,
) -> list[Verdict]:  # fmt: skip
    """Each vehicle's command, in priority order (the leader first): kept if recoverable
    with ``SLACK_S`` to spare, else the nearest course that is (``ESCAPE_OFFSETS`` off the
    command, at one of ``escape_altitudes``), else the best there is if it beats the
    command by ``BETTER_BY_M``.  A vehicle yields to those before it, and to those after it
    that it is ``overtaking``.  ``escaping`` (per vehicle, the escape it was sent last, or
    None) is tried first and kept within ``ESCAPE_COMMIT_M``."""
    verdicts: list[Verdict] = []
    paths: list[Track] = []
    for i, (m, c) in enumerate(zip(motions, commands, strict=True)):
        near = [paths[j] for j in range(i) if within_reach(m, motions[j], hold_s, keep)]
        near += [
            straight_track(o, hold_s) for o in motions[i + 1 :]
            if overtaking(m, o) and within_reach(m, o, hold_s, keep)
        ]  # fmt: skip
        planned, reason, path = score(m, c, hold_s, keep, near)
        chosen, chosen_margin, chosen_path = c, planned, path
        slack = SLACK_S * m.speed_m_s
        if planned < slack:
            best: tuple[float, Command, Track] | None = None
            previous = None if escaping is None else escaping[i]
            candidates = itertools.chain(
                () if previous is None else (previous,),
                (
                    Command(_wrap(c.course_rad + offset), z)
                    for offset in (0.0, *ESCAPE_OFFSETS)
                    for z in escape_altitudes(m, c, reason, hold_s, keep)
                ),
            )
            for candidate in candidates:
                s, _, p = score(m, candidate, hold_s, keep, near)
                if s >= slack:
                    best = (s, candidate, p)
                    break
                kept = 0.0 if best is None or best[1] != previous else ESCAPE_COMMIT_M
                if best is None or s > best[0] + kept:
                    best = (s, candidate, p)
            assert best is not None
            if best[0] >= slack or best[0] > planned + BETTER_BY_M:
                chosen_margin, chosen, chosen_path = best
        replaced = chosen != c
        verdicts.append(Verdict(chosen, replaced, reason if replaced or planned < slack else None,
                                planned, chosen_margin))  # fmt: skip
        paths.append(chosen_path)
    return verdicts

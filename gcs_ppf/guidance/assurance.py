"""Run-time assurance: a command is sent only if the vehicle, holding it until the next one
can take effect, can still escape every keep-out; otherwise it gets the nearest command that
can (the simplex architecture: the planner is the advanced controller, this the safety one).

Pure: arrays in, verdicts out.  The prediction is ArduPlane's response as the built-in SITL
is calibrated to it (``sitl/calibration.py``): the course converges at most at the airframe's
turn rate, first order with its heading time constant, the altitude at TECS's climb and
sink limits, the speed held.  A command is *recoverable* when, from where the vehicle is at
the end of ``hold_s`` (the lag of the telemetry, the link and the next tick), a turn to
either side at the full turn rate through 180° (the way back is the way it came) keeps
out of every keep-out: an obstacle's surface plus ``safe_distance_obstacle``, the ground plus
the same, a teammate of higher priority (earlier in the order; the leader first) plus
``safe_distance_uav``.  Teammates are predicted on their own (assured) commands, straight on
after their hold.  Moving obstacles are taken where they are now (their motion over a few
seconds is inside the planner's margins).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gcs_ppf.planning.scene import FloatArray, Obstacles

#: Course offsets tried for an escape, nearest the command first (radians).
ESCAPE_OFFSETS = tuple(
    math.radians(d) for d in (30, -30, 60, -60, 90, -90, 120, -120, 150, -150, 180)
)
#: Seconds between predicted samples.
STEP_S = 0.25
#: Samples along an escape half-circle.
ARC_SAMPLES = 12
#: A replacement that is not safe either must beat the command by this much (m).
BETTER_BY_M = 1.0


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


def hold_path(m: Motion, c: Command, hold_s: float) -> tuple[FloatArray, float]:
    """Positions [k,3] (from now, every ``STEP_S``) while the vehicle flies ``c`` for
    ``hold_s``, and its yaw at the end."""
    k = max(1, math.ceil(hold_s / STEP_S))
    dt = hold_s / k
    x, y, z = m.pos_m
    yaw = m.yaw_rad
    out = np.empty((k + 1, 3))
    out[0] = (x, y, z)
    for i in range(1, k + 1):
        err = _wrap(c.course_rad - yaw)
        rate = max(-m.turn_rate_rad_s, min(m.turn_rate_rad_s, err / max(m.heading_tau_s, dt)))
        yaw += rate * dt
        x += m.speed_m_s * math.cos(yaw) * dt
        y += m.speed_m_s * math.sin(yaw) * dt
        dz = c.z_m - z
        z += max(-m.sink_m_s * dt, min(m.climb_m_s * dt, dz))
        out[i] = (x, y, z)
    return out, yaw


def escape_arcs(end: FloatArray, yaw: float, m: Motion) -> list[FloatArray]:
    """The two half-circles [ARC_SAMPLES,3] flown from ``end`` heading ``yaw`` at the full
    turn rate, left and right (level)."""
    r = m.speed_m_s / max(m.turn_rate_rad_s, 1e-6)
    phi = np.linspace(0.0, math.pi, ARC_SAMPLES)
    arcs = []
    for side in (1.0, -1.0):
        cx = end[0] - side * r * math.sin(yaw)
        cy = end[1] + side * r * math.cos(yaw)
        a = yaw - side * math.pi / 2.0 + side * phi
        arcs.append(np.column_stack([cx + r * np.cos(a), cy + r * np.sin(a),
                                     np.full(ARC_SAMPLES, end[2])]))  # fmt: skip
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
    path, yaw = hold_path(m, c, hold_s)
    held_others = np.stack([o.path for o in others]) if others else None
    held, reason = margin(path, keep, held_others)
    ahead = None
    if others:
        t = np.linspace(0.0, math.pi / max(m.turn_rate_rad_s, 1e-6), ARC_SAMPLES)[:, None]
        ends = np.stack([o.path[-1] for o in others])[:, None, :]
        velocities = np.stack([o.velocity_m_s for o in others])[:, None, :]
        ahead = ends + velocities * t[None]
    escapes = [margin(arc, keep, ahead) for arc in escape_arcs(path[-1], yaw, m)]
    escape, escape_reason = max(escapes, key=lambda e: e[0])
    velocity = m.speed_m_s * np.array([math.cos(yaw), math.sin(yaw), 0.0])
    track = Track(path, velocity)
    if escape < held:
        return escape, escape_reason, track
    return held, reason, track


def within_reach(a: Motion, b: Motion, hold_s: float, keep: KeepOut) -> bool:
    """Whether two vehicles can come within the safe distance of each other during a hold
    and an escape (both at full speed towards each other): the others are not checked (at
    50 vehicles, checking every pair made a tick's p99 224 ms)."""
    horizon = hold_s + math.pi / max(min(a.turn_rate_rad_s, b.turn_rate_rad_s), 1e-6)
    gap = math.dist(a.pos_m, b.pos_m)
    return gap < (a.speed_m_s + b.speed_m_s) * horizon + keep.safe_distance_uav


def assure(
    motions: list[Motion], commands: list[Command], hold_s: float, keep: KeepOut
) -> list[Verdict]:
    """Each vehicle's command, in priority order (the leader first): kept if recoverable,
    else the nearest recoverable course (``ESCAPE_OFFSETS`` off the command, the altitude
    raised clear of the ground when the ground is the reason), else the best there is if it
    beats the command by ``BETTER_BY_M``.  A vehicle yields to those before it."""
    verdicts: list[Verdict] = []
    paths: list[Track] = []
    for i, (m, c) in enumerate(zip(motions, commands, strict=True)):
        near = [paths[j] for j in range(i) if within_reach(m, motions[j], hold_s, keep)]
        planned, reason, path = score(m, c, hold_s, keep, near)
        chosen, chosen_margin, chosen_path = c, planned, path
        if planned < 0.0:
            z = c.z_m
            if reason == "ground" and keep.ground_z_m is not None:
                z = max(z, keep.ground_z_m + 2.0 * keep.safe_distance_obstacle, m.pos_m[2])
            best: tuple[float, Command, Track] | None = None
            for offset in (0.0, *ESCAPE_OFFSETS):
                candidate = Command(_wrap(c.course_rad + offset), z)
                s, _, p = score(m, candidate, hold_s, keep, near)
                if s >= 0.0:
                    best = (s, candidate, p)
                    break
                if best is None or s > best[0]:
                    best = (s, candidate, p)
            assert best is not None
            if best[0] >= 0.0 or best[0] > planned + BETTER_BY_M:
                chosen_margin, chosen, chosen_path = best
        replaced = chosen != c
        verdicts.append(Verdict(chosen, replaced, reason if replaced or planned < 0 else None,
                                planned, chosen_margin))  # fmt: skip
        paths.append(chosen_path)
    return verdicts

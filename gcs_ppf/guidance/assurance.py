"""Run-time assurance: a command is sent only if the vehicle, holding it until the next one
can take effect, can still escape every keep-out; otherwise it gets the nearest command that
can (the simplex architecture: the planner is the advanced controller, this the safety one).

Pure: arrays in, verdicts out.  The prediction is ArduPlane's response as the built-in SITL
is calibrated to it (``gcs_ppf.guidance.vehicle_motion``).  A command is *recoverable* when,
from where the vehicle is at the end of ``hold_s`` (the lag of the telemetry, the link and
the next tick), a turn to either side at the full bank through 180° (the way back is the
way it came), rolled into from the bank it then has, level or climbing as fast as it can
(``prediction.flights``), keeps out of every keep-out: an
obstacle's surface plus ``safe_distance_obstacle``, a zone's (a cylinder's or a polygon's,
``gcs_ppf.planning.zones``; outside an exclusion zone, inside an inclusion zone) the same,
the ground plus the same, a teammate
of higher priority (earlier in the order; the leader first) or one it is overtaking, plus
``safe_distance_uav``, with ``SLACK_S`` of flight to spare.
Teammates are predicted on their own (assured) commands, through their hold and on
through the escape (not carried on straight and level from their hold's end, as before:
two wingmen came to 48.1 m, ×5 on a lossy link, the lower one diving at up to 124 m/s).
Moving obstacles are taken where they are now (their motion over a few seconds is inside
the planner's margins).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from gcs_ppf.guidance import prediction, reach
from gcs_ppf.guidance.vehicle_motion import (
    Command,
    Motion,
    Track,
    advance,
    escape_s,
    motion_vector,
    straight_track,
    turn_side,
    wrap,
)
from gcs_ppf.planning.scene import FloatArray, IntArray, Obstacles
from gcs_ppf.planning.zones import CYLINDER, Zones, no_zones

#: Course offsets tried for an escape, nearest the command first (radians).
ESCAPE_OFFSETS = tuple(
    math.radians(d) for d in (30, -30, 60, -60, 90, -90, 120, -120, 150, -150, 180)
)
#: A replacement that is not safe either must beat the command by this much (m).
BETTER_BY_M = 1.0
ESCAPE_COMMIT_M = 10.0
"""An escape in force is kept unless another does better by this much (m) or has the slack
it lacks: choosing afresh each tick among escapes of nearly equal margin, a wingman flying
at 100 m/s turned left and right by turns every half second, ×10 on a lossy link, and went
71 m into an obstacle."""
SIDE_SWITCH_S = 1.0
"""An escape turns one way; once it has, an escape the other way is taken only if its
margin is better by this many seconds of flight (× the speed), the slack included.  The
prediction starts each tick from the state the telemetry gave, carried on at the turn it
had: it does not see the bank the commands still in flight have rolled in, so a reversal
costs more than it predicts.  Measured (Table 3, ×5, 300 ms, 20 % loss, a CPU burner per
core): a wingman at 100 m/s was sent escapes to the left and right by turns, 0.3–0.6 s
apart, for 7 s; its heading stayed within 37–44° throughout, and it went 1.4 m into an
obstacle's sphere."""
SLACK_S = 0.5
"""A command counts as recoverable only with this many seconds of flight (× its speed) to
spare beyond the keep-out: slack for what the prediction does not know (a late tick, a lost
command, a teammate's turn).  Without it the switch to an escape came at zero margin, and
under load on a lossy link the escapes' margins then fell 50–80 m within half a second
(Table 3, ×5, 300 ms, 20 % loss: 5 of 20 runs entered a keep-out)."""


@dataclass(frozen=True, slots=True)
class KeepOut:
    """Where no vehicle may go."""

    obstacles: Obstacles
    ground_z_m: float | None
    safe_distance_obstacle: float
    safe_distance_uav: float
    zones: Zones = field(default_factory=no_zones)
    """Cylinders and polygons (exclusion and inclusion): kept out of by their surface plus
    ``safe_distance_obstacle`` on their free side, as spheres are."""
    compiled: tuple[Any, ...] = field(init=False, repr=False, compare=False)
    """All of it as ``prediction.judge`` takes it (contiguous float64 and int64: one
    compiled signature), made once: a tick scores thousands of commands against it."""

    def __post_init__(self) -> None:
        obs = self.obstacles
        ground = math.nan if self.ground_z_m is None else float(self.ground_z_m)
        compiled = (
            _floats(obs.center),
            _floats(obs.radius),
            float(self.safe_distance_obstacle),
            ground,
            float(self.safe_distance_uav),
            *_zone_arrays(self.zones),
        )
        object.__setattr__(self, "compiled", compiled)


@dataclass(frozen=True, slots=True)
class Escape:
    """The escape a vehicle is flying, or flew last (``command`` None once it flies its
    plan again), and the way it turns: +1 left, −1 right (``SIDE_SWITCH_S``)."""

    command: Command | None
    side: int
    ended_s: float | None = None
    """When the vehicle went back to its plan (mission seconds); None while it escapes."""


@dataclass(frozen=True, slots=True)
class Verdict:
    """One vehicle's command after assurance: ``replaced`` when the planned one was not
    recoverable (``reason``: obstacle, zone, ground or teammate; ``margin_m``: how far the
    planned one would have come inside, negative; ``chosen_margin_m``: the one sent)."""

    command: Command
    replaced: bool
    reason: str | None
    margin_m: float
    chosen_margin_m: float
    side: int = 0
    """The way the command sent turns the vehicle, when it was replaced: +1 left, −1 right."""
    gives_way_to: int | None = None
    """The teammate (its index in the list assured) it was sent this to make way for,
    when that teammate had no escape of its own with the slack (``assure``)."""


REASONS = {
    prediction.OBSTACLE: "obstacle",
    prediction.GROUND: "ground",
    prediction.TEAMMATE: "teammate",
    prediction.ZONE: "zone",
}


@dataclass(frozen=True, slots=True)
class _Near:
    """The teammates one vehicle yields to, as ``prediction.judge`` takes them: the rows
    ``which`` [n] of ``pool`` [P,L,3] (flights, ``Track.path``; a tick's are all as long),
    and ``steps`` [P], each row's ``prediction.longest_step`` (``_put``)."""

    pool: FloatArray
    which: IntArray
    steps: FloatArray

    @staticmethod
    def of(tracks: Sequence[Track]) -> _Near:
        if not tracks:
            return _Near(np.zeros((0, 1, 3)), np.zeros(0, dtype=np.int64), np.zeros(0))
        pool = np.ascontiguousarray(np.stack([t.path for t in tracks]), dtype=np.float64)
        steps = np.array([prediction.longest_step(row) for row in pool])
        return _Near(pool, np.arange(len(tracks), dtype=np.int64), steps)


def _put(pool: FloatArray, steps: FloatArray, row: int, own: _Own, c: Command) -> None:
    """The vehicle's flight on ``c`` (``vehicle_motion.track``, as long as the rows) into row
    ``row`` of ``pool``, and its longest step into ``steps``."""
    course, z = float(c.course_rad), float(c.z_m)
    prediction.track_into(own.vector, course, z, own.hold_s, pool, steps, row)


@dataclass(frozen=True, slots=True)
class _Own:
    """A vehicle as commands are scored for it: its motion, packed for the prediction, and
    the flights of each command tried for it (``flights``), predicted once: a tick scores
    the same command against other teammates, in both passes of ``assure`` and for each
    candidate of a teammate in ``_make_way``."""

    motion: Motion
    vector: FloatArray
    hold_s: float
    tried: dict[tuple[float, float], prediction.Flights] = field(default_factory=dict)

    @staticmethod
    def of(m: Motion, hold_s: float) -> _Own:
        return _Own(m, motion_vector(m), float(hold_s))

    def flights(self, c: Command) -> prediction.Flights:
        key = (float(c.course_rad), float(c.z_m))
        found = self.tried.get(key)
        if found is None:
            found = prediction.flights(self.vector, key[0], key[1], self.hold_s)
            self.tried[key] = found
        return found

    def judged(self, c: Command, around: prediction.Around) -> tuple[float, int]:
        """``prediction.judge`` of ``c``'s flights, flown and judged in one call the first
        time (``judge_flown``), kept for the next."""
        key = (float(c.course_rad), float(c.z_m))
        found = self.tried.get(key)
        if found is not None:
            return prediction.judge(*found, around)
        s, reason, flown = prediction.judge_flown(self.vector, key[0], key[1], self.hold_s, around)
        self.tried[key] = flown
        return s, reason


def _around(keep: KeepOut, near: _Near) -> prediction.Around:
    """The keep-outs and the teammates as ``prediction.judge`` takes them (one signature: no
    compiling in flight)."""
    centers, radii, safe_obstacle, ground, safe_uav, zk, zg, zs, zv = keep.compiled
    teammates = (near.pool, near.steps, near.which, safe_uav)
    return (centers, radii, safe_obstacle, ground, *teammates, zk, zg, zs, zv)


def _in_turn(
    own: _Own, candidates: list[Command], ends: list[bool], slack: float, keep: KeepOut, near: _Near
) -> tuple[Any, ...]:
    """``prediction.judge_in_turn``'s arguments: ``_escape``'s candidates and which of them
    may end its search."""
    courses = np.array([float(c.course_rad) for c in candidates], dtype=np.float64)
    altitudes = np.array([float(c.z_m) for c in candidates], dtype=np.float64)
    search = (own.vector, courses, altitudes, np.array(ends, dtype=np.bool_), own.hold_s, slack)
    return (*search, _around(keep, near))


def _score(own: _Own, c: Command, keep: KeepOut, near: _Near) -> tuple[float, str | None]:
    """A command's margin and the keep-out it is to (``_Own.judged``)."""
    s, reason = own.judged(c, _around(keep, near))
    return float(s), REASONS.get(reason)


def _zone_arrays(zones: Zones) -> tuple[IntArray, FloatArray, IntArray, FloatArray]:
    """The zones' arrays as ``prediction.judge`` compiles them (contiguous int64 and
    float64: one signature, no compiling in flight)."""
    kind, geom, vstart, verts = zones.arrays
    return (
        np.ascontiguousarray(kind, dtype=np.int64),
        _floats(geom),
        np.ascontiguousarray(vstart, dtype=np.int64),
        _floats(verts),
    )


def _floats(a: FloatArray) -> FloatArray:
    """``a`` as contiguous float64 (integer radii in a test's spheres made numba compile a
    second version of the prediction, seconds of a tick had it happened in flight)."""
    return np.ascontiguousarray(a, dtype=np.float64)


def score(
    m: Motion, c: Command, hold_s: float, keep: KeepOut, others: list[Track]
) -> tuple[float, str | None]:
    """A command's margin: along its hold, then along the better of its two escapes (the
    teammates flying on meanwhile, ``Track``); with the keep-out it is to."""
    return _score(_Own.of(m, hold_s), c, keep, _Near.of(others))


def overtaking(a: Motion, b: Motion) -> bool:
    """Whether ``a`` closes on ``b`` from behind: ``b`` ahead of it, flying the same way
    (within 90°; head on, the one of lower priority turns), and the gap shrinking.
    The overtaking vehicle gives way, whatever their priorities (the rule of the air): a
    wingman of higher priority caught up with one flying ahead of it and came to 44.6 m of it
    on real ArduPlane, where only the one ahead was to yield."""
    gap = np.subtract(b.pos_m, a.pos_m)
    va, vb = a.velocity(), b.velocity()
    return bool(gap @ va > 0.0 and va @ vb > 0.0 and gap @ (va - vb) > 0.0)


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
    motions: list[Motion],
    commands: list[Command],
    hold_s: float,
    keep: KeepOut,
    escaping: Sequence[Escape | None] | None = None,
) -> list[Verdict]:
    """Each vehicle's command, in priority order (the leader first): kept if recoverable
    with ``SLACK_S`` to spare, else the nearest course that is (``ESCAPE_OFFSETS`` off the
    command, at one of ``escape_altitudes``), else the best there is if it beats the
    command by ``BETTER_BY_M``.  A vehicle yields to those before it, and to those after it
    that it is ``overtaking``.  ``escaping`` (per vehicle, the escape it flies or flew last,
    or None): its command is tried first and kept within ``ESCAPE_COMMIT_M``, and escapes
    that turn the other way must do better by ``SIDE_SWITCH_S`` (or keep out where the
    others do not).

    A vehicle a teammate of higher priority leaves without the slack (``cornered``) makes
    that teammate give way too (``_make_way``), and the rest are assured again after it;
    the second verdicts stand if the worst shortfall under the slack (``shortfall``) is
    smaller.  Measured (Table 3, ×10, a CPU burner per core): two wingmen escaping at once,
    the one of lower priority yielding alone, its escapes 7–9 m clear where the slack was
    50 m, came to 37.1 m of each other (the safe distance 50 m)."""
    owns = [_Own.of(m, hold_s) for m in motions]
    vectors = [o.vector for o in owns]
    after = max((int(prediction.escape_steps(v)) for v in vectors), default=1)
    yields = _yields(motions, vectors, hold_s, keep)
    first = _in_order(owns, commands, keep, escaping, after, yields, {})
    forced: dict[int, tuple[int, Command]] = {}
    for i in cornered(motions, first.verdicts):
        way = _make_way(owns, commands, keep, after, first, i)
        if way is not None and way[0] not in forced:
            forced[way[0]] = (i, way[1])
    if not forced:
        return first.verdicts
    second = _in_order(owns, commands, keep, escaping, after, yields, forced, first)
    if shortfall(motions, second.verdicts) < shortfall(motions, first.verdicts):
        return second.verdicts
    return first.verdicts


def cornered(motions: Sequence[Motion], verdicts: Sequence[Verdict]) -> list[int]:
    """The vehicles a teammate leaves without the slack, whatever they are sent."""
    return [
        i
        for i, (m, v) in enumerate(zip(motions, verdicts, strict=True))
        if v.reason == "teammate" and v.chosen_margin_m < SLACK_S * m.speed_m_s
    ]


def shortfall(motions: Sequence[Motion], verdicts: Sequence[Verdict]) -> float:
    """How far (m) the worst-off vehicle's command falls short of the slack; 0: none."""
    short = (
        SLACK_S * m.speed_m_s - v.chosen_margin_m for m, v in zip(motions, verdicts, strict=True)
    )
    return max(0.0, *short)


@dataclass(frozen=True, slots=True)
class _Pass:
    """One pass of ``assure`` in priority order: each vehicle's verdict, the teammates it
    yielded to (by index, on the flights it took them to fly: the row of ``pool`` each
    one's is in), and the flights (``pool``: each vehicle's as it was given it)."""

    verdicts: list[Verdict]
    yielded: list[dict[int, int]]
    pool: FloatArray
    """[2N+1,L,3]: row j vehicle j's flight as assured, row N + j the one the vehicles
    before it took it to fly (its command held straight, or what ``_make_way`` found for
    it), row 2N free (``_make_way``'s candidates)."""
    steps: FloatArray
    """[2N+1]: each row's longest step (``_put``; inf: not written)."""


def _yields(
    motions: list[Motion], vectors: list[FloatArray], hold_s: float, keep: KeepOut
) -> list[list[int]]:
    """Whom each vehicle yields to: those before it within reach, and those after it it is
    ``overtaking`` (``within_reach`` either way), in ascending order; found for the fleet at
    once (``reach.yields``), a pair too near a threshold to tell there asked here."""
    n = len(motions)
    if n == 0:
        return []
    pos = np.array([m.pos_m for m in motions], dtype=np.float64).reshape(n, 3)
    vel = np.array([m.velocity() for m in motions], dtype=np.float64).reshape(n, 3)
    speed = np.array([m.speed_m_s for m in motions], dtype=np.float64)
    escape = np.array([prediction.escape_s(v) for v in vectors], dtype=np.float64)
    start, items, status = reach.yields(
        pos, vel, speed, escape, float(hold_s), float(keep.safe_distance_uav)
    )
    out: list[list[int]] = []
    for i, m in enumerate(motions):
        lo, hi = int(start[i]), int(start[i + 1])
        out.append(
            [
                j
                for j, st in zip(items[lo:hi].tolist(), status[lo:hi].tolist(), strict=True)
                if st == reach.YIELDS
                or (
                    (j < i or overtaking(m, motions[j]))
                    and within_reach(m, motions[j], hold_s, keep)
                )
            ]
        )
    return out


def _in_order(
    owns: list[_Own],
    commands: list[Command],
    keep: KeepOut,
    escaping: Sequence[Escape | None] | None,
    after: int,
    yields: list[list[int]],
    forced: dict[int, tuple[int, Command]],
    earlier: _Pass | None = None,
) -> _Pass:
    """``assure``'s pass in priority order; ``yields``: whom each vehicle yields to
    (``_yields``); ``forced``: the vehicles sent what ``_make_way`` found for them (for
    whom, and what), whatever their own search would choose.  Each teammate's flight is
    predicted once (``_Pass.pool``), not once for every vehicle that yields to it.
    ``earlier``: the pass before, with nothing forced; a vehicle not forced, whose
    teammates fly as they flew in it, is judged as it was there (the same inputs)."""
    n = len(owns)
    hold_s = owns[0].hold_s if owns else 0.0
    verdicts: list[Verdict] = []
    yielded: list[dict[int, int]] = []
    length = int(prediction.hold_steps(float(hold_s))) + 1 + after
    pool = np.empty((2 * n + 1, length, 3))
    steps = np.full(2 * n + 1, np.inf)
    for j in sorted({j for i, js in enumerate(yields) for j in js if j > i}):
        if earlier is not None and j not in forced:
            pool[n + j], steps[n + j] = earlier.pool[n + j], earlier.steps[n + j]
            continue
        mj = owns[j].motion
        taken = forced[j][1] if j in forced else Command(mj.yaw_rad, mj.pos_m[2])  # held on
        _put(pool, steps, n + j, owns[j], taken)
    changed: set[int] = set()  # flying otherwise than in ``earlier``
    for i, (own, c) in enumerate(zip(owns, commands, strict=True)):
        m = own.motion
        to = {j: j if j < i else n + j for j in yields[i]}
        if (
            earlier is not None
            and i not in forced
            and not any(j in changed if j < i else j in forced for j in yields[i])
        ):
            verdicts.append(earlier.verdicts[i])
            pool[i], steps[i] = earlier.pool[i], earlier.steps[i]
            yielded.append(to)
            continue
        prepared = _Near(pool, np.array(list(to.values()), dtype=np.int64), steps)
        planned, reason = _score(own, c, keep, prepared)
        chosen, chosen_margin = c, planned
        slack = SLACK_S * m.speed_m_s
        previous = None if escaping is None else escaping[i]
        if i in forced:
            chosen = forced[i][1]
            chosen_margin, _ = _score(own, chosen, keep, prepared)
            reason = "teammate"
        elif planned < slack:
            best = _escape(own, c, reason, keep, prepared, previous)
            if best[0] >= slack or best[0] > planned + BETTER_BY_M:
                chosen_margin, chosen = best
        replaced = chosen != c
        side = 0
        if replaced:
            side = turn_side(m, chosen.course_rad)
            if side == 0 and previous is not None:
                side = previous.side
        verdicts.append(
            Verdict(
                chosen,
                replaced,
                reason if replaced or planned < slack else None,
                planned,
                chosen_margin,
                side,
                forced[i][0] if i in forced else None,
            )
        )
        if earlier is not None and chosen != earlier.verdicts[i].command:
            changed.add(i)
        _put(pool, steps, i, own, chosen)
        yielded.append(to)
    return _Pass(verdicts, yielded, pool, steps)


def _make_way(
    owns: list[_Own], commands: list[Command], keep: KeepOut, after: int, first: _Pass, i: int
) -> tuple[int, Command] | None:
    """What the teammate that corners vehicle ``i`` (of those it yields to, the one whose
    flight leaves it the least margin) is sent instead, so that both keep the slack: the
    first of its candidates (its command, then ``ESCAPE_OFFSETS`` off it at its
    ``escape_altitudes``) after which ``i`` has an escape with the slack and it has the
    slack itself (from those it yields to, and from ``i`` on the flight ``i`` was given);
    else the one whose worse shortfall of the two is the smallest, if smaller than now.
    None: no one teammate corners it, or no candidate does better."""
    m, v, hold_s = owns[i].motion, first.verdicts[i], owns[i].hold_s
    pool, steps = first.pool, first.steps
    rows = np.array(list(first.yielded[i].values()), dtype=np.int64)
    if not rows.shape[0]:
        return None
    # its margin with each teammate alone
    each = prediction.judge_each(
        *owns[i].flights(v.command), _around(keep, _Near(pool, rows, steps))
    )
    alone = dict(zip(first.yielded[i], each.tolist(), strict=True))
    j = min(alone, key=alone.__getitem__)
    slack_i, slack_j = SLACK_S * m.speed_m_s, SLACK_S * owns[j].motion.speed_m_s
    if alone[j] >= slack_i:
        return None
    mj, cj = owns[j].motion, commands[j]
    # j's teammates but i, and i on the flight it was given (row i)
    theirs = _Near(
        pool,
        np.array([row for k, row in first.yielded[j].items() if k != i] + [i], dtype=np.int64),
        steps,
    )
    scratch = pool.shape[0] - 1
    with_candidate = np.array(
        [row for k, row in first.yielded[i].items() if k != j] + [scratch], dtype=np.int64
    )
    now = max(slack_i - v.chosen_margin_m, slack_j - first.verdicts[j].chosen_margin_m)
    best: tuple[float, Command] | None = None
    altitudes = escape_altitudes(mj, cj, "teammate", hold_s, keep)
    candidates = (
        Command(wrap(cj.course_rad + offset), z)
        for offset in (0.0, *ESCAPE_OFFSETS)
        for z in altitudes
    )
    for candidate in candidates:
        own, _ = _score(owns[j], candidate, keep, theirs)
        if own < slack_j and best is not None and slack_j - own >= best[0]:
            continue  # cannot beat the best so far: skip the escape search
        _put(pool, steps, scratch, owns[j], candidate)
        near = _Near(pool, with_candidate, steps)
        escape, _ = _escape(owns[i], commands[i], v.reason, keep, near, None)
        worse = max(slack_i - escape, slack_j - own)
        if worse <= 0.0:
            return j, candidate
        if best is None or worse < best[0]:
            best = (worse, candidate)
    if best is None or best[0] >= now:
        return None
    return j, best[1]


def _escape(
    own: _Own,
    c: Command,
    reason: str | None,
    keep: KeepOut,
    near: _Near,
    previous: Escape | None,
) -> tuple[float, Command]:
    """The escape for a command that is not recoverable with the slack: the first candidate
    that is, turning the way ``previous`` turned (any way if none); else the best, the
    escape in force kept within ``ESCAPE_COMMIT_M``; one turning the other way only if it
    beats that by ``SIDE_SWITCH_S`` of flight, or keeps out where that does not."""
    m, hold_s = own.motion, own.hold_s
    slack = SLACK_S * m.speed_m_s
    kept_command = None if previous is None else previous.command
    side = 0 if previous is None else previous.side
    altitudes = escape_altitudes(m, c, reason, hold_s, keep)
    candidates = [
        *(() if kept_command is None else (kept_command,)),
        *(
            Command(wrap(c.course_rad + offset), z)
            for offset in (0.0, *ESCAPE_OFFSETS)
            for z in altitudes
        ),
    ]
    # one that turns the other way does not end the search
    ends = [
        not (side and candidate != kept_command and turn_side(m, candidate.course_rad) == -side)
        for candidate in candidates
    ]
    scores = prediction.judge_in_turn(*_in_turn(own, candidates, ends, slack, keep, near))
    best: tuple[float, Command] | None = None
    other: tuple[float, Command] | None = None  # the best turning the other way
    for candidate, s, may_end in zip(candidates, scores.tolist(), ends, strict=True):
        if not may_end:
            if other is None or s > other[0]:
                other = (s, candidate)
            continue
        if s >= slack:
            best = (s, candidate)
            break
        kept = 0.0 if best is None or best[1] != kept_command else ESCAPE_COMMIT_M
        if best is None or s > best[0] + kept:
            best = (s, candidate)
    if other is not None and (
        best is None
        or other[0] > best[0] + SIDE_SWITCH_S * m.speed_m_s
        or best[0] < 0.0 <= other[0]
    ):
        return other
    assert best is not None
    return best


_WARM_UP_ZONES = Zones(
    np.array([CYLINDER], dtype=np.int64),  # unbounded in height
    np.array([[500.0, -800.0, 300.0, -math.inf, math.inf]]),
    np.array([0, 0], dtype=np.int64),
    np.zeros((0, 2)),
    np.array([0, 0], dtype=np.int64),
    np.zeros((0, 2)),
)


def warm_up() -> None:
    """Load the compiled prediction (numba's cache, or compile it) before any run, so that
    no tick pays for it."""
    m = Motion((0.0, 0.0, 100.0), 0.0, 25.0, 0.3, 5.0, 5.0)
    sphere = Obstacles(np.array([[500.0, 0.0, 100.0]]), np.array([100.0]), np.zeros((1, 3)))
    keep = KeepOut(sphere, 0.0, 25.0, 50.0)
    assure([m], [Command(0.0, 100.0)], 1.0, replace(keep, zones=_WARM_UP_ZONES))
    beside = replace(m, pos_m=(0.0, 300.0, 100.0))
    assure([m, beside], [Command(0.0, 100.0)] * 2, 1.0, keep)
    near = _Near.of([straight_track(beside, 1.0, int(prediction.escape_steps(motion_vector(m))))])
    own, ahead = _Own.of(m, 1.0), Command(0.0, 100.0)
    prediction.judge_each(*own.flights(ahead), _around(keep, near))
    prediction.judge_in_turn(*_in_turn(own, [ahead], [True], 1.0, keep, near))
    _score(own, ahead, keep, near)  # flown and judged (judge_flown), then judged again
    _score(own, ahead, keep, near)
    _put(near.pool, near.steps, 0, own, ahead)  # track_into
    advance(m, Command(0.0, 100.0), 1.0)
    escape_s(m)
    prediction.height_demand_now(motion_vector(m))  # the holds' stack

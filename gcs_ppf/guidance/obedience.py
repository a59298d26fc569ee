"""Whether each vehicle obeys the service during a run: in GUIDED, its commands acknowledged
ACCEPTED, its course converging on the course it was sent — and, when not for longer than a
bound of its own time, ``vehicle_not_responding``.

Pure bookkeeping, fed once per tick with what the vehicles report (HEARTBEAT mode, the last
COMMAND_ACK of the course command). Flown with a lossy link (issue 10), a leader stayed in
MANUAL while the service sent it 2,851 commands, 1,800 answered FAILED, and nothing noticed:
now a vehicle that has not obeyed for ``bound_s`` of vehicle time is flagged, the others
treat it as an uncontrolled moving obstacle, and it is cleared once it obeys again.  An
autopilot stuck on its last command stays in GUIDED and ACKs everything ACCEPTED (the SITL's
``ignore`` fault; unflagged, it was flown around by no one while two teammates entered
obstacles): so a vehicle must also fly the course it is sent, or be turning towards it —
any course it was sent within the lag (``courses_in_effect``): what it reports now answers
commands sent a lag ago.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from gcs_ppf.guidance.online import VehicleState
from gcs_ppf.mavlink.enums import MAV_RESULT_ACCEPTED, MAV_RESULT_IN_PROGRESS
from gcs_ppf.planning.scene import Obstacles

OBEYED = (MAV_RESULT_ACCEPTED, MAV_RESULT_IN_PROGRESS)
COURSE_TOLERANCE_RAD = math.radians(5.0)
"""A course within this of the one sent is flown.  (20° once: the course sent is slewed at
most ~17° ahead of the course flown, so a wingman stuck flying straight was 17.4° off for
80 s and never flagged, campaign (d).)"""
TURNING_RAD_S = 0.02
"""A vehicle turning towards the course sent at least this fast is converging."""
TURN_FRACTION = 0.3
"""... or at least this fraction of the turn an obeying one makes (``expected_turn_rad_s``)."""


RESPONSE_S = 1.0
"""Beyond the lag, how long a course sent may still be what a vehicle is seen answering."""
SILENT_S = 1.0
"""A vehicle without a new position for longer than this (its own seconds) reports nothing
to judge it by (``Obedience.unheard``); at 10 Hz, 20 % loss leaves such a gap once in 10⁷."""


def courses_in_effect(
    sent: Sequence[tuple[float, float]], now_s: float, lag_s: float
) -> list[float]:
    """Of the courses sent (mission time, course), those a vehicle's report now may answer:
    sent within ``lag_s`` + ``RESPONSE_S`` of ``now_s``, and the latest in any case.
    Measured (Table 3, ×5, 300 ms, 20 % loss, ~1 s of lag): judged against the latest
    course only, obeying wingmen were flagged ``vehicle_not_responding`` in 4 of 30 runs
    while their escapes changed course every half second."""
    out = [c for t, c in sent if now_s - t <= lag_s + RESPONSE_S]
    return out if out or not sent else [sent[-1][1]]


@dataclass(frozen=True, slots=True)
class Report:
    """What one vehicle shows at a tick: whether it is in GUIDED, and the result of the last
    COMMAND_ACK of the command the service flies it by (None: none yet)."""

    vehicle_id: int
    guided: bool
    last_ack_result: int | None
    course_error_rad: float | None = None
    """The course sent minus the course flown (ICS, wrapped; None: no course sent yet)."""
    turn_rate_rad_s: float = 0.0
    """How fast it turns (ICS, +: left)."""
    expected_turn_rad_s: float | None = None
    """How fast an obeying vehicle turns towards the course sent (the error over its heading
    time constant, within its turn rate); None: unknown, ``TURNING_RAD_S`` is asked."""

    @property
    def converging(self) -> bool:
        """Flying the course sent, or turning towards it: at ``TURNING_RAD_S``, or at
        ``TURN_FRACTION`` of the turn expected if that is slower (a fast vehicle a few
        degrees off turns slowly)."""
        e = self.course_error_rad
        if e is None or abs(e) <= COURSE_TOLERANCE_RAD:
            return True
        needed = TURNING_RAD_S
        if self.expected_turn_rad_s is not None:
            needed = min(needed, TURN_FRACTION * self.expected_turn_rad_s)
        return e * self.turn_rate_rad_s > 0.0 and abs(self.turn_rate_rad_s) >= needed


@dataclass
class Obedience:
    """Per vehicle, since when (vehicle seconds) it has not obeyed, and which are flagged."""

    bound_s: float
    since_s: dict[int, float] = field(default_factory=dict)
    not_responding: set[int] = field(default_factory=set)

    @staticmethod
    def obeys(report: Report) -> bool:
        ack = report.last_ack_result
        return report.guided and (ack is None or ack in OBEYED) and report.converging

    def restart(self) -> None:
        """Forget since when vehicles have not obeyed (those flagged stay flagged): after
        a gap in the ground station's own ticks longer than the bound, what a vehicle did
        meanwhile is no evidence against it (×10 under load, ticks 3.7 s of vehicle time
        apart flagged an obeying leader and failed the run)."""
        self.since_s.clear()

    def unheard(self, vehicle_id: int) -> None:
        """No report of the vehicle this tick (``SILENT_S`` without a position): its silence
        is no evidence against it.  Counted on, the last course it reported before a link
        cut was judged against the courses sent into the cut, which it never received: a
        wingman was flagged 3 s into an 8 s cut, never commanded again after it was heard
        once more, and flew its last course into an obstacle's keep-out."""
        self.since_s.pop(vehicle_id, None)

    def forget(self, vehicle_id: int) -> None:
        """A vehicle heard again after it was lost is judged afresh: commanded again, and
        flagged again only if it does not obey for the bound.  Once flagged it is no longer
        commanded, so it could be cleared only by flying, by chance, the last course sent
        before the loss."""
        self.since_s.pop(vehicle_id, None)
        self.not_responding.discard(vehicle_id)

    def update(self, now_s: float, reports: list[Report]) -> tuple[list[int], list[int]]:
        """One tick at vehicle time ``now_s``: the vehicles newly flagged, and those that
        obey again.  A vehicle with several reports obeys if one of them does."""
        flagged: list[int] = []
        cleared: list[int] = []
        obeying: dict[int, bool] = {}
        for r in reports:  # several of one vehicle (one per course in effect): any will do
            obeying[r.vehicle_id] = obeying.get(r.vehicle_id, False) or self.obeys(r)
        for vid, obeys in obeying.items():
            if obeys:
                self.since_s.pop(vid, None)
                if vid in self.not_responding:
                    self.not_responding.discard(vid)
                    cleared.append(vid)
                continue
            since = self.since_s.setdefault(vid, now_s)
            if now_s - since >= self.bound_s and vid not in self.not_responding:
                self.not_responding.add(vid)
                flagged.append(vid)
        return flagged, cleared


def as_obstacles(
    states: dict[int, VehicleState], vehicle_ids: set[int], radius_m: float
) -> Obstacles:
    """Vehicles that do not obey as moving spheres (where they are, flying as they fly), so
    that the others avoid them as uncontrolled traffic; ``radius_m`` makes the obstacle's
    keep-out (radius + safe_distance_obstacle) the teammates' safe distance."""
    rows = [(states[i], i) for i in sorted(vehicle_ids) if i in states]
    m = len(rows)
    center = np.array([s.pos_m for s, _ in rows], dtype=float).reshape(m, 3)
    velocity = np.array(
        [
            (
                s.speed_m_s * math.cos(s.pitch_rad) * math.cos(s.yaw_rad),
                s.speed_m_s * math.cos(s.pitch_rad) * math.sin(s.yaw_rad),
                s.speed_m_s * math.sin(s.pitch_rad),
            )
            for s, _ in rows
        ],
        dtype=float,
    ).reshape(m, 3)
    return Obstacles(center, np.full(m, radius_m), velocity)


def with_obstacles(a: Obstacles, b: Obstacles) -> Obstacles:
    """Both sets of spheres."""
    return Obstacles(
        np.concatenate([a.center, b.center]),
        np.concatenate([a.radius, b.radius]),
        np.concatenate([a.velocity, b.velocity]),
    )

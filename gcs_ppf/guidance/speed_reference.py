"""The speed and course each tick plans from: where the previous plan's had got to by now
(the commanded reference), not the ones measured, as long as the two stay close.

Pure.  The plan is re-made every tick; its speed law (Eq. 21–24) changes the speed at the
mission's ``accel``/``decel`` from the speed the plan starts at, and the service commands
the planned speed 1 s on (``gcs_ppf.guidance.online.guidance``).  Started from the measured
speed, each tick's command is the measured speed plus a second of acceleration, and the
aircraft, which tracks an airspeed demand with TECS's own lag and authority, is asked for
more each time it gets faster: on real ArduPlane (formation takeoff of 5, ×5) the leader's
commanded airspeed rose 23.0 → 26.6 m/s in 1.5 s (2.4 m/s², four times the mission's
0.6), the airspeed followed at ~1.9 m/s², and TECS traded height for it: the leader's
vertical speed swung ±2–4 m/s over 6–8 s cycles, and slots 200 m behind, which turn with
its flight-path pitch (Eq. 6), moved ±15–20 m up and down, so no wingman stayed within
10 m of its slot for more than 1.4–2.5 s.  Planned from the reference, the speed changes at
the mission's rates whatever the aircraft's lag; the measured speed still bounds the
reference (``REFERENCE_BOUND_M_S``), so a vehicle that cannot fly the reference is planned
from what it flies.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from gcs_ppf.guidance.online import Guidance, VehicleState
from gcs_ppf.planning.ppf.primitives import FOLLOWED_ACCEL_M_S2
from gcs_ppf.planning.scene import FloatArray

REFERENCE_BOUND_M_S = 2.0
"""The reference is kept within this of the measured speed (m/s): what ArduPlane lags an
airspeed ramp at the mission's rates by, with room (measured: 0.5–1.2 m/s behind a demand
ramping at 0.6–0.8 m/s², and ground speed 1–2 m/s above airspeed)."""


REFERENCE_COURSE_BOUND_RAD = math.radians(2.0)
"""The leader's course planned from is kept within this of the course it flies (rad): what
it lags the heading sent by while its course turns slowly (the loiter route's first leg,
turning at 0.005–0.007 rad/s: 1–2°).  In a turn at the formation's held rate it lags by
more, and the plan's leader is that much further round: its wingmen's aims, carried 1/ω
ahead along its direction, swing in by v/ω × the offset.  With 5°, the loiter route's
outer wingman was 24 m inside its slot at the turn onto the circle (13–16 m with 2°, 8–10
m from the course flown); round the circle, 3.4–5.9 m (1.6–2.6 m with 2°, 7.7–8.5 m)."""


SPEED_COMMAND_LEAD_S = 0.25
"""The leader's airspeed commanded is its plan's this far on: ArduPlane's TECS answers a
speed demand within ~0.25 s (measured: a 0.6 m/s step flown at ~2.4 m/s²).  With the plan
started from the reference a longer lead buys the leader nothing, and each turn of its
wait law (Eq. 24, waiting at 0.8 m/s² of deceleration or leading on at 0.6 m/s² of
acceleration, which flips as a wingman crosses the target accuracy) jumped the command by
1.4 m/s per second of lead: with 1 s, on real ArduPlane, the leader's command flipped
between 25.8 and 27.4 m/s every second or two, its throttle between 34 and 100 %, its vertical speed
between −3 and +4 m/s."""
WINGMAN_SPEED_COMMAND_LEAD_S = 1.25
"""A wingman's airspeed commanded is its plan's this far on (the leader's,
``SPEED_COMMAND_LEAD_S``): ArduPlane's airspeed follows a demand ramped at the mission's
0.8 m/s² 1.1–1.3 m/s behind (about 1.4 s; the built-in SITL's loiter route at ×10), so a
wingman commanded its plan's speed a quarter second on flew its speed corrections late,
and through its slot: 15.9 m/s where its plan, started from the reference, had it at 18
and its leader flew 22.  A wingman's plan changes speed only as its place asks, not as
the leader's wait law flips."""
SPEED_DEADBAND_M_S = 0.2
"""An airspeed is sent again when it has changed by this much (m/s): each send is a step
TECS answers with a throttle pulse (0.5 m/s steps every ~0.8 s on a 0.6 m/s² ramp)."""


def speed_to_command(g: Guidance, i: int, lead_s: float = SPEED_COMMAND_LEAD_S) -> float:
    """Vehicle ``i``'s planned speed ``lead_s`` on (``g``'s speed plan; without one, the
    speed it plans 1 s on, or ``lead_s`` = 0.5 s on)."""
    if g.speed_plan_t_s is not None and g.speed_plan_m_s is not None:
        return float(np.interp(lead_s, g.speed_plan_t_s, g.speed_plan_m_s[:, i]))
    ahead = g.speed_m_s if g.speed_ahead_m_s is None else g.speed_ahead_m_s
    return float(ahead[i])


LEGACY_COMMAND_LEAD_S = 1.0
LEGACY_DEADBAND_M_S = 0.5


def follows_speed_plan(accel_m_s2: float, decel_m_s2: float) -> bool:
    """Whether the vehicles fly the plan's speed changes (``FOLLOWED_ACCEL_M_S2``), so that
    a tick plans from the reference and the leader of a held formation keeps its speed.

    At the paper's 10 m/s² of acceleration and 40 m/s² of deceleration no airframe flies
    the plan's speed: kept within 2 m/s of a vehicle that lags by more, the plan started 2
    m/s off the flown speed on the side of the change and the command asked a fraction of
    what planning from the measured speed asked; Table 2's level formation on the built-in
    SITL did not form (the worst wingman 513–2158 m off at best in five runs, 3.7 m
    before).  There each tick plans from the measured speed and commands the speed 1 s on
    (``LEGACY_COMMAND_LEAD_S``, ``LEGACY_DEADBAND_M_S``), as before."""
    return max(accel_m_s2, decel_m_s2) <= FOLLOWED_ACCEL_M_S2


@dataclass(frozen=True)
class SpeedPlan:
    """The speeds one tick planned: ``speed_m_s`` [K,N] at ``t_s`` [K] seconds after the
    plan's start (``t_s[0]`` = 0, the speeds it started from), for the vehicles ``ids``
    [N] in the plan's order, the plan made at mission time ``planned_at_s``; and the
    courses (ICS yaw) planned then, ``course_rad`` [K,N] (None: not planned)."""

    ids: tuple[int, ...]
    t_s: FloatArray
    speed_m_s: FloatArray
    planned_at_s: float
    course_rad: FloatArray | None = None

    @staticmethod
    def of(g: Guidance, planned_at_s: float) -> SpeedPlan | None:
        """The speed plan of ``g`` (None if it carries none), with its courses."""
        if g.speed_plan_t_s is None or g.speed_plan_m_s is None:
            return None
        ids = tuple(g.ids)
        return SpeedPlan(ids, g.speed_plan_t_s, g.speed_plan_m_s, planned_at_s, g.course_plan_rad)

    def _column(self, plan: FloatArray, vehicle_id: int, mission_time_s: float) -> float | None:
        """``plan``'s column of ``vehicle_id`` at ``mission_time_s`` (None: the vehicle is
        not in it, or the moment is before its start or past its end)."""
        if vehicle_id not in self.ids:
            return None
        elapsed = mission_time_s - self.planned_at_s
        if elapsed < 0.0 or elapsed > float(self.t_s[-1]):
            return None
        return float(np.interp(elapsed, self.t_s, plan[:, self.ids.index(vehicle_id)]))

    def speed_at(self, vehicle_id: int, mission_time_s: float) -> float | None:
        """The speed the plan had reached at ``mission_time_s`` (None: the vehicle is not in
        it, or the moment is before its start or past its end)."""
        return self._column(self.speed_m_s, vehicle_id, mission_time_s)

    def course_at(self, vehicle_id: int, mission_time_s: float) -> float | None:
        """The course the plan had reached at ``mission_time_s`` (None as ``speed_at``, or
        no courses planned)."""
        if self.course_rad is None:
            return None
        return self._column(np.unwrap(self.course_rad, axis=0), vehicle_id, mission_time_s)


def reference_speed(
    planned_m_s: float | None, measured_m_s: float, bound_m_s: float = REFERENCE_BOUND_M_S
) -> float:
    """The speed to plan from: the previous plan's speed now (``planned_m_s``) kept within
    ``bound_m_s`` of the measured speed; the measured speed without a plan."""
    if planned_m_s is None:
        return measured_m_s
    return min(max(planned_m_s, measured_m_s - bound_m_s), measured_m_s + bound_m_s)


def reference_course(
    planned_rad: float | None, measured_rad: float, bound_rad: float = REFERENCE_COURSE_BOUND_RAD
) -> float:
    """The course to plan from: the previous plan's course now (``planned_rad``) kept within
    ``bound_rad`` of the measured course, in (−π, π]; the measured course without a plan.

    Planned from the course measured, each tick's plan opened with a turn at the formation's
    held rate to put right the degree or two the autopilot lags a turning heading by, and
    the wingmen planned their speeds to that turn (their slots swing with it: ±3.3 m/s for
    slots 100 m out at 0.033 rad/s) for the 0.3 s it lasted: the airspeed commanded a quarter
    second into the plan never changed (the loiter route flown: a wingman 11–12 m ahead of
    its slot asked for more than the leader for 28 s)."""
    if planned_rad is None:
        return measured_rad
    off = math.remainder(planned_rad - measured_rad, math.tau)
    return math.remainder(measured_rad + min(max(off, -bound_rad), bound_rad), math.tau)


def reference_states(
    states: dict[int, VehicleState],
    plan: SpeedPlan | None,
    mission_time_s: float,
    bound_m_s: float = REFERENCE_BOUND_M_S,
    leader_id: int | None = None,
    course_bound_rad: float = REFERENCE_COURSE_BOUND_RAD,
) -> dict[int, VehicleState]:
    """``states`` with each speed replaced by its ``reference_speed``, and the course of the
    leader (``leader_id``) by its ``reference_course`` (``course_ahead_rad`` saying by how
    much); positions, flight paths, turn rates and the wingmen's courses as measured.

    Only the leader's: its opening turn is what its wingmen's speeds answer.  A wingman's
    own is its own, and in a held turn the built-in SITL's wingmen flew their courses 5°
    and more ahead of their plans', so that planned from the reference they were planned
    turning late, further off their slots each tick (the loiter route: 24 m at the turn
    onto the circle where they had been 10 m)."""
    out = {}
    for vid, s in states.items():
        planned = None if plan is None else plan.speed_at(vid, mission_time_s)
        s = replace(s, speed_m_s=reference_speed(planned, s.speed_m_s, bound_m_s))
        course = None if plan is None or vid != leader_id else plan.course_at(vid, mission_time_s)
        if course is not None:
            yaw = reference_course(course, s.yaw_rad, course_bound_rad)
            s = replace(s, yaw_rad=yaw, course_ahead_rad=math.remainder(yaw - s.yaw_rad, math.tau))
        out[vid] = s
    return out


HOLD_RELEASE = 2.0
"""A formation held (every wingman once within the target accuracy of its slot) is let go
when a wingman is more than this many target accuracies from its slot."""
HOLD_RESERVE_M_S = 2.0
"""The leader of a held formation flies at least this much below v_max (m/s): a wingman
the target accuracy behind its slot is planned ω·d = 3 m/s faster than the leader
(``catching_up_speed``, 10 m, ω = 0.3 rad/s), and gets most of it."""


def formation_holds(g: Guidance, target_accuracy_m: float, held: bool) -> bool:
    """Whether the formation is held after this tick's plan ``g``: every wingman within the
    target accuracy of its slot, or, once ``held``, within ``HOLD_RELEASE`` of them.  A
    fleet without wingmen is never held."""
    distances = g.local_target_distance_m[1:]
    if not distances or any(d is None for d in distances):
        return False
    worst = max(d for d in distances if d is not None)
    return worst <= (HOLD_RELEASE if held else 1.0) * target_accuracy_m


def leader_held(
    g: Guidance, v_max_m_s: float, v_min_m_s: float, decel_m_s2: float, accel_m_s2: float
) -> Guidance:
    """``g`` with the leader (index 0) keeping the speed it starts at, brought down at
    ``decel_m_s2`` to ``HOLD_RESERVE_M_S`` below ``v_max_m_s`` if above (never below
    ``v_min_m_s``), and into ``g.leader_speed_range_m_s`` at ``accel_m_s2`` or
    ``decel_m_s2`` if outside it.

    The paper's leader (Eq. 24) waits at v_min while any wingman is out of its slot and
    leads on at full acceleration once all are in.  Closed loop, wingmen cross the target
    accuracy back and forth, so the leader's speed law flips between −0.8 and +0.6 m/s²
    every few seconds (real ArduPlane, formation takeoff of 5: formed / broken 11 times in
    the first 25 s), and TECS flies every change partly as a climb or a sink: the leader's
    flight path swung ±4°, the slots 200 m behind ±15–20 m.  Waiting does nothing for a
    wingman beside or below its slot, and one behind has the reserve to catch up.  But a
    leader held at the speed it had slowed to while waiting can leave the slot inside the
    formation's turns slower than v_min (``gcs_ppf.planning.turns.held_speed_range``): the
    loiter route on a lossy link, held at 19 m/s round its circle, put the inner slot at
    15.5 m/s, and its wingman, at 16, drew ahead of it for 100 s.  So the range is kept
    ``HOLD_RESERVE_M_S`` inside at each end (its middle if narrower): a leader held at the
    top of the U-turn route's range (24.5 m/s) put its outer slot at v_max through the turn
    and its wingman, with nothing left to catch up with, fell 18 m behind it."""
    if g.speed_plan_t_s is None or g.speed_plan_m_s is None:
        return g
    low, high = g.leader_speed_range_m_s or (v_min_m_s, v_max_m_s)
    middle = 0.5 * (low + high)
    low, high = min(low + HOLD_RESERVE_M_S, middle), max(high - HOLD_RESERVE_M_S, middle)
    floor = max(v_min_m_s, low)
    cap = max(min(v_max_m_s - HOLD_RESERVE_M_S, high), floor)
    start = float(g.speed_plan_m_s[0, 0])
    t = g.speed_plan_t_s
    if start > cap:
        held = np.maximum(start - decel_m_s2 * t, cap)
    elif start < floor:
        held = np.minimum(start + accel_m_s2 * t, floor)
    else:
        held = np.full_like(t, start)
    plan = g.speed_plan_m_s.copy()
    plan[:, 0] = held
    speed = g.speed_m_s.copy()
    speed[0] = float(np.interp(0.5, t, held))
    ahead = None if g.speed_ahead_m_s is None else g.speed_ahead_m_s.copy()
    if ahead is not None:
        ahead[0] = float(np.interp(1.0, t, held))
    return replace(g, speed_plan_m_s=plan, speed_m_s=speed, speed_ahead_m_s=ahead)

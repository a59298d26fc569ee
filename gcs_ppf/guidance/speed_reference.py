"""The speed each tick plans from: where the previous plan's speed had got to by now (the
commanded reference), not the speed measured, as long as the two stay close.

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

from dataclasses import dataclass, replace

import numpy as np

from gcs_ppf.guidance.online import Guidance, VehicleState
from gcs_ppf.planning.scene import FloatArray

REFERENCE_BOUND_M_S = 2.0
"""The reference is kept within this of the measured speed (m/s): what ArduPlane lags an
airspeed ramp at the mission's rates by, with room (measured: 0.5–1.2 m/s behind a demand
ramping at 0.6–0.8 m/s², and ground speed 1–2 m/s above airspeed)."""


SPEED_COMMAND_LEAD_S = 0.25
"""The airspeed commanded is the plan's this far on: ArduPlane's TECS answers a speed demand
within ~0.25 s (measured: a 0.6 m/s step flown at ~2.4 m/s²).  With the plan started from
the reference a longer lead buys nothing, and each turn of the leader's wait law (Eq. 24,
waiting at 0.8 m/s² of deceleration or leading on at 0.6 m/s² of acceleration, which
flips as a wingman crosses the target accuracy) jumped the command by 1.4 m/s per second
of lead: with 1 s, on real ArduPlane, the leader's command flipped between 25.8 and
27.4 m/s every second or two, its throttle between 34 and 100 %, its vertical speed
between −3 and +4 m/s."""
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


FOLLOWED_ACCEL_M_S2 = 2.0
"""The fastest planned speed change (m/s², the mission's accel and decel) an autopilot is
taken to follow: ArduPlane's TECS flew 1.9–2.4 m/s² when asked for more."""
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
    [N] in the plan's order, the plan made at mission time ``planned_at_s``."""

    ids: tuple[int, ...]
    t_s: FloatArray
    speed_m_s: FloatArray
    planned_at_s: float

    @staticmethod
    def of(g: Guidance, planned_at_s: float) -> SpeedPlan | None:
        """The speed plan of ``g`` (None if it carries none)."""
        if g.speed_plan_t_s is None or g.speed_plan_m_s is None:
            return None
        return SpeedPlan(tuple(g.ids), g.speed_plan_t_s, g.speed_plan_m_s, planned_at_s)

    def speed_at(self, vehicle_id: int, mission_time_s: float) -> float | None:
        """The speed the plan had reached at ``mission_time_s`` (None: the vehicle is not in
        it, or the moment is before its start or past its end)."""
        if vehicle_id not in self.ids:
            return None
        elapsed = mission_time_s - self.planned_at_s
        if elapsed < 0.0 or elapsed > float(self.t_s[-1]):
            return None
        column = self.speed_m_s[:, self.ids.index(vehicle_id)]
        return float(np.interp(elapsed, self.t_s, column))


def reference_speed(
    planned_m_s: float | None, measured_m_s: float, bound_m_s: float = REFERENCE_BOUND_M_S
) -> float:
    """The speed to plan from: the previous plan's speed now (``planned_m_s``) kept within
    ``bound_m_s`` of the measured speed; the measured speed without a plan."""
    if planned_m_s is None:
        return measured_m_s
    return min(max(planned_m_s, measured_m_s - bound_m_s), measured_m_s + bound_m_s)


def reference_states(
    states: dict[int, VehicleState],
    plan: SpeedPlan | None,
    mission_time_s: float,
    bound_m_s: float = REFERENCE_BOUND_M_S,
) -> dict[int, VehicleState]:
    """``states`` with each speed replaced by its ``reference_speed`` (positions, attitudes
    and turn rates as measured)."""
    out = {}
    for vid, s in states.items():
        planned = None if plan is None else plan.speed_at(vid, mission_time_s)
        out[vid] = replace(s, speed_m_s=reference_speed(planned, s.speed_m_s, bound_m_s))
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


def leader_held(g: Guidance, v_max_m_s: float, v_min_m_s: float, decel_m_s2: float) -> Guidance:
    """``g`` with the leader (index 0) keeping the speed it starts at, brought down at
    ``decel_m_s2`` to ``HOLD_RESERVE_M_S`` below ``v_max_m_s`` if above (never below
    ``v_min_m_s``).

    The paper's leader (Eq. 24) waits at v_min while any wingman is out of its slot and
    leads on at full acceleration once all are in.  Closed loop, wingmen cross the target
    accuracy back and forth, so the leader's speed law flips between −0.8 and +0.6 m/s²
    every few seconds (real ArduPlane, formation takeoff of 5: formed / broken 11 times in
    the first 25 s), and TECS flies every change partly as a climb or a sink: the leader's
    flight path swung ±4°, the slots 200 m behind ±15–20 m.  Waiting does nothing for a
    wingman beside or below its slot, and one behind has the reserve to catch up."""
    if g.speed_plan_t_s is None or g.speed_plan_m_s is None:
        return g
    cap = max(v_max_m_s - HOLD_RESERVE_M_S, v_min_m_s)
    start = float(g.speed_plan_m_s[0, 0])
    t = g.speed_plan_t_s
    held = np.full_like(t, start) if start <= cap else np.maximum(start - decel_m_s2 * t, cap)
    plan = g.speed_plan_m_s.copy()
    plan[:, 0] = held
    speed = g.speed_m_s.copy()
    speed[0] = float(np.interp(0.5, t, held))
    ahead = None if g.speed_ahead_m_s is None else g.speed_ahead_m_s.copy()
    if ahead is not None:
        ahead[0] = float(np.interp(1.0, t, held))
    return replace(g, speed_plan_m_s=plan, speed_m_s=speed, speed_ahead_m_s=ahead)

"""A mission run in flight: its states, what it keeps between ticks, and how it reads in
the API's status; with the small geometric rules the service's tick applies."""

from __future__ import annotations

import asyncio
import math
from collections import deque
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

import numpy as np

from gcs_ppf.guidance import assurance, lag, obedience, safety_monitor, slew
from gcs_ppf.guidance.formation_watch import FormationWatch
from gcs_ppf.guidance.online import Guidance
from gcs_ppf.guidance.speed_reference import SpeedPlan
from gcs_ppf.mavlink.fences import FenceItem
from gcs_ppf.mission import Mission
from gcs_ppf.planning.route import Leg, Loitering, legs
from gcs_ppf.planning.zones import Zones, zones_from_mission
from gcs_ppf.service import commanding
from gcs_ppf.service.store import StoredRun
from gcs_ppf.service.tick_phases import TickPhases
from gcs_ppf.service.tick_rate import TickRate

NOT_RESPONDING_S = 3.0


@dataclass(frozen=True)
class SavedFence:
    """A vehicle's fence before the run put up its own (``service.vehicle_fences``): its
    list and FENCE_ENABLE, _TYPE, _ACTION as read (None: never read)."""

    items: list[FenceItem]
    params: dict[str, float | None]


"""Vehicle seconds out of GUIDED or refusing the course: not responding."""


class RunState(StrEnum):
    """Life of a mission run."""

    PENDING = "pending"
    """Uploaded, never started (or not since its last run ended)."""
    STARTING = "starting"
    """Vehicles being launched or switched to GUIDED."""
    RUNNING = "running"
    """Planning and commanding every tick."""
    COMPLETED = "completed"
    """The leader reached the target; every vehicle loiters."""
    COMPLETED_UNSAFE = "completed_unsafe"
    """The leader reached the target, but a vehicle entered a keep-out on the way
    (``safety_violation`` events): never a plain ``completed``."""
    ABORTED = "aborted"
    """Stopped by the operator; every vehicle loiters."""
    FAILED = "failed"
    """The leader was lost (or the run could not go on); every vehicle loiters."""
    INTERRUPTED = "interrupted"
    """The service stopped (a crash, ``kill -9``) while the run flew, and was started again:
    the vehicles flew on their last commands (and their own GCS failsafe) meanwhile."""


FINISHED = {
    RunState.COMPLETED,
    RunState.COMPLETED_UNSAFE,
    RunState.ABORTED,
    RunState.FAILED,
    RunState.INTERRUPTED,
}


@dataclass
class Run:
    """A mission run in flight (its lasting record is in the store)."""

    record: StoredRun
    mission_id: int
    mission: Mission
    orders: commanding.Orders
    state: RunState = RunState.STARTING
    outcome: str | None = None  # why it ended
    start_vehicle_time_s: float | None = None
    mission_time_s: float = 0.0
    last: Guidance | None = None
    speed_plan: SpeedPlan | None = None
    """The speeds the last tick planned, which the next plans from (``speed_reference``)."""
    formation_held: bool = False
    """The formation is held: the leader keeps its speed (``speed_reference.leader_held``)."""
    min_separation_m: float | None = None
    min_clearance_m: float | None = None
    nearest_keep_out: dict[int, tuple[str | None, float | None]] = field(default_factory=dict)
    """Each vehicle watched at the last tick: the keep-out nearest to it (the mission's
    ``"obstacles[j]"`` or ``"zones[k]"``) and how far it is from its surface now (m)."""
    legs: list[Leg] = field(init=False)
    """The leader's route, leg by leg (``gcs_ppf.planning.route``); one leg without one."""
    leg: int = 0
    """The leg the leader flies now (an index into ``legs``)."""
    loitering: Loitering | None = None
    """The loiter of a leg that ends in one, as far as it is flown (None: not begun); a
    run resumed flies it anew."""
    waypoint_times_s: list[float] = field(default_factory=list)
    """Mission time at which each waypoint of the route was reached (one with a loiter:
    its circles flown)."""
    formation: FormationWatch = field(init=False)
    """The formation flown (``guidance.formation_watch``): each wingman's slot error from
    the reported positions every tick, formed or broken, the run's formation figures."""
    abort: asyncio.Event = field(default_factory=asyncio.Event)
    lost_ids: set[int] = field(default_factory=set)
    taken_over: set[int] = field(default_factory=set)
    """Vehicles another ground station commanded (``vehicle_taken_over``), out of the run's
    command until handed back."""
    link_changes: dict[int, tuple[int, int, str]] = field(default_factory=dict)
    """Vehicle id → the last change of the link it is commanded on, told
    (``vehicle_link_changed``)."""
    duplicates: dict[int, tuple[int, ...]] = field(default_factory=dict)
    """Vehicle id → the links it was heard on at once (``duplicate_system_id`` told)."""
    commanded_speed: dict[int, float] = field(default_factory=dict)
    speed_sent_s: dict[int, float] = field(default_factory=dict)
    """When (our monotonic seconds) each vehicle was last sent its airspeed."""
    climb_trims: dict[int, slew.ClimbTrim] = field(default_factory=dict)
    """Each vehicle's climb trim (``gcs_ppf.guidance.slew.climb_trim``)."""
    ended_vehicle_s: float | None = None
    """The fleet's vehicle time when the run ended (``service.station.Station.fleet_time_s``)."""
    escaping: dict[int, assurance.Escape] = field(default_factory=dict)
    """Each vehicle's escape in force (the run-time assurance's last replacement), or the
    way its last one turned, for a while after it ended."""
    sent_courses: dict[int, deque[tuple[float, float]]] = field(default_factory=dict)
    """The courses (mission time, ICS yaw in rad) each vehicle was sent lately."""
    leader_pos: Any = None  # ICS position at the last tick
    leader_fix_ms: int | None = None
    """Vehicle time of the leader's newest position judged (``Station.path_since``)."""
    tick_latency_s: deque[float] = field(default_factory=lambda: deque(maxlen=10_000))
    tick_gaps_s: deque[float] = field(default_factory=lambda: deque(maxlen=RECENT_GAPS))
    """Vehicle seconds between the latest ticks: how long a command may have to hold."""
    task: asyncio.Task[None] | None = None
    hold_task: asyncio.Task[None] | None = None
    """The holds after the end and the watch that follows them."""
    safety: safety_monitor.Monitor = field(default_factory=safety_monitor.Monitor)
    obedience: obedience.Obedience = field(
        default_factory=lambda: obedience.Obedience(NOT_RESPONDING_S)
    )
    fleet_lag: lag.Lag = field(default_factory=lambda: lag.Lag(0.0, 0.0))
    """The fleet's lag at the last tick (``gcs_ppf.guidance.lag``), vehicle seconds."""
    lag_budget: lag.Budget = field(default_factory=lambda: lag.Budget(LAG_BUDGET_S))
    phases: TickPhases = field(default_factory=TickPhases)
    """Where the latest ticks' time went (``service.tick_phases``)."""
    decoded_s: float = 0.0
    """``Fleet.decoding_s`` at the last tick (the decoding since is the next tick's)."""
    tick_rate: TickRate | None = None
    """Whether the ticks keep their period (``service.tick_rate``), from the first tick."""
    fences_before: dict[int, SavedFence] = field(default_factory=dict)
    """The vehicles whose fence the run put up, and what they had (restored at the end)."""
    _zones: tuple[Mission, Zones] | None = field(default=None, repr=False)

    @property
    def zones(self) -> Zones:
        """The mission's zones as the planner's arrays (``gcs_ppf.planning.zones``), made
        once per mission document (a mission replaced mid-run gets its own)."""
        if self._zones is None or self._zones[0] is not self.mission:
            self._zones = (self.mission, zones_from_mission(self.mission))
        return self._zones[1]

    def __post_init__(self) -> None:
        self.formation = FormationWatch(self.mission.limits.target_accuracy)
        self.legs = legs(self.mission)


RECENT_GAPS = 50
"""Ticks whose spacing sets how long a command may hold (5 s of vehicle time at 10 Hz)."""
LAG_BUDGET_S = 1.0
"""Telemetry age + command delay (vehicle seconds) beyond which a ``lag_over_budget`` event
is raised."""


def min_of(a: float | None, b: float | None) -> float | None:
    if a is None:
        return b
    if b is None:
        return a
    return min(a, b)


def latency_ms(run: Run) -> dict[str, float] | None:
    """Tick latency (telemetry received → commands sent) percentiles, ms."""
    if not run.tick_latency_s:
        return None
    ms = np.array(run.tick_latency_s) * 1e3
    return {
        "p50": round(float(np.percentile(ms, 50)), 3),
        "p99": round(float(np.percentile(ms, 99)), 3),
        "ticks": int(ms.size),
    }


def summary(run: Run) -> dict[str, Any]:
    """What the store keeps of a run when it ends (``StoredRun.summary``)."""
    return {
        "mission_time_s": run.mission_time_s,
        "min_separation_m": run.min_separation_m,
        "min_obstacle_clearance_m": run.min_clearance_m,
        "safety_violations": run.safety.count,
        "deepest_violation_m": run.safety.deepest_m,
        "tick_latency_ms": latency_ms(run),
        "worst_lag_s": round(run.lag_budget.worst_s, 3),
        "formation": run.formation.figures().as_dict(),
        "waypoint_times_s": list(run.waypoint_times_s),
    }


def slots(mission: Mission) -> dict[str, list[float]]:
    """Each wingman's slot (its id as text: the status's and the events' JSON)."""
    return {str(w.id): list(w.slot) for w in mission.wingmen if w.slot is not None}


def status(run: Run) -> dict[str, Any]:
    """The API's status of a run in flight (``GET /missions/{id}/status``)."""
    g = run.last
    per_vehicle = []
    if g is not None:
        for i, vid in enumerate(g.ids):
            per_vehicle.append(
                {
                    "id": vid,
                    "ppf_state": g.state[i],
                    "avoiding": g.avoiding[i],
                    "formed": g.formed[i] if i else None,
                    "local_target_distance_m": g.local_target_distance_m[i],
                    **nearest_row(run.nearest_keep_out.get(vid, (None, None))),
                    "lost": vid in run.lost_ids,
                    "taken_over": vid in run.taken_over,
                }
            )
    return {
        "mission_id": run.mission_id,
        "run_id": run.record.id,
        "state": run.state,
        "outcome": run.outcome,
        "mission_time_s": round(run.mission_time_s, 3),
        "leader_id": run.mission.leader.id,
        "slots": slots(run.mission),
        "formation_formed": run.formation.formed,
        "formation": run.formation.status(),
        "leg": leg_status(run),
        "min_separation_m": run.min_separation_m,
        "min_obstacle_clearance_m": run.min_clearance_m,
        "safety_violations": run.safety.count,
        "tick_latency_ms": latency_ms(run),
        "tick_phases_ms": run.phases.summary_ms(),
        "tick_rate": None if run.tick_rate is None else run.tick_rate.as_dict(),
        "lag_s": {
            **run.fleet_lag.as_dict(),
            "budget_s": run.lag_budget.budget_s,
            "worst_s": round(run.lag_budget.worst_s, 3),
            "over_budget": run.lag_budget.over,
        },
        "vehicles": per_vehicle,
    }


def nearest_row(nearest: tuple[str | None, float | None]) -> dict[str, Any]:
    """A vehicle's nearest keep-out in the status: which, and its clearance now (m)."""
    name, clearance_m = nearest
    return {
        "nearest_keep_out": name,
        "clearance_m": None if clearance_m is None else round(clearance_m, 1),
    }


def leg_status(run: Run) -> dict[str, Any]:
    """The leg of the route the leader flies: its index, of how many, where it ends, the turn
    point it flies straight on to first (``route.onto_target``; None without one); with a
    loiter, its circle and how far it is flown (``loiter``; None without one)."""
    leg = run.legs[run.leg]
    turn = leg.turn_point_m
    loiter: dict[str, Any] | None = None
    if leg.loiter is not None:
        going = run.loitering
        loiter = {
            "radius_m": round(leg.loiter_radius_m, 1),
            "clockwise": leg.loiter.clockwise,
            "turns": leg.loiter.turns,
            "time_s": leg.loiter.time_s,
            "on_circle": going is not None and going.began_s is not None,
            "turns_flown": 0.0 if going is None else round(going.swept / (2.0 * math.pi), 2),
        }
    return {
        "index": leg.index,
        "of": len(run.legs),
        "to_m": [round(float(c), 2) for c in leg.end_m],
        "turn_point_m": None if turn is None else [round(float(c), 2) for c in turn],
        "final": leg.final,
        "loiter": loiter,
        "waypoint_times_s": list(run.waypoint_times_s),
    }


def changes(run: Run, g: Guidance) -> list[tuple[str, int | None]]:
    """The events of what changed in the plan since the run's last tick (``run.last``), as
    (kind, vehicle id).  The formation's events are the flown formation's
    (``run.formation``, fed in ``service.flight``), not the plan's."""
    out: list[tuple[str, int | None]] = []
    before = run.last
    if before is None:
        return out
    for i, vid in enumerate(g.ids):
        if g.avoiding[i] != before.avoiding[i]:
            out.append(("avoidance_entered" if g.avoiding[i] else "avoidance_left", vid))
        if g.resolving and before.resolving and g.resolving[i] != before.resolving[i]:
            out.append(("conflict_resolution_" + ("began" if g.resolving[i] else "ended"), vid))
        if g.state[i] == "s2" and before.state[i] != "s2":
            out.append(("local_minimum_escape", vid))
    return out

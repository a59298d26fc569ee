"""Where an interrupted run stood when the service stopped, read from what the store kept of
it: its events (each committed as it happened) and its telemetry samples.

Pure: the records in, the run's standing out.  ``FormationService.resume`` flies the run on
from it, ``FormationService.abort`` ends it there.  What the events say is taken as said:
the leader as the ``leader_succeeded`` events left it (``planning.succession``, applied in
turn), the route's leg as far as the ``waypoint_reached`` events went, the vehicles lost
and not back, the safety violations already counted (a run that had one never completes
plain ``completed``); the closest separation and clearance from the samples.  Mission time
goes on as if the service had never stopped (moving obstacles moved meanwhile): on the
leader's own clock, from the zero the events recorded for it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from gcs_ppf.guidance.online import clearance, separations
from gcs_ppf.mission import Mission
from gcs_ppf.planning import succession
from gcs_ppf.planning.scene import obstacles_from_mission
from gcs_ppf.planning.zones import zones_from_mission
from gcs_ppf.service.run import min_of
from gcs_ppf.service.store import StoredEvent, TelemetryRow


@dataclass(frozen=True)
class Standing:
    """An interrupted run as its records left it."""

    mission: Mission
    """The mission as the run flew it last: led by the last ``leader_succeeded``'s vehicle."""
    flew: bool
    """It had begun its ticks (``run_running``): False, it died while launching."""
    mission_time_s: float = 0.0
    """Of the latest event that has one."""
    wall_s: float | None = None
    """When that event was stored (``time.time()``)."""
    clock_zero_s: float | None = None
    """The leader's clock at mission time 0 (``leader_clock_zero_s`` of ``run_running`` or
    of the last ``leader_succeeded``): its seconds since boot, less the mission time."""
    leg: int = 0
    waypoint_times_s: tuple[float, ...] = ()
    lost_ids: frozenset[int] = frozenset()
    """Vehicles lost (``vehicle_lost``) and not heard again (``vehicle_back``)."""
    violations: int = 0
    deepest_m: dict[str, float] = field(default_factory=dict)
    """The deepest violation of each keep-out kind (``safety_monitor.Monitor.deepest_m``)."""


def standing(mission: Mission, events: Sequence[StoredEvent]) -> Standing:
    """The run of ``mission`` (as stored: obstacles and zones as last revised) that these
    events, in their order, were stored for."""
    flew = False
    time_s, wall_s, clock_zero = 0.0, None, None
    waypoints: list[float] = []
    lost: set[int] = set()
    violations = 0
    deepest: dict[str, float] = {}
    for e in events:
        if e.kind == "run_running":
            flew = True
            clock_zero = _clock_zero(e, clock_zero)
        elif e.kind == "leader_succeeded" and e.vehicle_id is not None:
            heir = next(v for v in mission.vehicles if v.id == e.vehicle_id)
            mission = succession.led_by(mission, heir)
            clock_zero = _clock_zero(e, None)
        elif e.kind == "waypoint_reached" and e.mission_time_s is not None:
            waypoints.append(e.mission_time_s)
        elif e.kind == "vehicle_lost" and e.vehicle_id is not None:
            lost.add(e.vehicle_id)
        elif e.kind == "vehicle_back" and e.vehicle_id is not None:
            lost.discard(e.vehicle_id)
        elif e.kind == "safety_violation" and e.detail is not None:
            violations += 1
            kind, depth = str(e.detail.get("keep_out")), float(e.detail.get("depth_m", 0.0))
            deepest[kind] = max(deepest.get(kind, 0.0), depth)
        if e.mission_time_s is not None and flew:
            time_s, wall_s = e.mission_time_s, e.wall_s
    return Standing(
        mission,
        flew,
        time_s,
        wall_s,
        clock_zero,
        len(waypoints),
        tuple(waypoints),
        frozenset(lost),
        violations,
        deepest,
    )


def _clock_zero(e: StoredEvent, otherwise: float | None) -> float | None:
    value = None if e.detail is None else e.detail.get("leader_clock_zero_s")
    return otherwise if value is None else float(value)


def mission_time_now_s(
    s: Standing, leader_time_s: float | None, now_wall_s: float, clock_rate: float
) -> float:
    """Mission time now: on the leader's clock (``leader_time_s``, its seconds since boot)
    from its zero, when it has one and has not restarted since; otherwise the latest
    event's, carried on by the wall time since at the vehicles' ``clock_rate`` (their
    seconds per ours).  0 for a run that never flew."""
    if not s.flew:
        return 0.0
    if s.clock_zero_s is not None and leader_time_s is not None:
        on_clock = leader_time_s - s.clock_zero_s
        if on_clock >= s.mission_time_s:
            return on_clock
    if s.wall_s is None:
        return s.mission_time_s
    return s.mission_time_s + max(0.0, now_wall_s - s.wall_s) * clock_rate


def closest_m(mission: Mission, rows: Sequence[TelemetryRow]) -> tuple[float | None, float | None]:
    """The closest separation and obstacle (and zone) clearance of the sampled positions
    (``Store.telemetry``'s rows: by mission time, ICS x, y, z at 5:8)."""
    if not rows:
        return None, None
    table = np.array([(r[0], *r[5:8]) for r in rows], dtype=float)
    obstacles = obstacles_from_mission(mission)
    zones = zones_from_mission(mission)
    separation: float | None = None
    clear: float | None = None
    times, starts = np.unique(table[:, 0], return_index=True)
    for t, a, b in zip(times, starts, [*starts[1:], len(table)], strict=True):
        positions = table[a:b, 1:4]
        separation = min_of(separation, separations(positions))
        clear = min_of(clear, clearance(positions, obstacles.at(float(t)), zones))
    return separation, clear

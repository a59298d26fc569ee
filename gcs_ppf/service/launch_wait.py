"""The vehicles waiting in the air while others take off: each held on a circle flown by the
service under run-time assurance (``ending.hold_during_launch``) — those flying when the
launch begins at once (in Table 3, wingmen 3 and 4 flew on towards each other while wingman
2 took off, 45.6 m apart), those that took off and were sent on (``launch.straight_on``, as
far as ``clear_ahead`` allows) once one of them nears the point it was sent to.

Why the second: ArduPlane circles the point it was sent to at WP_LOITER_RAD, unassured.
Climbed out of the formation takeoff of five, the five points lie 100 m apart abreast,
0.86–1.27 km on (the sphere cuts them short), so their circles overlap; on a link losing
20 % of its messages at 300 ms, the launch took 65 s, the others reached their points
meanwhile, and the leader and wingman 5 came to 47.2 m of each other (safe 50 m) before the
run began (the built-in SITL starting them in the air at the ground's height, as it then
did).  A launch as quick as usual (9 s idle) ends before any of them gets there, and the
formation takeoff keeps its shape.
"""

from __future__ import annotations

import asyncio
import math

import numpy as np

from gcs_ppf.geodesy import geodetic_to_enu
from gcs_ppf.guidance import holding
from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.mavlink.telemetry import VehicleTelemetry
from gcs_ppf.mission import Mission
from gcs_ppf.planning.scene import FloatArray, obstacles_from_mission
from gcs_ppf.planning.zones import zones_from_mission
from gcs_ppf.service import commanding, launch
from gcs_ppf.service.ending import hold_during_launch
from gcs_ppf.service.fleet import planning_states
from gcs_ppf.service.returning import home_heights
from gcs_ppf.service.run import Run
from gcs_ppf.service.station import Station

CLIMB_OUT_TURN_RADII = 2.0
"""A vehicle sent on after its takeoff keeps this many turn radii (at the mission's v_max
and ω) more than twice the safe distance from every keep-out on its way, room for
ArduPlane's turn onto it and its circle round the point it is sent to (``clear_ahead``)."""
HANDOVER_S = 10.0
"""Vehicle seconds before a vehicle sent on would turn onto the circle round its point
(``nearing``) that it is held instead: the holds' first commands through a link of 300 ms
latency at ×10 (3 s of the vehicles' time) and 20 % loss, with room to spare."""
LOOK_S = 0.5
"""How often (vehicle seconds) the vehicles sent on are looked at."""


def clear_ahead(mission: Mission, t: VehicleTelemetry) -> tuple[float, float] | None:
    """Where a vehicle that has climbed out is sent until the run begins (east, north metres
    from it): straight on along its course, level, as far as the way keeps twice the safe
    distance (as the holds do) and ``CLIMB_OUT_TURN_RADII`` turn radii more from every
    obstacle and zone, up to ``launch.STRAIGHT_ON_M``; where that is under four turn radii,
    along the course nearest its own that runs that far (``holding.clear_course``).  None
    (straight on) without a position or a course."""
    return _clear_ahead_of(mission, _position_m(mission, t), t)


def _position_m(mission: Mission, t: VehicleTelemetry) -> FloatArray | None:
    """Where it is in the mission's ICS (m), or None without a position."""
    if t.lat_deg is None or t.lon_deg is None or t.alt_amsl_m is None:
        return None
    return np.array(geodetic_to_enu(t.lat_deg, t.lon_deg, t.alt_amsl_m, mission.origin))


def _clear_ahead_of(
    mission: Mission, here: FloatArray | None, t: VehicleTelemetry
) -> tuple[float, float] | None:
    """``clear_ahead`` of a vehicle at ``here`` (ICS, m)."""
    if here is None:
        return None
    if t.vn_m_s is None or t.ve_m_s is None or math.hypot(t.vn_m_s, t.ve_m_s) == 0.0:
        return None
    turn_m = turn_radius_m(mission)
    keep = 2.0 * mission.limits.safe_distance_obstacle + CLIMB_OUT_TURN_RADII * turn_m
    yaw, run = holding.clear_course(
        here,
        math.atan2(t.vn_m_s, t.ve_m_s),
        obstacles_from_mission(mission).at(0.0),
        zones_from_mission(mission),
        keep,
        launch.STRAIGHT_ON_M,
        2.0 * CLIMB_OUT_TURN_RADII * turn_m,
    )
    return run * math.cos(yaw), run * math.sin(yaw)


def turn_radius_m(mission: Mission) -> float:
    """The mission's turn radius at v_max and its slower turn rate."""
    lim = mission.limits
    return lim.v_max / min(lim.max_yaw_rate, lim.max_pitch_rate)


def nearing(
    here_m: FloatArray, speed_m_s: float, point_m: FloatArray, circle_m: float, handover_s: float
) -> bool:
    """Within ``handover_s`` (at ``speed_m_s``) of turning onto the circle round ``point_m``:
    level, ``circle_m`` from it (its radius and the turn onto it)."""
    gap_m = math.hypot(point_m[0] - here_m[0], point_m[1] - here_m[1]) - circle_m
    return gap_m < speed_m_s * handover_s


class LaunchWait:
    """The holds flown while the launch goes on: ``clear_ahead`` is given to the launch (it
    notes where each vehicle is sent on to); ``stop`` once the launch is done (the holds
    are then sent once, and the run commands the vehicles at its first tick)."""

    def __init__(self, station: Station, run: Run, ids: list[int]) -> None:
        self.station, self.run = station, run
        self.points: dict[int, FloatArray] = {}  # where each vehicle was sent on to (ICS)
        self.held: set[int] = set()
        self.holds: asyncio.Task[None] | None = None
        fleet = station.fleet
        flying = set()
        for vid in ids:
            t = fleet.telemetry(vid)
            if t is not None and not launch.on_ground(t):
                flying.add(vid)
        if flying and len(flying) < len(ids):  # some take off: the others hold meanwhile
            self._hold(flying)
        self.watch = station.spawn(self._watch())

    def clear_ahead(self, vehicle_id: int, t: VehicleTelemetry) -> tuple[float, float] | None:
        """``clear_ahead`` for the launch, the point noted."""
        here = _position_m(self.run.mission, t)
        ahead = _clear_ahead_of(self.run.mission, here, t)
        if ahead is not None and here is not None:
            self.points[vehicle_id] = here[:2] + ahead
        return ahead

    async def stop(self) -> None:
        """No more holds started; the ones flown sent once (``hold_during_launch``)."""
        self.watch.cancel()
        await asyncio.wait([self.watch])
        await self._cancel_holds()

    def _hold(self, ids: set[int]) -> None:
        located = [(v, p) for v, p in self.station.located(self.run) if v.system_id in ids]
        states, _, _ = planning_states(located)
        self.held = set(ids)
        floor = self._over_the_climbs_m(ids)
        holds = hold_during_launch(self.station, self.run, states, floor)
        self.holds = self.station.spawn(holds)

    def _over_the_climbs_m(self, held: set[int]) -> float:
        """The lowest a hold may be: a stack level (``commanding.stack_spacing_m``) over the
        takeoff altitude of every vehicle not held (its home and the TKOFF_ALT set), which
        climbs out and flies on level there: held at its own height, the leader came to
        42.1 m of a wingman climbing out late below it on a lossy link."""
        takeoff_m = self.station.settings.takeoff_alt_m
        homes = home_heights(self.station, self.run)
        climbs = [z + takeoff_m for vid, z in homes.items() if vid not in held]
        if not climbs:
            return -math.inf
        return max(climbs) + commanding.stack_spacing_m(self.run.mission)

    async def _cancel_holds(self) -> None:
        if self.holds is not None:
            self.holds.cancel()
            await asyncio.wait([self.holds])

    def _sent_on_and_guided(self) -> dict[int, VehicleTelemetry]:
        out = {}
        for vid in self.points:
            t = self.station.fleet.telemetry(vid)
            if t is not None and t.custom_mode == int(PlaneMode.GUIDED):
                out[vid] = t
        return out

    def _nearing(self, vid: int, t: VehicleTelemetry) -> bool:
        here = _position_m(self.run.mission, t)
        if here is None or t.vn_m_s is None or t.ve_m_s is None:
            return False
        circle_m = commanding.HOLD_MIN_RADIUS_M + turn_radius_m(self.run.mission)
        speed = math.hypot(t.vn_m_s, t.ve_m_s)
        return nearing(here, speed, self.points[vid], circle_m, HANDOVER_S)

    async def _watch(self) -> None:
        """Every ``LOOK_S``: once a vehicle sent on and flying there in GUIDED nears its
        point, every such vehicle is held with those held before (their holds planned
        again, together: a ``launch_wait_held`` event)."""
        while True:
            await asyncio.sleep(LOOK_S / self.station.fleet.clock_rate())
            guided = self._sent_on_and_guided()
            near = [v for v, t in guided.items() if v not in self.held and self._nearing(v, t)]
            if not near:
                continue
            joining = sorted(set(guided) - self.held)
            self.station.event(self.run, "launch_wait_held", None, vehicles=joining, nearing=near)
            await self._cancel_holds()
            self._hold(self.held | set(guided))

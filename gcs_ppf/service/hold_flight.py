"""The holding phase after a run, flown by the service under run-time assurance: each
vehicle is flown onto its holding circle and round it with course and altitude commands
at the tick rate, every one through ``guidance.assurance`` with its teammates and the
obstacles as keep-outs (as in a run), and the circles are handed to the autopilots
(GUIDED's loiter, ``commanding.loiter_orders``) only once every vehicle flies its own, at
its own level of the stack (``holding.on_ring``).

Why: handed to the autopilots at once, the holds were safe only while the vehicles flew
them in step. In 172 campaign runs (session 9) four vehicles entered a keep-out after the
end and none during a run: two climbed through a teammate's level on overlapping circles
(one after its hold had to be sent twice on a lossy link), two descended into a sphere on
the way to a circle that had been checked against another approach than the one flown.
Nothing watched the approaches but the safety monitor, which only tells.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections import deque

from gcs_ppf.guidance import assurance, holding, lag, obedience
from gcs_ppf.guidance.airframe import Airframe
from gcs_ppf.guidance.tick_plan import traffic_radius_m
from gcs_ppf.mavlink import commands
from gcs_ppf.planning.scene import obstacles_from_mission
from gcs_ppf.service import commanding
from gcs_ppf.service.fleet import planning_states
from gcs_ppf.service.run import Run
from gcs_ppf.service.station import Station
from gcs_ppf.service.watch import ground, watch_once

SETTLE_MAX_S = 180.0
"""Vehicle seconds the service flies the holds at most; then they are handed over as they
are (``hold_settle_timeout`` event)."""
SPEED_RESEND_S = 1.0
"""v_min is sent again this often (vehicle seconds) while the service flies the holds: a
DO_CHANGE_SPEED lost on a lossy link would leave a vehicle at its run's speed."""
GAPS_KEPT = 20  # the latest tick gaps that size a command's hold (``lag.hold_s``)


def taken_over(station: Station, run: Run) -> set[int]:
    """The vehicles of ``run`` that a run started after it commands now (of its mission or
    another: its holds are not to be flown or handed over)."""
    later = [r for r in station.runs.values() if r is not run and r.record.id > run.record.id]
    mine = {v.id for v in run.mission.vehicles}
    return mine & {v.id for r in later for v in r.mission.vehicles}


async def fly_holds(
    station: Station, run: Run, circles: dict[int, holding.Hold], *, launching: bool = False
) -> None:
    """Fly every vehicle of ``circles`` still heard and obeying to its circle and round it
    (``commanding.command_holds``) at ``tick_hz`` of the vehicles' time, with the safety
    monitor on every tick, until all of them are on their rings (``holding.on_ring``) or
    ``SETTLE_MAX_S`` has passed after the run's end; while the run is ``launching`` (the
    vehicles flying hold while others take off), until cancelled.  Every other vehicle
    with a state is avoided as traffic: one taking off, lost from the holds, flagged not
    responding, or commanded by a later run (``taken_over``; when every one is, the holds
    end there)."""
    fleet, settings, mission = station.fleet, station.settings, run.mission
    tick_hz, positions_hz = station.rates_hz(mission)
    period = 1.0 / tick_hz
    telemetry_interval = 1.0 / positions_hz
    ended = run.ended_vehicle_s
    if ended is None and not launching:
        return
    event = station.events_of(run)
    gaps: deque[float] = deque(maxlen=GAPS_KEPT)
    speed_sent: dict[int, float] = {}
    last_tick: float | None = None
    kind = "launch_holds_flown" if launching else "holds_flown"
    station.event(run, kind, None, vehicles=sorted(circles))
    while True:
        fleet.telemetry_event.clear()
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(1.0):
                await fleet.telemetry_event.wait()
        now = station.fleet_time_s()
        taken = taken_over(station, run)
        if now is None or set(circles) <= taken:
            return
        after = 0.0 if ended is None else now - ended  # after the end (0 while launching)
        if last_tick is not None and now - last_tick < period * 0.999:
            continue
        if last_tick is not None:
            gaps.append(now - last_tick)
        last_tick = now
        located = [(v, p) for v, p in station.located(run) if not v.lost]
        watch_once(station, run, located, after)
        states, active, lags = planning_states(located)
        stuck = run.obedience.not_responding & set(states)
        ids = [
            v.id
            for v in mission.vehicles
            if v.id in circles and v.id in active and v.id not in stuck | taken
        ]
        traffic_ids = set(states) - set(ids)
        airframes = {v.system_id: Airframe.from_telemetry(v.telemetry) for v, _ in located}
        motions = [commanding.hold_motion(states[i], airframes[i], mission) for i in ids]
        settled = [
            holding.on_ring(
                m.pos_m, m.yaw_rad, m.climb_rate_m_s, circles[i], m.speed_m_s, m.turn_rate_rad_s
            )
            for i, m in zip(ids, motions, strict=True)
        ]
        if not launching and all(settled):
            station.event(run, "holds_settled", None, after_end_s=round(after, 1))
            return
        if not launching and after > SETTLE_MAX_S:
            off = [i for i, s in zip(ids, settled, strict=True) if not s]
            station.event(
                run, "hold_settle_timeout", None, after_end_s=round(after, 1), off_ring=off
            )
            return
        obstacles = obstacles_from_mission(mission).at(run.mission_time_s + after)
        if traffic_ids:
            traffic = obedience.as_obstacles(states, traffic_ids, traffic_radius_m(mission))
            obstacles = obedience.with_obstacles(obstacles, traffic)
        lim = mission.limits
        keep = assurance.KeepOut(
            obstacles,
            ground(run, located),
            lim.safe_distance_obstacle,
            lim.safe_distance_uav,
            run.zones,
        )
        starvation = settings.starvation_allowance_s * fleet.clock_rate()
        hold_s = lag.hold_s(
            gaps, period, telemetry_interval, lag.worst(list(lags.values())), starvation
        )
        await commanding.command_holds(
            fleet,
            circles,
            ids,
            motions,
            run.orders,
            keep,
            hold_s,
            event,
            run.escaping,
            run.mission_time_s + after,
        )
        for vid in ids:
            if now - speed_sent.get(vid, -SPEED_RESEND_S) >= SPEED_RESEND_S:
                speed_sent[vid] = now
                slowest = commanding.slowest_airspeed(mission, airframes[vid])
                await fleet.send(vid, commands.change_speed(vid, slowest))

"""Flying one run: its vehicles launched, then a planning tick on the leader's clock until
the run ends, each tick watching losses, safety, obedience and lag, planning
(``guidance.tick_plan``) and commanding (``service.commanding``), sampling telemetry.

The end itself (the run's final state, the holds, the watch after) is ``service.ending``.
"""

from __future__ import annotations

import asyncio
import itertools
import logging
import math
import statistics
import time
from collections import deque
from dataclasses import replace

import numpy as np

from gcs_ppf.geodesy import velocity_ned_to_enu
from gcs_ppf.guidance import (
    assurance,
    failsafe,
    lag,
    obedience,
    speed_reference,
    tick_plan,
)
from gcs_ppf.guidance.airframe import Airframe
from gcs_ppf.guidance.formation_watch import slot_errors_m
from gcs_ppf.guidance.online import (
    VehicleState,
    home_ground,
    nearest_keep_outs,
    separations,
)
from gcs_ppf.guidance.tick_plan import traffic_radius_m
from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.mavlink.enums import MAV_CMD_DO_REPOSITION, MAV_CMD_GUIDED_CHANGE_HEADING
from gcs_ppf.planning import succession
from gcs_ppf.planning.ppf.primitives import LEADER_SPEED_CHANGE_SHARE
from gcs_ppf.planning.route import Loitering, leg_flown, onto_target
from gcs_ppf.planning.scene import FloatArray, Obstacles, obstacles_from_mission
from gcs_ppf.service import commanding, launch, vehicle_fences
from gcs_ppf.service.ending import end
from gcs_ppf.service.fleet import planning_states
from gcs_ppf.service.launch_wait import LaunchWait
from gcs_ppf.service.returning import home_heights
from gcs_ppf.service.run import NOT_RESPONDING_S, Run, RunState, changes, min_of, slots
from gcs_ppf.service.station import Station
from gcs_ppf.service.tick_rate import TickRate
from gcs_ppf.service.watch import Located, current_reports, reported_together, watch_safety

log = logging.getLogger("gcs_ppf.service.runs")  # the runs' log, under its name of old

COURSE_COMMAND = {  # the command each guidance mode flies by
    "course": MAV_CMD_GUIDED_CHANGE_HEADING,
    "point": MAV_CMD_DO_REPOSITION,
}
RECENT_TICKS = 20  # the tick's own work is the median of this many latest
SENT_COURSES_KEPT = 100  # courses kept per vehicle for the obedience check (10 s at 10 Hz)
TICK_SPACING = 0.75
"""A tick comes with the first position of the leader at least this share of a period
after the one the last tick planned from (``due``).  A 10 Hz stream's positions are
stamped on the autopilot's loop, 0.08 and 0.12 s apart by turns (the built-in SITL's 50 Hz
steps, ArduPlane's scheduler): waiting a whole period of the leader's clock (any message
of its moves it) passed over the early ones, commands came 0.1 and 0.2 s apart in a
pattern, and the altitude demand, held twice as long every half second, swung every
vehicle's flight path by ±1° at 2 Hz, the slots 600 m behind by ±10 m (Table 2 at 1×,
observer: in formation 73–77 % of the flight after forming, held 4 s at most; ticking on
every position, 98–99 %, held 23 s)."""
TICK_FALLBACK = 2.0
"""Periods of the leader's clock after which a tick comes without a new position of its."""


async def fly(station: Station, run: Run) -> None:
    """The run from launch to its end; an error fails the run, never the service."""
    try:
        await station.kernels_loaded()  # no tick compiles or loads a kernel
        await launch_fleet(station, run)
        run.state = RunState.RUNNING
        station.store.update_run(run.record.id, RunState.RUNNING)
        if run.start_vehicle_time_s is None:  # mission time 0 now, or a resumed run's on
            now_v = vehicle_time_s(station, run)
            if now_v is not None:
                run.start_vehicle_time_s = now_v - run.mission_time_s
        station.event(run, "run_running", leader_clock_zero_s=run.start_vehicle_time_s)
        await tick_loop(station, run)
    except asyncio.CancelledError:
        raise
    except launch.CommandFailed as exc:  # a vehicle refused: its answer, not a bug
        log.warning("mission %d failed: %s", run.mission_id, exc)
        end(station, run, RunState.FAILED, f"error: {exc}")
    except Exception as exc:  # a run must never take the service down
        log.exception("mission %d failed", run.mission_id)
        end(station, run, RunState.FAILED, f"error: {exc}")


async def launch_fleet(station: Station, run: Run) -> None:
    """Every vehicle flying in GUIDED (``gcs_ppf.service.launch``: those on the ground taken off
    in TAKEOFF mode to their TKOFF_ALT first, every arm and mode change confirmed);
    parameters not answered yet are asked for again first.  A vehicle lost meanwhile is
    left out and the run told (``vehicle_lost``); the leader lost ends it at the first tick."""
    ids = [v.id for v in run.mission.vehicles if v.id not in run.lost_ids]  # (resumed: lost)
    for vid in ids:
        await station.fleet.request_airframe_params(vid, missing_only=True)
    if station.settings.failsafe_rtl_altitude:  # beside the launch, not before it
        station.spawn(set_failsafe_altitudes(station, run, ids))
    if station.settings.fences and run.mission.zones:
        station.spawn(vehicle_fences.put_up(station, run, ids))

    def is_lost(vid: int) -> bool:
        vehicle = station.fleet.by_id.get(vid)
        return vehicle is not None and vehicle.lost

    def on_lost(vid: int) -> None:  # as ``losses`` would say it at the first tick
        run.lost_ids.add(vid)
        station.event(run, "vehicle_lost", vid)

    waiting = LaunchWait(station, run, ids)
    try:
        await launch.launch(
            station.fleet,
            ids,
            station.settings.takeoff_alt_m,
            station.events_of(run),
            takeoff_dist_m=station.settings.takeoff_dist_m,
            is_lost=is_lost,
            on_lost=on_lost,
            ready_timeout_s=station.settings.prearm_timeout_s,
            clear_ahead=waiting.clear_ahead,
        )
    finally:  # the holds flown until now, sent once, before the run
        await waiting.stop()


async def set_failsafe_altitudes(station: Station, run: Run, ids: list[int]) -> None:
    """Each vehicle's RTL_ALTITUDE set and read back (``guidance.failsafe``: over every
    keep-out, one holding level apart), all at once: a ``failsafe_rtl_altitude`` event with
    the altitude above its home as read back (None: never answered), and the value it had."""
    homes = {vid: z for vid, z in home_heights(station, run).items() if vid in ids}
    altitudes = failsafe.rtl_altitudes_m(
        run.mission, homes, run.mission_time_s, commanding.stack_spacing_m(run.mission)
    )

    async def set_one(vid: int, alt_m: float) -> None:
        t = station.fleet.telemetry(vid)
        before = None if t is None else t.param("RTL_ALTITUDE")
        read = await launch.set_param(
            station.fleet, vid, "RTL_ALTITUDE", alt_m, station.events_of(run)
        )
        station.event(
            run,
            "failsafe_rtl_altitude",
            vid,
            rtl_altitude_m=read,
            was_m=None if before is None else before.value,
        )

    await asyncio.gather(*(set_one(vid, alt) for vid, alt in altitudes.items()))


def vehicle_time_s(station: Station, run: Run) -> float | None:
    """The leader's clock (seconds since its boot), which the ticks follow."""
    leader = station.fleet.by_id.get(run.mission.leader.id)
    if leader is None or leader.telemetry.time_boot_ms is None:
        return None
    return leader.telemetry.time_boot_ms / 1000.0


def leader_fix_s(station: Station, run: Run) -> float | None:
    """When the leader's latest position was taken (seconds of its clock)."""
    leader = station.fleet.by_id.get(run.mission.leader.id)
    if leader is None or leader.telemetry.position_boot_ms is None:
        return None
    return leader.telemetry.position_boot_ms / 1000.0


def due(
    since_tick_s: float,
    fix_s: float | None,
    last_fix_s: float | None,
    period_s: float,
    spacing: float = TICK_SPACING,
) -> bool:
    """Whether a tick is due: the leader's position ``fix_s`` new and ``spacing`` of a
    period after the one the last tick planned from (``last_fix_s``); or, its positions
    missing, ``TICK_FALLBACK`` periods of its clock since the last tick (``since_tick_s``).
    Its other messages move its clock too, some stamped just before a position: ticking
    on those ticked twice a period.  ``spacing`` 1: a whole period of its clock, a
    position or not (``tick_spacing``)."""
    if spacing >= 1.0:
        return since_tick_s >= period_s * 0.999
    if fix_s is not None and last_fix_s is not None and fix_s - last_fix_s >= period_s * spacing:
        return True
    return since_tick_s >= period_s * TICK_FALLBACK


def tick_spacing(on_radio: bool, overrunning: bool) -> float:
    """``due``'s spacing: ``TICK_SPACING``, or whole periods where a vehicle of the run is
    commanded over a radio or while the ticks overrun their period (``service.tick_rate``).
    A radio's uplink is budgeted at a tick a period (docs/service.md#telemetry-radios: 1.0
    kB/s a vehicle); ticking with every position sends a third more, and five vehicles on
    one 57,600-baud radio (83 % busy up at whole periods) lost commands and missed their
    target time (tests/integration/test_serial.py, 2 runs of 2).  A service short of CPU
    (a burner on each core) gains nothing from more ticks: 2 of the integration tests
    failed once so, against none with whole periods."""
    return 1.0 if on_radio or overrunning else TICK_SPACING


def run_spacing(station: Station, run: Run) -> float:
    """``tick_spacing`` for the run as it is now (its vehicles' links, its tick rate)."""
    assert run.tick_rate is not None
    on_radio = station.fleet.on_radio(v.id for v in run.mission.vehicles)
    return tick_spacing(on_radio, run.tick_rate.overrunning)


async def tick_loop(station: Station, run: Run) -> None:
    """A tick at ``tick_hz`` of the leader's clock (lower where a radio carries the run's
    vehicles: ``Station.rates_hz``, a ``rates_fitted`` event), or with a position of the leader's
    (``due``), woken by fresh telemetry, until the run is aborted or ends; a telemetry
    sample at ``telemetry_sample_hz`` of mission time.  A new leader's clock carries the
    mission time on from where the last one left it.  The first tick counts the decoding
    since the loop began (counted from the service's start, it took in the whole launch's:
    a first tick of 1.7–4.6 s of work and a ``tick_overrun`` event in 15 of 69 flights of the
    ArduPlane-scale missions at ×10)."""
    fleet = station.fleet
    tick_hz, positions_hz = station.rates_hz(run.mission)
    if tick_hz < station.settings.tick_hz:  # a radio carries its vehicles
        station.event(run, "rates_fitted", None, tick_hz=tick_hz, positions_hz=positions_hz)
    period = 1.0 / tick_hz
    sample_period = 1.0 / station.settings.telemetry_sample_hz
    last_tick: float | None = None
    last_fix: float | None = None
    last_sample = -math.inf
    run.tick_rate = TickRate(tick_hz)
    clock_of = run.mission.leader.id
    spacing = run_spacing(station, run)
    run.decoded_s = fleet.decoding_s()  # the launch's decoding is not the first tick's work
    while not run.abort.is_set():
        fleet.telemetry_event.clear()
        try:
            async with asyncio.timeout(1.0):
                await fleet.telemetry_event.wait()
        except TimeoutError:
            pass
        if await losses(station, run):  # not on the leader's clock: it may be the one lost
            return
        received = fleet.telemetry_received_s
        now_v = vehicle_time_s(station, run)
        if now_v is None:
            continue
        if run.start_vehicle_time_s is None:  # (a resumed run's mission time goes on)
            run.start_vehicle_time_s = now_v - run.mission_time_s
        if run.mission.leader.id != clock_of:  # a new leader: mission time goes on, on its clock
            clock_of = run.mission.leader.id
            run.start_vehicle_time_s = now_v - run.mission_time_s
            last_tick = last_fix = None
        fix = leader_fix_s(station, run)
        if last_tick is not None and not due(now_v - last_tick, fix, last_fix, period, spacing):
            continue
        if last_tick is not None:
            run.tick_gaps_s.append(now_v - last_tick)
        last_tick, last_fix = now_v, fix
        run.mission_time_s = now_v - run.start_vehicle_time_s
        phases = run.phases
        phases.begin_tick()
        decoded = fleet.decoding_s()
        phases.add("decoding", decoded - run.decoded_s)
        run.decoded_s = decoded
        done = await tick(station, run)
        run.tick_latency_s.append(time.perf_counter() - received)
        if run.mission_time_s - last_sample >= sample_period:
            last_sample = run.mission_time_s
            with phases.phase("storage"):
                sample(station, run)
        with phases.phase("events"):
            station.publish()
        work_s = sum(phases.end_tick().values())
        if done:  # the run's last event is its end: the rate of the tick that ended it is moot
            return
        keep_rate(station, run, now_v, work_s)
        spacing = run_spacing(station, run)  # once a tick: the loop wakes with every position


def keep_rate(station: Station, run: Run, now_v: float, work_s: float) -> None:
    """The tick's work (``work_s``, ours: its phases, decoding since the last included)
    against its period in the vehicles' seconds (``service.tick_rate``): a ``tick_overrun``
    event when the ticks start overrunning it, ``tick_rate_kept`` when they keep it again."""
    assert run.tick_rate is not None
    change = run.tick_rate.update(now_v, work_s * station.fleet.clock_rate())
    if change is not None:
        station.event(run, change, None, **run.tick_rate.event_detail())


async def losses(station: Station, run: Run) -> bool:
    """Events for vehicles newly lost (the watchdog's verdict, in their own seconds); the
    leader lost, a wingman leads (``hand_over``); True when none is left to: the run has
    then failed, every vehicle loitering."""
    for v in run.mission.vehicles:
        vehicle = station.fleet.by_id.get(v.id)
        if vehicle is not None and vehicle.lost and v.id not in run.lost_ids:
            run.lost_ids.add(v.id)
            station.event(run, "vehicle_lost", v.id)
        elif vehicle is not None and not vehicle.lost and v.id in run.lost_ids:
            run.lost_ids.discard(v.id)  # heard again: planned for and watched again
            run.obedience.forget(v.id)  # and commanded again
            station.event(run, "vehicle_back", v.id)
        change = None if vehicle is None else vehicle.link_change
        if change is not None and run.link_changes.get(v.id) is not change:
            run.link_changes[v.id] = change
            station.event(run, "vehicle_link_changed", v.id, was=change[0], now=change[1],
                          why=change[2])  # fmt: skip
        if vehicle is not None and vehicle.duplicate_links != run.duplicates.get(v.id, ()):
            if vehicle.duplicate_links:
                run.duplicates[v.id] = vehicle.duplicate_links
                station.event(
                    run,
                    "duplicate_system_id",
                    v.id,
                    links=list(vehicle.duplicate_links),
                    commanded_link=vehicle.link_id,
                )
            else:
                run.duplicates.pop(v.id, None)
    if run.mission.leader.id not in run.lost_ids or hand_over(station, run, "lost"):
        return False
    end(station, run, RunState.FAILED, "leader lost")
    return True


def hand_over(station: Station, run: Run, why: str) -> bool:
    """The leader lost (``why``: ``lost``, ``not_responding`` or ``taken_over``): the
    wingman of highest priority leads and the slots move to it (``planning.succession``), a
    ``leader_succeeded`` event; False when no wingman is left to lead.  What the ticks
    carried from one to the next about the old leader's plan starts again."""
    out = run.mission.leader.id
    unable = run.lost_ids | run.obedience.not_responding | run.taken_over | {out}
    mission = succession.succeed(run.mission, unable)
    if mission is None:
        return False
    run.mission = mission
    run.orders = replace(run.orders, mission=mission)
    run.last = None
    run.speed_plan = None
    run.formation_held = False
    run.leader_pos = run.leader_fix_ms = None
    now_v = vehicle_time_s(station, run)  # the new leader's clock (``tick_loop`` follows it)
    station.event(
        run,
        "leader_succeeded",
        mission.leader.id,
        lost_leader=out,
        why=why,
        slots=slots(mission),
        leader_clock_zero_s=None if now_v is None else now_v - run.mission_time_s,
    )
    return True


def check_obedience(
    station: Station,
    run: Run,
    located: Located,
    states: dict[int, VehicleState],
    airframes: dict[int, Airframe],
) -> bool:
    """Which vehicles obey (GUIDED, the course command ACCEPTED, the course sent flown
    or turned to): events when one stops for ``NOT_RESPONDING_S`` of vehicle time or
    comes back; True if it is the leader.  One without a new position for
    ``obedience.SILENT_S`` is not judged (``Obedience.unheard``)."""
    command = COURSE_COMMAND[station.settings.guidance]
    reports = []
    now = time.monotonic()
    for v, _ in located:
        t = v.telemetry
        received = t.position_received_s
        if received is None or v.clock.vehicle_seconds(now - received) > obedience.SILENT_S:
            run.obedience.unheard(v.system_id)
            continue
        ack = t.ack(command)
        guided = t.custom_mode == PlaneMode.GUIDED
        result = ack.result if ack else None
        s = states.get(v.system_id)
        sent = obedience.courses_in_effect(
            run.sent_courses.get(v.system_id, ()), run.mission_time_s, run.fleet_lag.total_s
        )
        if s is None or not sent:
            reports.append(obedience.Report(v.system_id, guided, result))
            continue
        turn = -t.course_rate_rad_s  # clockwise from north → ICS yaw rate
        m = commanding.motion(s, airframes[v.system_id], run.mission)
        for course in sent:
            error = math.remainder(course - s.yaw_rad, math.tau)
            expected = min(m.turn_rate_rad_s, abs(error) / max(m.heading_tau_s, 1e-3))
            reports.append(obedience.Report(v.system_id, guided, result, error, turn, expected))
    if run.tick_gaps_s and run.tick_gaps_s[-1] > NOT_RESPONDING_S:
        run.obedience.restart()  # no evidence across our own stall
    flagged, cleared = run.obedience.update(run.mission_time_s, reports)
    by_id = {v.system_id: v.telemetry for v, _ in located}
    for vid in flagged:
        t = by_id[vid]
        ack = t.ack(command)
        station.event(
            run,
            "vehicle_not_responding",
            vid,
            mode=t.mode_name,
            last_ack=ack.result if ack else None,
        )
    for vid in cleared:
        station.event(run, "vehicle_responding", vid)
    return run.mission.leader.id in flagged


def account_lag(station: Station, run: Run, lags: list[lag.Lag]) -> None:
    """The fleet's lag this tick, and an event when it crosses the budget."""
    run.fleet_lag = lag.worst(lags)
    change = run.lag_budget.update(run.fleet_lag.total_s)
    if change is not None:
        station.event(
            run, change, None, budget_s=run.lag_budget.budget_s, **run.fleet_lag.as_dict()
        )


async def tick(station: Station, run: Run) -> bool:
    """One planning tick; True when the run has ended."""
    mission = run.mission
    leader_id = mission.leader.id

    phases = run.phases
    with phases.phase("prediction"):
        located = list(station.located(run))  # one geodetic → ICS conversion per vehicle
        ground = home_ground(
            [
                (pos[2], v.telemetry.relative_alt_m)
                for v, pos in located
                if v.telemetry.relative_alt_m is not None
            ]
        )
        # what the vehicles report, on one instant (the safety monitor's and the status's
        # distances), of those not lost (``losses`` has just matched them to the fleet's)
        reporting = [(v, p) for v, p in located if v.system_id not in run.lost_ids]
        ids = [v.system_id for v, _ in reporting]
        together, now = reported_together(reporting)
    with phases.phase("monitoring"):
        watch_ground = mission.ground if mission.ground is not None else ground
        watch_safety(station, run, *current_reports(ids, together, now), watch_ground)
        watch_formation(station, run, reporting, together)
    with phases.phase("prediction"):
        recent = list(itertools.islice(reversed(run.tick_latency_s), RECENT_TICKS))
        work = statistics.median(recent) if recent else 0.0
        states, active, lags = planning_states(located, work)
        account_lag(station, run, [lags[i] for i in active if i in lags])
    if leader_id not in states:
        return False
    with phases.phase("monitoring"):
        # what the vehicles report, not where they are predicted to be when commands act:
        # the target is reached, and distances kept, by the reported positions
        reported = {v.system_id: pos for v, pos in located}
        at = {vid: k for k, vid in enumerate(ids)}
        watched = sorted(active)
        positions = together[[at[i] for i in watched]].reshape(-1, 3)
        obstacles = obstacles_from_mission(mission).at(run.mission_time_s)
        of_now = together[[at[i] for i in watched if now[at[i]]]].reshape(-1, 3)
        run.min_separation_m = min_of(run.min_separation_m, separations(of_now))
        nearest = nearest_keep_outs(positions, obstacles, run.zones)
        run.nearest_keep_out = dict(zip(watched, nearest, strict=True))
        clear = [d for _, d in nearest if d is not None]
        run.min_clearance_m = min_of(run.min_clearance_m, min(clear) if clear else None)

        reached = leader_flown(station, run, np.array(reported[leader_id]))
    if reached:
        end(station, run, RunState.COMPLETED, "leader reached the target", states)
        return True

    if run.mission_time_s > mission.planner.max_time:
        end(station, run, RunState.FAILED, "planner.max_time passed before the target")
        return True

    with phases.phase("prediction"):
        airframes = {v.system_id: Airframe.from_telemetry(v.telemetry) for v, _ in located}
    with phases.phase("confirmation"):
        leader_not_responding = check_obedience(station, run, located, states, airframes)
    if leader_not_responding:  # the next tick plans for the new leader, if there is one
        if hand_over(station, run, "not_responding"):
            return False
        end(station, run, RunState.FAILED, "leader not responding")
        return True
    if run.mission.leader.id in run.taken_over:  # another GCS flies it: not ours to lead
        if hand_over(station, run, "taken_over"):
            return False
        end(station, run, RunState.FAILED, "leader taken over by another ground station")
        return True
    uncontrolled = (run.obedience.not_responding | run.taken_over) & set(states)
    active -= uncontrolled  # not planned for, not commanded: avoided as traffic
    if uncontrolled:
        traffic = obedience.as_obstacles(states, uncontrolled, traffic_radius_m(mission))
        obstacles = obedience.with_obstacles(obstacles, traffic)
    await plan_and_command(station, run, airframes, states, active, obstacles, ground)
    return False


def leader_flown(station: Station, run: Run, leader_pos: FloatArray) -> bool:
    """Whether the leader has reached the target, along every position it reported since the
    last tick (``Station.path_since``) to ``leader_pos``, its latest; the route's legs it
    flew on the way are followed (``follow_route``)."""
    path, run.leader_fix_ms = station.path_since(
        run.mission, run.mission.leader.id, run.leader_fix_ms
    )
    reached = False
    for position in [*path[:-1], leader_pos]:
        previous, run.leader_pos = run.leader_pos, position
        follow_route(station, run, previous, position)
        leg = run.legs[run.leg]  # the target's leg: reached within the target accuracy
        reached = reached or (leg.final and leg_flown(leg, previous, position))
    return reached


def follow_route(
    station: Station, run: Run, previous: FloatArray | None, leader_pos: FloatArray
) -> None:
    """On to the route's next leg once the leader, as reported, has flown this one
    (``route.leg_flown``; a leg that ends in a loiter, once its circles are flown:
    ``route.Loitering``): a ``waypoint_reached`` event with the waypoint's index, and
    ``loiter_began`` when the leader comes onto a loiter's circle."""
    leg = run.legs[run.leg]
    if leg.final:
        return
    if leg.loiter is not None:
        was = run.loitering or Loitering(leader_pos if previous is None else previous)
        run.loitering = was.on(leg, leader_pos[None], run.mission_time_s)
        if was.began_s is None and run.loitering.began_s is not None:
            station.event(
                run,
                "loiter_began",
                run.mission.leader.id,
                waypoint=leg.index,
                radius_m=round(leg.loiter_radius_m, 1),
            )
        if not run.loitering.flown(leg.loiter, run.mission_time_s):
            return
    elif not leg_flown(leg, previous, leader_pos):
        return
    run.leg += 1
    run.loitering = None
    run.waypoint_times_s.append(round(run.mission_time_s, 3))
    distance_m = round(float(np.linalg.norm(leader_pos - leg.end_m)), 1)
    station.event(
        run,
        "waypoint_reached",
        run.mission.leader.id,
        waypoint=leg.index,
        legs=len(run.legs),
        distance_m=distance_m,
    )


def watch_formation(station: Station, run: Run, reporting: Located, together: FloatArray) -> None:
    """The flown formation this tick (``run.formation``): each wingman's slot error from the
    positions reported on one instant (``together``, [N,3] in ``reporting``'s order) and the
    leader's reported velocity; ``formation_formed`` / ``formation_broken`` events with the
    wingman farthest from its slot.  Every wingman not lost counts: one not heard yet keeps
    the formation from forming."""
    mission = run.mission
    at = {v.system_id: k for k, (v, _) in enumerate(reporting)}
    errors: dict[int, float] = {}
    leader_k = at.get(mission.leader.id)
    if leader_k is not None:
        t = reporting[leader_k][0].telemetry
        if t.vn_m_s is not None and t.ve_m_s is not None and t.vd_m_s is not None:
            wingmen = {
                w.id: (together[at[w.id]].tolist(), w.slot)
                for w in mission.wingmen
                if w.id in at and w.slot is not None
            }
            velocity = velocity_ned_to_enu(t.vn_m_s, t.ve_m_s, t.vd_m_s)
            errors = slot_errors_m(together[leader_k].tolist(), velocity, wingmen)
    counted = [w.id for w in mission.wingmen if w.id not in run.lost_ids]
    unmeasured = sum(1 for vid in counted if vid not in at)
    for change in run.formation.update(run.mission_time_s, errors, unmeasured):
        station.event(
            run,
            change.kind,
            None,
            worst_wingman_id=change.worst_wingman_id,
            worst_error_m=None if change.worst_error_m is None else round(change.worst_error_m, 1),
            since_s=round(change.since_s, 2),
        )


async def plan_and_command(
    station: Station,
    run: Run,
    airframes: dict[int, Airframe],
    states: dict[int, VehicleState],
    active: set[int],
    obstacles: Obstacles,
    ground: float | None,
) -> None:
    """The tick's plan (``tick_plan.plan`` from the speeds the last plan reached,
    ``speed_reference``; events for what changed) sent to the vehicles it commands, every
    command through the run-time assurance; ``airframes`` of the located vehicles."""
    mission = run.mission
    settings = station.settings
    lim = mission.limits
    phases = run.phases
    tick_hz, positions_hz = station.rates_hz(mission)
    telemetry_interval_s = 1.0 / positions_hz
    lagging_s = telemetry_interval_s + run.fleet_lag.total_s  # what the margins must cover
    with phases.phase("planning"):
        leader = states.get(mission.leader.id)
        if leader is not None:  # a waypoint inside the formation's turn: a turn point first
            was = run.legs[run.leg]
            position = np.array(leader.pos_m, dtype=float)
            leg = onto_target(was, position, leader.yaw_rad, leader.speed_m_s)
            run.legs[run.leg] = leg
            if leg.turn_point_m is not None and was.turn_point_m is None:
                station.event(
                    run,
                    "turn_point",
                    mission.leader.id,
                    waypoint=leg.index,
                    turn_point_m=[round(float(c), 1) for c in leg.turn_point_m],
                    ahead_m=round(float(np.linalg.norm(leg.turn_point_m[:2] - position[:2])), 1),
                )
        # planned from the speeds the last plan had reached by now, not the measured ones
        follows = speed_reference.follows_speed_plan(lim.accel, lim.decel)
        reference = run.speed_plan if follows else None
        planning = speed_reference.reference_states(
            states, reference, run.mission_time_s, leader_id=mission.leader.id
        )
        g, ordered = tick_plan.plan(
            mission,
            planning,
            active,
            obstacles,
            ground,
            airframes,
            tick_plan.Tuning.of(settings),
            lagging_s,
            run.last,
            run.legs[run.leg],
        )
        held = follows and speed_reference.formation_holds(
            g, lim.target_accuracy, run.formation_held
        )
        run.formation_held = held
        if held:  # the leader keeps its speed (``speed_reference.leader_held``)
            share = LEADER_SPEED_CHANGE_SHARE
            g = speed_reference.leader_held(
                g, lim.v_max, lim.v_min, lim.decel * share, lim.accel * share
            )
        run.speed_plan = speed_reference.SpeedPlan.of(g, run.mission_time_s)
        for kind, vehicle_id in changes(run, g):  # what changed since the last tick
            station.event(run, kind, vehicle_id)
        run.last = g
    with phases.phase("assurance"):
        keep = assurance.KeepOut(
            obstacles,
            mission.ground if mission.ground is not None else ground,
            lim.safe_distance_obstacle,
            lim.safe_distance_uav,
            run.zones,
        )
        starvation_s = settings.starvation_allowance_s * station.fleet.clock_rate()
        hold_s = lag.hold_s(
            run.tick_gaps_s,
            1.0 / tick_hz,
            telemetry_interval_s,
            run.fleet_lag,
            starvation_s,
        )
    with phases.phase("commanding"):
        verdicts = await commanding.command_fleet(
            station.fleet,
            g,
            active,
            states,
            ordered,
            run.orders,
            keep,
            hold_s,
            run.commanded_speed,
            station.events_of(run),
            run.escaping,
            run.mission_time_s,
            run.climb_trims,
            phases=phases,
            speed_sent_s=run.speed_sent_s,
            speed_ack_wait_s=commanding.SPEED_ACK_VEHICLE_S / station.fleet.clock_rate(),
        )
    with phases.phase("confirmation"):
        for vid, v in verdicts.items():
            sent = run.sent_courses.setdefault(vid, deque(maxlen=SENT_COURSES_KEPT))
            sent.append((run.mission_time_s, v.command.course_rad))


def sample(station: Station, run: Run) -> None:
    """The run's vehicles' telemetry now, stored (the run's track)."""
    rows = []
    for vehicle, pos in station.located(run):
        t = vehicle.telemetry
        if t.lat_deg is None or t.lon_deg is None or t.alt_amsl_m is None:
            continue
        speed = t.groundspeed_m_s if t.groundspeed_m_s is not None else float("nan")
        rows.append(
            (run.mission_time_s, vehicle.system_id, t.lat_deg, t.lon_deg, t.alt_amsl_m, *pos, speed)
        )
    if rows:
        station.store.add_telemetry(run.record.id, rows)

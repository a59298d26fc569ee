"""The safety monitor (``guidance.safety_monitor``) on a run's reported positions: every
tick while it flies, and for ``WATCH_AFTER_END_S`` of vehicle time after it ends."""

from __future__ import annotations

import asyncio
import contextlib
import time

import numpy as np

from gcs_ppf.geodesy import velocity_ned_to_enu
from gcs_ppf.guidance.online import home_ground
from gcs_ppf.guidance.safety_monitor import aligned, current
from gcs_ppf.planning.scene import BoolArray, FloatArray, obstacles_from_mission
from gcs_ppf.service.fleet import Vehicle
from gcs_ppf.service.run import Run, RunState, summary
from gcs_ppf.service.station import Station

WATCH_AFTER_END_S = 60.0  # vehicle seconds the safety monitor goes on after a run ends

Located = list[tuple[Vehicle, tuple[float, float, float]]]
"""Vehicles that have reported a position, with it in the ICS."""


def watch_safety(
    station: Station,
    run: Run,
    ids: list[int],
    positions: FloatArray,
    ground_z_m: float | None,
    after_end_s: float = 0.0,
) -> None:
    """The safety monitor on the positions [N,3] the vehicles ``ids`` report, on one instant
    (``reported_together``; not planned): a ``safety_violation`` event for each keep-out
    entered."""
    if not ids:
        return
    lim = run.mission.limits
    began = run.safety.watch(
        ids,
        positions,
        obstacles_from_mission(run.mission).at(run.mission_time_s + after_end_s),
        ground_z_m,
        lim.safe_distance_uav,
        lim.safe_distance_obstacle,
        run.zones,
    )
    late = {"after_end_s": round(after_end_s, 1)} if after_end_s else {}
    for v in began:
        station.event(
            run,
            "safety_violation",
            v.vehicle_id,
            keep_out=v.kind,
            other=v.other,
            depth_m=round(v.depth_m, 1),
            **late,
        )


def reported_together(located: Located) -> tuple[FloatArray, BoolArray]:
    """The reported positions [N,3] (ICS) on one instant: each carried along its velocity by
    how much older it is than the newest (its age since it arrived, on its own clock); and
    which of them are of that instant (``safety_monitor.current``: not a vehicle gone
    silent, carried at most ``MAX_ALIGN_S``)."""
    now = time.monotonic()
    positions = np.array([p for _, p in located], dtype=float).reshape(-1, 3)
    velocities = np.zeros_like(positions)
    ages = np.zeros(len(located))
    carried = np.zeros(len(located))  # ages, those without a velocity taken as they are
    for k, (v, _) in enumerate(located):
        t = v.telemetry
        if t.position_received_s is not None:
            ages[k] = v.clock.vehicle_seconds(max(0.0, now - t.position_received_s))
        if t.vn_m_s is None or t.ve_m_s is None or t.vd_m_s is None:
            continue  # no velocity: taken as it is
        velocities[k] = velocity_ned_to_enu(t.vn_m_s, t.ve_m_s, t.vd_m_s)
        carried[k] = ages[k]
    return aligned(positions, velocities, carried), current(ages)


def current_reports(
    ids: list[int], together: FloatArray, now: BoolArray
) -> tuple[list[int], FloatArray]:
    """The ids and positions [N,3] the safety monitor judges: of ``reported_together``'s
    (``together``, ``now``), the vehicles whose reports are of its instant."""
    return [i for i, c in zip(ids, now, strict=True) if c], together[now]


def ground(run: Run, located: Located) -> float | None:
    """The mission's ground, or the vehicles' home (``online.home_ground``)."""
    if run.mission.ground is not None:
        return run.mission.ground
    return home_ground(
        [
            (pos[2], v.telemetry.relative_alt_m)
            for v, pos in located
            if v.telemetry.relative_alt_m is not None
        ]
    )


def watch_once(station: Station, run: Run, located: Located, after_end_s: float) -> None:
    """The safety monitor on one sample taken outside the run's ticks (the holds flown while
    others take off, ``after_end_s`` 0; the holds and the watch after the end): a violation
    is a ``safety_violation`` event, and a completed run becomes ``completed_unsafe``."""
    before = run.safety.count
    ids = [v.system_id for v, _ in located]
    judged = current_reports(ids, *reported_together(located))
    watch_safety(station, run, *judged, ground(run, located), after_end_s)
    if run.safety.count > before and run.state == RunState.COMPLETED:
        run.state = RunState.COMPLETED_UNSAFE
        run.outcome = f"{run.outcome}; a safety violation after the end"
        station.store.update_run(
            run.record.id, run.state, outcome=run.outcome, summary=summary(run)
        )
        station.event(run, f"run_{run.state}", outcome=run.outcome)
        station.publish()


def superseded(station: Station, run: Run) -> bool:
    """Whether another run of the run's mission has started since."""
    return station.runs.get(run.mission_id) is not run


async def watch_after_end(station: Station, run: Run) -> None:
    """The safety monitor goes on for ``WATCH_AFTER_END_S`` of vehicle time after the
    run ended, while the vehicles fly to and around their holds (an observer saw a
    wingman enter a sphere 4.2 s after a run it ended plain ``completed``): a violation
    is a ``safety_violation`` event, and a completed run becomes ``completed_unsafe``.
    It stops when another run of the mission starts."""
    fleet = station.fleet
    start = run.ended_vehicle_s
    while start is not None:
        fleet.telemetry_event.clear()
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(1.0):
                await fleet.telemetry_event.wait()
        now = station.fleet_time_s()
        if now is None or now - start > WATCH_AFTER_END_S or superseded(station, run):
            return
        watch_once(
            station, run, [(v, p) for v, p in station.located(run) if not v.lost], now - start
        )

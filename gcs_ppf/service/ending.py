"""The end of a run: its final state and summary at once, then every vehicle still heard
flown to its holding circle under run-time assurance (``service.hold_flight``), the circles
handed to the autopilots and confirmed, and the safety watch after the end
(``service.watch``)."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math

from gcs_ppf.guidance import failsafe
from gcs_ppf.guidance.airframe import Airframe
from gcs_ppf.guidance.online import VehicleState
from gcs_ppf.service import (
    commanding,
    confirmation,
    hold_flight,
    launch,
    returning,
    vehicle_fences,
)
from gcs_ppf.service.fleet import planning_states
from gcs_ppf.service.run import FINISHED, Run, RunState, summary
from gcs_ppf.service.station import Station
from gcs_ppf.service.watch import watch_after_end

log = logging.getLogger("gcs_ppf.service.runs")

HANDOVER_ON_STOP_S = 2.0
"""How long the service's shutdown waits for the holds being flown to be handed over."""


def finish(station: Station, run: Run, state: RunState, outcome: str) -> None:
    """The run's final state, stored with its summary (once: a run already finished stays
    as it is); completed with a safety violation is ``completed_unsafe``."""
    if run.state in FINISHED:
        return
    if state == RunState.COMPLETED and run.safety.count:
        state = RunState.COMPLETED_UNSAFE
        outcome = f"{outcome}; {run.safety.count} safety violation(s)"
    run.state = state
    run.outcome = outcome
    station.store.update_run(
        run.record.id, state, ended=True, outcome=outcome, summary=summary(run)
    )
    station.event(run, f"run_{state}", outcome=outcome)
    station.publish()


def end(
    station: Station,
    run: Run,
    state: RunState,
    outcome: str,
    states: dict[int, VehicleState] | None = None,
) -> None:
    """The run ends now (its state, at once: a hold that takes long to confirm, or a
    dead vehicle's that never is, does not delay it); every vehicle still heard then
    holds clear of every obstacle, in the background: after completion (``states``
    given) stacked above the target, otherwise stacked above the highest vehicle."""
    finish(station, run, state, outcome)
    run.ended_vehicle_s = station.fleet_time_s()
    stacked = states is not None
    if states is None:
        states, _, _ = planning_states(list(station.located(run)))
    run.hold_task = station.spawn(hold(station, run, states, stacked))


def on_ground(station: Station, vehicle_id: int) -> bool:
    """The vehicle reports itself on the ground, not flying (``launch.on_ground``)."""
    vehicle = station.fleet.by_id.get(vehicle_id)
    return vehicle is not None and launch.on_ground(vehicle.telemetry)


async def hold(station: Station, run: Run, states: dict[int, VehicleState], stacked: bool) -> None:
    """Every vehicle still heard and flying (one on the ground, after a start that failed,
    is left alone: ``holds_not_on_ground``; a hold's course commands a vehicle standing
    still cannot turn at all) flown to its holding circle and round it by the service,
    under run-time assurance (``fly``), then the circles handed to the autopilots, every
    command confirmed (``confirmation.confirm_all``), then (a completion whose mission ends in
    RTL) each sent home (``returning.return_home``), then the safety watch for the rest of
    its time after the end."""
    heard = {i for i, v in station.fleet.by_id.items() if not v.lost}
    heard -= run.taken_over  # another ground station flies them: not ours to hold
    ids = {v.id for v in run.mission.vehicles}
    grounded = sorted(i for i in heard if i in ids and on_ground(station, i))
    if grounded:  # a failed start: those that never took off are left alone, not commanded
        station.event(run, "holds_not_on_ground", None, vehicles=grounded)
        heard -= set(grounded)
    plan = _plan(station, run, states, stacked, heard)
    await fly(station, run, plan, launching=False)
    taken = hold_flight.taken_over(station, run)
    mine = [o for o in plan.orders if o.vehicle_id not in taken]
    await _confirm(station, run, mine)
    station.event(run, "holds_loitering", None, vehicles=sorted({o.vehicle_id for o in mine}))
    if stacked and run.mission.at_end == "rtl":  # completed: home from the holds
        holding_ids = {o.vehicle_id for o in mine}
        circles = {vid: c for vid, c in plan.circles.items() if vid in holding_ids}
        await returning.return_home(station, run, circles)
    if run.fences_before:  # the vehicles' own fences back, beside the watch
        station.spawn(vehicle_fences.take_down(station, run))
    await watch_after_end(station, run)


def _plan(
    station: Station,
    run: Run,
    states: dict[int, VehicleState],
    stacked: bool,
    heard: set[int],
    floor_z_m: float = -math.inf,
) -> commanding.HoldPlan:
    """``commanding.hold_plan`` for the run's vehicles as the fleet reports them, the stack
    from ``floor_z_m`` up; after a completion whose mission ends in RTL, over every
    keep-out (``failsafe.return_floor_m``)."""
    airframes = {
        vid: Airframe.from_telemetry(v.telemetry) for vid, v in station.fleet.by_id.items()
    }
    floor = floor_z_m
    if stacked and run.mission.at_end == "rtl":  # levels to fly home at
        homes = returning.home_heights(station, run)
        if homes:
            floor = max(floor, failsafe.return_floor_m(run.mission, homes, run.mission_time_s))
    return commanding.hold_plan(
        run.orders,
        states,
        airframes,
        run.mission_time_s,
        stacked,
        station.events_of(run),
        heard,
        floor,
    )


async def _confirm(station: Station, run: Run, orders: list[confirmation.Order]) -> None:
    """``orders`` sent until confirmed (``commanding.hold_retry``)."""
    retry = commanding.hold_retry(station.fleet.clock_rate())
    await confirmation.confirm_all(station.fleet, orders, station.events_of(run), retry)


async def fly(station: Station, run: Run, plan: commanding.HoldPlan, launching: bool) -> bool:
    """``plan``'s circles flown by the service (``hold_flight.fly_holds``); True when that
    ended as it should.  If the service stops meanwhile (it waits ``HANDOVER_ON_STOP_S``
    for this) the circles are sent once, unconfirmed, and the cancellation goes on; if
    flying them fails, False (``holds_flight_failed``): a vehicle is never left on the last
    course it was sent."""
    try:
        await hold_flight.fly_holds(station, run, plan.circles, launching=launching)
    except asyncio.CancelledError:
        await send_once(station, run, plan.orders)
        raise
    except Exception:  # the holds must still be handed over
        log.exception("mission %d: flying the holds failed; handing them over", run.mission_id)
        station.event(run, "holds_flight_failed", None)
        return False
    return True


async def send_once(station: Station, run: Run, orders: list[confirmation.Order]) -> None:
    """Each of ``orders`` sent once, unconfirmed, to the vehicles no later run commands
    (the service is stopping: there is no time to confirm them)."""
    taken = hold_flight.taken_over(station, run)
    for o in orders:
        if o.vehicle_id not in taken:
            with contextlib.suppress(Exception):
                await station.fleet.send(o.vehicle_id, o.make())


async def hold_during_launch(
    station: Station, run: Run, states: dict[int, VehicleState], floor_z_m: float = -math.inf
) -> None:
    """While some vehicles take off, the ones already flying (``states``) hold on circles
    (``commanding.hold_plan``: clear of every obstacle, stacked above the highest and from
    ``floor_z_m`` up), flown
    by the service under run-time assurance with the vehicles taking off as traffic
    (``fly``, launching) until the launch is done and this is cancelled; then the circles
    are sent once (the run commands the vehicles at its first tick).  Sent to the
    autopilots and only confirmed, as before, wingmen 3 and 4 of Table 3 came to 43.0 m of
    each other on their way to them while wingman 2 took off (×5, 300 ms, 20 % loss, a CPU
    burner per core; 1 of 20 runs).  If flying them fails, the circles are handed over and
    confirmed at once."""
    plan = _plan(station, run, states, False, set(states), floor_z_m)
    if not await fly(station, run, plan, launching=True):
        await _confirm(station, run, plan.orders)

"""The ground-station service: missions and their runs (the imperative shell).

It owns the clocks and the tasks.  The vehicles and their links are ``service.fleet``
(each vehicle's state carried on by its measured lag, ``guidance.lag``); launching them is
``service.launch``, with commands confirmed by ``service.confirmation``; a run's record and
status are ``service.run``; each tick plans with ``guidance.tick_plan`` (pure: the
envelope, PPF guidance, the separation guard) and commands with ``service.commanding``
(every command through the run-time assurance, ``guidance.assurance``; the holds that end a
run); the safety monitor and obedience are ``guidance.safety_monitor`` and
``guidance.obedience``; storage is ``service.store``.  Routes in ``api/`` call the public
methods here and of ``fleet``, nothing else.  (Modules under ``gcs_ppf``.)
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import math
import statistics
import time
from collections.abc import AsyncIterator, Iterator
from typing import Any

import numpy as np

from gcs_ppf.guidance import assurance, lag, obedience, tick_plan
from gcs_ppf.guidance.airframe import Airframe
from gcs_ppf.guidance.online import (
    Guidance,
    VehicleState,
    clearance,
    home_ground,
    separations,
    warm_up,
)
from gcs_ppf.guidance.tick_plan import passes_within, traffic_radius_m
from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.mavlink.enums import MAV_CMD_DO_REPOSITION, MAV_CMD_GUIDED_CHANGE_HEADING
from gcs_ppf.mission import Mission, Obstacle
from gcs_ppf.planning.scene import obstacles_from_mission
from gcs_ppf.service import commanding, confirmation, launch
from gcs_ppf.service.errors import Conflict, NotFound, ServiceError
from gcs_ppf.service.fleet import Fleet, Vehicle, planning_states
from gcs_ppf.service.run import (
    FINISHED,
    Run,
    RunState,
    changes,
    latency_ms,
    min_of,
)
from gcs_ppf.service.run import status as run_status
from gcs_ppf.service.settings import Settings
from gcs_ppf.service.store import Store, StoredMission, StoredRun

__all__ = ["FINISHED", "FormationService", "RunState"]

log = logging.getLogger("gcs_ppf.service.runs")

COURSE_COMMAND = {  # the command each guidance mode flies by
    "course": MAV_CMD_GUIDED_CHANGE_HEADING,
    "point": MAV_CMD_DO_REPOSITION,
}
RECENT_TICKS = 20  # the tick's own work is the median of this many latest
WATCH_AFTER_END_S = 60.0  # vehicle seconds the safety monitor goes on after a run ends


class FormationService:
    """Links, vehicles, missions and runs; see the module docstring."""

    def __init__(self, settings: Settings, store: Store) -> None:
        self.settings = settings
        self.store = store
        self.fleet = Fleet(settings, self._spawn)
        self._runs: dict[int, Run] = {}  # mission id → its current or last run
        self._subscribers: set[asyncio.Queue[dict[str, Any]]] = set()
        self._tasks: asyncio.TaskGroup | None = None
        for stale in store.interrupted_runs():  # a previous process stopped mid-flight
            store.update_run(stale.id, RunState.FAILED, ended=True, outcome="service restarted")

    # Lifetime ----------------------------------------------------------------------------
    @contextlib.asynccontextmanager
    async def running(self) -> AsyncIterator[FormationService]:
        """Run the background tasks (links, heartbeats, watchdog) for the body's duration;
        the planner's kernel is loaded first, before any telemetry can queue behind it."""
        warm_up(self.settings.planner_dt_s)
        async with asyncio.TaskGroup() as tg:
            self._tasks = tg
            background = [
                tg.create_task(self.fleet.heartbeats()),
                tg.create_task(self.fleet.watchdog()),
            ]
            for url in self.settings.links:
                await self.fleet.add_link(url)
            try:
                yield self
            finally:
                for run in self._runs.values():
                    if run.task is not None and not run.task.done():
                        run.abort.set()
                        run.task.cancel()
                    if run.hold_task is not None and not run.hold_task.done():
                        run.hold_task.cancel()  # the holds and the watch after the end
                self.fleet.close()
                for task in background:
                    task.cancel()
                self._tasks = None

    def _spawn(self, coro: Any) -> asyncio.Task[Any]:
        if self._tasks is None:
            raise ServiceError("the service is not running")
        return self._tasks.create_task(coro)

    # Missions ----------------------------------------------------------------------------
    def create_mission(self, mission: Mission) -> StoredMission:
        return self.store.add_mission(mission)

    def missions(self) -> list[StoredMission]:
        return self.store.missions()

    def mission(self, mission_id: int) -> StoredMission:
        try:
            return self.store.mission(mission_id)
        except KeyError:
            raise NotFound(f"mission {mission_id} does not exist") from None

    def replace_obstacles(self, mission_id: int, obstacles: list[Obstacle]) -> StoredMission:
        """New obstacle set; a running mission uses it from its next tick on."""
        stored = self.mission(mission_id)
        doc = stored.mission.model_dump()
        doc["obstacles"] = [o.model_dump() for o in obstacles]
        try:
            mission = Mission.model_validate(doc)
        except ValueError as exc:
            raise ServiceError(str(exc)) from None
        run = self._runs.get(mission_id)
        if run is not None and run.state not in FINISHED:
            run.mission = mission
        return self.store.replace_mission(mission_id, mission)

    # Runs --------------------------------------------------------------------------------
    def _active_run(self) -> Run | None:
        return next((r for r in self._runs.values() if r.state not in FINISHED), None)

    async def start(self, mission_id: int) -> dict[str, Any]:
        stored = self.mission(mission_id)
        active = self._active_run()
        if active is not None:
            raise Conflict(
                f"mission {active.mission_id} is {active.state}; abort it first",
                {"mission_id": active.mission_id, "state": active.state},
            )
        ids = [v.id for v in stored.mission.vehicles]
        missing = [i for i in ids if i not in self.fleet.by_id or self.fleet.by_id[i].lost]
        if missing:
            raise Conflict(f"vehicles not connected: {missing}", {"missing_ids": missing})
        record = self.store.add_run(mission_id, RunState.STARTING)
        orders = commanding.Orders(
            stored.mission, self.settings.guidance, self.settings.lookahead_s
        )
        run = Run(record=record, mission_id=mission_id, mission=stored.mission, orders=orders)
        self._runs[mission_id] = run
        self._event(run, "run_started")
        run.task = self._spawn(self._fly(run))
        return self.status(mission_id)

    async def abort(self, mission_id: int) -> dict[str, Any]:
        self.mission(mission_id)
        run = self._runs.get(mission_id)
        if run is None or run.state in FINISHED:
            raise Conflict(
                f"mission {mission_id} is not running",
                {"state": run.state if run else RunState.PENDING},
            )
        run.abort.set()
        self._end(run, RunState.ABORTED, "aborted by the operator")
        if run.task is not None:
            run.task.cancel()
        return self.status(mission_id)

    def status(self, mission_id: int) -> dict[str, Any]:
        self.mission(mission_id)
        run = self._runs.get(mission_id)
        if run is None:
            past = self.store.runs(mission_id)
            if not past:
                return {"mission_id": mission_id, "state": RunState.PENDING, "run_id": None}
            last = past[-1]
            return {
                "mission_id": mission_id,
                "state": last.state,
                "run_id": last.id,
                "outcome": last.outcome,
                "summary": last.summary,
            }
        return run_status(run)

    def events(self, mission_id: int) -> list[dict[str, Any]]:
        self.mission(mission_id)
        out = []
        for r in self.store.runs(mission_id):
            for e in self.store.events(r.id):
                out.append(
                    {
                        "run_id": e.run_id,
                        "mission_time_s": e.mission_time_s,
                        "wall_s": e.wall_s,
                        "kind": e.kind,
                        "vehicle_id": e.vehicle_id,
                        "detail": e.detail,
                    }
                )
        return out

    def runs(self) -> list[StoredRun]:
        return self.store.runs()

    # Live stream -------------------------------------------------------------------------
    def subscribe(self) -> asyncio.Queue[dict[str, Any]]:
        q: asyncio.Queue[dict[str, Any]] = asyncio.Queue(maxsize=100)
        self._subscribers.add(q)
        return q

    def unsubscribe(self, q: asyncio.Queue[dict[str, Any]]) -> None:
        self._subscribers.discard(q)

    def snapshot(self) -> dict[str, Any]:
        run = self._active_run() or (list(self._runs.values())[-1] if self._runs else None)
        return {
            "vehicles": self.fleet.vehicles(),
            "mission": self.status(run.mission_id) if run else None,
            "target": list(run.mission.target) if run else None,
            "obstacles": [o.model_dump() for o in run.mission.obstacles] if run else [],
        }

    def _publish(self) -> None:
        if not self._subscribers:
            return
        snap = self.snapshot()
        for q in self._subscribers:
            with contextlib.suppress(asyncio.QueueFull):
                q.put_nowait(snap)

    # Flying a run --------------------------------------------------------------------------
    def _event(self, run: Run, kind: str, vehicle_id: int | None = None, **detail: Any) -> None:
        self.store.add_event(
            run.record.id,
            kind,
            mission_time_s=round(run.mission_time_s, 3),
            vehicle_id=vehicle_id,
            detail=detail or None,
        )
        log.info(
            "mission %d t=%.1f s: %s%s %s",
            run.mission_id,
            run.mission_time_s,
            kind,
            f" (vehicle {vehicle_id})" if vehicle_id else "",
            detail or "",
        )

    @staticmethod
    def _summary(run: Run) -> dict[str, Any]:
        return {
            "mission_time_s": run.mission_time_s,
            "min_separation_m": run.min_separation_m,
            "min_obstacle_clearance_m": run.min_clearance_m,
            "safety_violations": run.safety.count,
            "deepest_violation_m": run.safety.deepest_m,
            "tick_latency_ms": latency_ms(run),
            "worst_lag_s": round(run.lag_budget.worst_s, 3),
        }

    def _finish(self, run: Run, state: RunState, outcome: str) -> None:
        if run.state in FINISHED:
            return
        if state == RunState.COMPLETED and run.safety.count:
            state = RunState.COMPLETED_UNSAFE
            outcome = f"{outcome}; {run.safety.count} safety violation(s)"
        run.state = state
        run.outcome = outcome
        self.store.update_run(
            run.record.id, state, ended=True, outcome=outcome, summary=self._summary(run)
        )
        self._event(run, f"run_{state}", outcome=outcome)
        self._publish()

    def _end(
        self, run: Run, state: RunState, outcome: str,
        states: dict[int, VehicleState] | None = None,
    ) -> None:  # fmt: skip
        """The run ends now (its state, at once: a hold that takes long to confirm, or a
        dead vehicle's that never is, does not delay it); every vehicle still heard then
        holds clear of every obstacle, in the background: after completion (``states``
        given) stacked above the target, otherwise stacked above the highest vehicle."""
        self._finish(run, state, outcome)
        run.ended_vehicle_s = self._fleet_time_s()
        stacked = states is not None
        if states is None:
            states, _, _ = planning_states(list(self._located(run)))
        run.hold_task = self._spawn(self._hold(run, states, stacked))

    async def _hold(self, run: Run, states: dict[int, VehicleState], stacked: bool) -> None:
        """Each vehicle to its holding circle (``commanding.hold_orders``), every command
        confirmed by its ACK and sent again while unanswered: a hold lost on a lossy link
        left a vehicle flying its last course into an obstacle."""
        airframes = {
            vid: Airframe.from_telemetry(v.telemetry) for vid, v in self.fleet.by_id.items()
        }

        def event(kind: str, vehicle_id: int | None = None, **detail: Any) -> None:
            self._event(run, kind, vehicle_id, **detail)

        heard = {i for i, v in self.fleet.by_id.items() if not v.lost}
        orders = commanding.hold_orders(
            run.orders, states, airframes, run.mission_time_s, stacked, event, heard
        )
        rate = max([v.clock.rate for v in self.fleet.by_id.values()] or [1.0])
        await confirmation.confirm_all(self.fleet, orders, event, commanding.hold_retry(rate))
        await self._watch_after_end(run)

    def _fleet_time_s(self) -> float | None:
        """The latest vehicle time any vehicle still heard has reported (seconds)."""
        times = [v.telemetry.time_boot_ms for v in self.fleet.by_id.values()
                 if not v.lost and v.telemetry.time_boot_ms is not None]  # fmt: skip
        return max(times) / 1000.0 if times else None

    async def _watch_after_end(self, run: Run) -> None:
        """The safety monitor goes on for ``WATCH_AFTER_END_S`` of vehicle time after the
        run ended, while the vehicles fly to and around their holds (an observer saw a
        wingman enter a sphere 4.2 s after a run it ended plain ``completed``): a violation
        is a ``safety_violation`` event, and a completed run becomes ``completed_unsafe``.
        It stops when another run of the mission starts."""
        start = run.ended_vehicle_s
        while start is not None:
            self.fleet.telemetry_event.clear()
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout(1.0):
                    await self.fleet.telemetry_event.wait()
            now = self._fleet_time_s()
            if (
                now is None
                or now - start > WATCH_AFTER_END_S
                or self._runs.get(run.mission_id) is not run
            ):
                return
            located = [(v, p) for v, p in self._located(run) if not v.lost]
            before = run.safety.count
            self._watch_safety(run, located, self._ground(run, located), now - start)
            if run.safety.count > before and run.state == RunState.COMPLETED:
                run.state = RunState.COMPLETED_UNSAFE
                run.outcome = f"{run.outcome}; a safety violation after the end"
                self.store.update_run(
                    run.record.id, run.state, outcome=run.outcome, summary=self._summary(run)
                )
                self._event(run, f"run_{run.state}", outcome=run.outcome)
                self._publish()

    @staticmethod
    def _ground(
        run: Run, located: list[tuple[Vehicle, tuple[float, float, float]]]
    ) -> float | None:
        """The mission's ground, or the vehicles' home (``online.home_ground``)."""
        if run.mission.ground is not None:
            return run.mission.ground
        return home_ground([(pos[2], v.telemetry.relative_alt_m) for v, pos in located
                            if v.telemetry.relative_alt_m is not None])  # fmt: skip

    def _vehicle_time_s(self, run: Run) -> float | None:
        leader = self.fleet.by_id.get(run.mission.leader.id)
        if leader is None or leader.telemetry.time_boot_ms is None:
            return None
        return leader.telemetry.time_boot_ms / 1000.0

    async def _launch(self, run: Run) -> None:
        """Every vehicle flying in GUIDED (``gcs_ppf.service.launch``: those on the ground taken off
        in TAKEOFF mode to their TKOFF_ALT first, every arm and mode change confirmed);
        parameters not answered yet are asked for again first."""
        ids = [v.id for v in run.mission.vehicles]
        for vid in ids:
            await self.fleet.request_airframe_params(vid, missing_only=True)

        def event(kind: str, vehicle_id: int | None = None, **detail: Any) -> None:
            self._event(run, kind, vehicle_id, **detail)

        await launch.launch(
            self.fleet, ids, self.settings.takeoff_alt_m, event,
            takeoff_dist_m=self.settings.takeoff_dist_m,
        )  # fmt: skip

    async def _fly(self, run: Run) -> None:
        try:
            await self._launch(run)
            run.state = RunState.RUNNING
            self.store.update_run(run.record.id, RunState.RUNNING)
            self._event(run, "run_running")
            await self._tick_loop(run)
        except asyncio.CancelledError:
            raise
        except Exception as exc:  # a run must never take the service down
            log.exception("mission %d failed", run.mission_id)
            self._end(run, RunState.FAILED, f"error: {exc}")

    async def _tick_loop(self, run: Run) -> None:
        period = 1.0 / self.settings.tick_hz
        sample_period = 1.0 / self.settings.telemetry_sample_hz
        last_tick: float | None = None
        last_sample = -math.inf
        while not run.abort.is_set():
            self.fleet.telemetry_event.clear()
            try:
                async with asyncio.timeout(1.0):
                    await self.fleet.telemetry_event.wait()
            except TimeoutError:
                pass
            if await self._losses(run):  # not on the leader's clock: it may be the one lost
                return
            received = self.fleet.telemetry_received_s
            now_v = self._vehicle_time_s(run)
            if now_v is None:
                continue
            if run.start_vehicle_time_s is None:
                run.start_vehicle_time_s = now_v
            if last_tick is not None and now_v - last_tick < period * 0.999:
                continue
            if last_tick is not None:
                run.tick_gaps_s.append(now_v - last_tick)
            last_tick = now_v
            run.mission_time_s = now_v - run.start_vehicle_time_s
            done = await self._tick(run)
            run.tick_latency_s.append(time.perf_counter() - received)
            if run.mission_time_s - last_sample >= sample_period:
                last_sample = run.mission_time_s
                self._sample(run)
            self._publish()
            if done:
                return

    async def _losses(self, run: Run) -> bool:
        """Events for vehicles newly lost (the watchdog's verdict, in their own seconds);
        True when the leader is lost: the run has then failed, every vehicle loitering."""
        for v in run.mission.vehicles:
            vehicle = self.fleet.by_id.get(v.id)
            if vehicle is not None and vehicle.lost and v.id not in run.lost_ids:
                run.lost_ids.add(v.id)
                self._event(run, "vehicle_lost", v.id)
            elif vehicle is not None and not vehicle.lost and v.id in run.lost_ids:
                run.lost_ids.discard(v.id)  # heard again: planned for and watched again
                self._event(run, "vehicle_back", v.id)
        if run.mission.leader.id not in run.lost_ids:
            return False
        self._end(run, RunState.FAILED, "leader lost")
        return True

    def _watch_safety(
        self, run: Run, located: list[tuple[Vehicle, tuple[float, float, float]]],
        ground_z_m: float | None, after_end_s: float = 0.0,
    ) -> None:  # fmt: skip
        """The safety monitor on the positions the vehicles report (not carried on, not
        planned): a ``safety_violation`` event for each keep-out entered."""
        if not located:
            return
        lim = run.mission.limits
        began = run.safety.watch(
            [v.system_id for v, _ in located], np.array([p for _, p in located], dtype=float),
            obstacles_from_mission(run.mission).at(run.mission_time_s + after_end_s), ground_z_m,
            lim.safe_distance_uav, lim.safe_distance_obstacle,
        )  # fmt: skip
        late = {"after_end_s": round(after_end_s, 1)} if after_end_s else {}
        for v in began:
            self._event(run, "safety_violation", v.vehicle_id, keep_out=v.kind, other=v.other,
                        depth_m=round(v.depth_m, 1), **late)  # fmt: skip

    def _obedience(
        self, run: Run, located: list[tuple[Vehicle, tuple[float, float, float]]],
        states: dict[int, VehicleState],
    ) -> bool:  # fmt: skip
        """Which vehicles obey (GUIDED, the course command ACCEPTED, the course sent flown
        or turned to): events when one stops for ``NOT_RESPONDING_S`` of vehicle time or
        comes back; True if it is the leader."""
        command = COURSE_COMMAND[self.settings.guidance]
        reports = []
        for v, _ in located:
            t = v.telemetry
            ack = t.ack(command)
            guided = t.custom_mode == PlaneMode.GUIDED
            s = states.get(v.system_id)
            sent = run.sent_course.get(v.system_id)
            error = turn = None
            if s is not None and sent is not None:
                error = math.remainder(sent - s.yaw_rad, math.tau)
                turn = -t.course_rate_rad_s  # clockwise from north → ICS yaw rate
            reports.append(obedience.Report(
                v.system_id, guided, ack.result if ack else None, error, turn or 0.0
            ))  # fmt: skip
        flagged, cleared = run.obedience.update(run.mission_time_s, reports)
        by_id = {v.system_id: v.telemetry for v, _ in located}
        for vid in flagged:
            t = by_id[vid]
            ack = t.ack(command)
            self._event(run, "vehicle_not_responding", vid, mode=t.mode_name,
                        last_ack=ack.result if ack else None)  # fmt: skip
        for vid in cleared:
            self._event(run, "vehicle_responding", vid)
        return run.mission.leader.id in flagged

    def _account_lag(self, run: Run, lags: list[lag.Lag]) -> None:
        """The fleet's lag this tick, and an event when it crosses the budget."""
        run.fleet_lag = lag.worst(lags)
        change = run.lag_budget.update(run.fleet_lag.total_s)
        if change is not None:
            self._event(run, change, None, budget_s=run.lag_budget.budget_s,
                        **run.fleet_lag.as_dict())  # fmt: skip

    def _located(self, run: Run) -> Iterator[tuple[Vehicle, tuple[float, float, float]]]:
        """The run's vehicles that have reported a position, with it in the ICS."""
        for v in run.mission.vehicles:
            vehicle = self.fleet.by_id.get(v.id)
            pos = None if vehicle is None else Fleet.vehicle_enu(vehicle, run.mission)
            if vehicle is not None and pos is not None:
                yield vehicle, pos

    async def _tick(self, run: Run) -> bool:
        """One planning tick; True when the run has ended."""
        mission = run.mission
        leader_id = mission.leader.id

        located = list(self._located(run))  # one geodetic → ICS conversion per vehicle
        ground = home_ground(
            [(pos[2], v.telemetry.relative_alt_m) for v, pos in located
             if v.telemetry.relative_alt_m is not None]
        )  # fmt: skip
        reporting = [(v, p) for v, p in located if v.system_id not in run.lost_ids]
        self._watch_safety(run, reporting, mission.ground if mission.ground is not None else ground)
        recent = list(itertools.islice(reversed(run.tick_latency_s), RECENT_TICKS))
        work = statistics.median(recent) if recent else 0.0
        states, active, lags = planning_states(located, work)
        self._account_lag(run, [lags[i] for i in active if i in lags])
        if leader_id not in states:
            return False
        # what the vehicles report, not where they are predicted to be when commands act:
        # the target is reached, and distances kept, by the reported positions
        reported = {v.system_id: pos for v, pos in located}
        positions = np.array([reported[i] for i in sorted(active)], dtype=float)
        obstacles = obstacles_from_mission(mission).at(run.mission_time_s)
        run.min_separation_m = min_of(run.min_separation_m, separations(positions))
        run.min_clearance_m = min_of(run.min_clearance_m, clearance(positions, obstacles))

        leader_pos = np.array(reported[leader_id])
        previous, run.leader_pos = run.leader_pos, leader_pos
        if passes_within(
            previous, leader_pos, np.array(mission.target), mission.limits.target_accuracy
        ):
            self._end(run, RunState.COMPLETED, "leader reached the target", states)
            return True

        if run.mission_time_s > mission.planner.max_time:
            self._end(run, RunState.FAILED, "planner.max_time passed before the target")
            return True

        if self._obedience(run, located, states):
            self._end(run, RunState.FAILED, "leader not responding")
            return True
        uncontrolled = run.obedience.not_responding & set(states)
        active -= uncontrolled  # not planned for, not commanded: avoided as traffic
        if uncontrolled:
            traffic = obedience.as_obstacles(states, uncontrolled, traffic_radius_m(mission))
            obstacles = obedience.with_obstacles(obstacles, traffic)

        airframes = {v.system_id: Airframe.from_telemetry(v.telemetry) for v, _ in located}
        lim = mission.limits
        telemetry_interval_s = 1.0 / self.settings.stream_rate_hz
        lagging_s = telemetry_interval_s + run.fleet_lag.total_s  # what the margins must cover
        g, ordered = tick_plan.plan(
            mission, states, active, obstacles, ground, airframes,
            tick_plan.Tuning.of(self.settings), lagging_s, run.last,
        )  # fmt: skip
        self._note_changes(run, g)
        run.last = g
        keep = assurance.KeepOut(
            obstacles, mission.ground if mission.ground is not None else ground,
            lim.safe_distance_obstacle, lim.safe_distance_uav,
        )  # fmt: skip
        hold_s = lag.hold_s(
            run.tick_gaps_s, 1.0 / self.settings.tick_hz, telemetry_interval_s, run.fleet_lag
        )

        def event(kind: str, vehicle_id: int | None = None, **detail: Any) -> None:
            self._event(run, kind, vehicle_id, **detail)

        verdicts = await commanding.command_fleet(
            self.fleet, g, active, states, ordered, run.orders, keep, hold_s,
            run.commanded_speed, event,
        )  # fmt: skip
        run.sent_course.update({vid: v.command.course_rad for vid, v in verdicts.items()})
        return False

    def _note_changes(self, run: Run, g: Guidance) -> None:
        """Events for what changed since the last tick (``gcs_ppf.service.run.changes``)."""
        for kind, vehicle_id in changes(run, g):
            self._event(run, kind, vehicle_id)

    def _sample(self, run: Run) -> None:
        rows = []
        for vehicle, pos in self._located(run):
            t = vehicle.telemetry
            if t.lat_deg is None or t.lon_deg is None or t.alt_amsl_m is None:
                continue
            speed = t.groundspeed_m_s if t.groundspeed_m_s is not None else float("nan")
            rows.append(
                (run.mission_time_s, vehicle.system_id, t.lat_deg, t.lon_deg, t.alt_amsl_m,
                 *pos, speed)
            )  # fmt: skip
        if rows:
            self.store.add_telemetry(run.record.id, rows)

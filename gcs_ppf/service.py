"""The ground-station service: missions and their runs (the imperative shell).

It owns the clocks and the tasks; the vehicles and their links are ``gcs_ppf.fleet``,
launching them (takeoff, confirmed arm and mode changes) is ``gcs_ppf.launch``, planning is
``gcs_ppf.online`` (pure) within each airframe's envelope (``gcs_ppf.airframe``, from the
vehicles' ArduPlane parameters) with ``gcs_ppf.separation_guard``, what the commands carry
is ``gcs_ppf.slew``, the wire is ``gcs_ppf.links`` and ``gcs_ppf.mavlink``, storage is
``gcs_ppf.store``.  Routes in ``api/`` call the public methods here and of ``fleet``,
nothing else.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import statistics
import time
from collections import deque
from collections.abc import AsyncIterator, Iterator
from dataclasses import dataclass, field, replace
from enum import StrEnum
from functools import partial
from typing import Any

import numpy as np

from gcs_ppf import (
    assurance,
    commanding,
    confirmation,
    holding,
    lag,
    launch,
    obedience,
    safety_monitor,
    separation_guard,
    slew,
)
from gcs_ppf.airframe import Airframe, guard_tuning, tick_envelope
from gcs_ppf.errors import Conflict, NotFound, ServiceError
from gcs_ppf.fleet import Fleet, Vehicle
from gcs_ppf.geodesy import enu_to_geodetic
from gcs_ppf.mavlink import commands
from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.mission import Mission, Obstacle
from gcs_ppf.online import (
    Guidance,
    VehicleState,
    clearance,
    coordinated_turn_rate,
    guidance,
    home_ground,
    scene_now,
    separations,
    state_from_velocity,
    warm_up,
)
from gcs_ppf.scene import obstacles_from_mission
from gcs_ppf.settings import Settings
from gcs_ppf.store import Store, StoredMission, StoredRun

log = logging.getLogger("gcs_ppf.service")

LOITER_AHEAD_M = 800.0  # after the mission each vehicle circles a point this far ahead …
LOITER_STACK_M = 100.0  # … at its own height: vehicle k of the mission this much above
NOT_RESPONDING_S = 3.0  # vehicle seconds out of GUIDED or refusing the course: not responding
COURSE_COMMAND = {"course": 43002, "point": 192}  # the command each guidance mode flies by
HOLD_TURN_RADII = 1.5  # a holding circle is this many of the vehicle's tightest turns wide …
HOLD_MIN_RADIUS_M = 80.0  # … and at least ArduPlane's WP_LOITER_RAD
HOLD_RETRY = confirmation.Retry(attempts=10)  # a hold is sent until it is ACCEPTED …
HOLD_ACK_VEHICLE_S = 2.0  # … again when unanswered for this long (vehicle seconds)


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


FINISHED = {RunState.COMPLETED, RunState.COMPLETED_UNSAFE, RunState.ABORTED, RunState.FAILED}


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
    min_separation_m: float | None = None
    min_clearance_m: float | None = None
    formed: bool = False
    abort: asyncio.Event = field(default_factory=asyncio.Event)
    lost_ids: set[int] = field(default_factory=set)
    commanded_speed: dict[int, float] = field(default_factory=dict)
    leader_pos: Any = None  # ICS position at the last tick
    tick_latency_s: deque[float] = field(default_factory=lambda: deque(maxlen=10_000))
    task: asyncio.Task[None] | None = None
    safety: safety_monitor.Monitor = field(default_factory=safety_monitor.Monitor)
    obedience: obedience.Obedience = field(
        default_factory=lambda: obedience.Obedience(NOT_RESPONDING_S)
    )
    fleet_lag: lag.Lag = field(default_factory=lambda: lag.Lag(0.0, 0.0))
    """The fleet's lag at the last tick (``gcs_ppf.lag``), vehicle seconds."""
    lag_budget: lag.Budget = field(default_factory=lambda: lag.Budget(LAG_BUDGET_S))
    recent_work_s: deque[float] = field(default_factory=lambda: deque(maxlen=20))
    """Our seconds from telemetry to commands sent, of the last ticks."""


MAX_PREDICTION_S = 2.0
"""A state is not carried on further than this (vehicle seconds): a silent vehicle is the
watchdog's business, not dead reckoning's, and a lag beyond the budget is an event."""
LAG_BUDGET_S = 1.0
"""Telemetry age + command delay (vehicle seconds) beyond which a ``lag_over_budget`` event
is raised."""


def formation_tolerance(mission: Mission) -> float:
    """``separation_guard.formation_tolerance_m`` of the mission's slots."""
    slots = np.array([v.slot for v in mission.vehicles if v.slot is not None], dtype=float)
    return separation_guard.formation_tolerance_m(slots, mission.limits.safe_distance_uav)


def in_formation(g: Guidance, tolerance_m: float) -> list[bool]:
    """The leader, and each wingman within ``tolerance_m`` of its local target point."""
    return [i == 0 or (d is not None and d <= tolerance_m)
            for i, d in enumerate(g.local_target_distance_m)]  # fmt: skip


def traffic_radius_m(mission: Mission) -> float:
    """The radius of a sphere standing for an uncontrolled vehicle: its keep-out (radius +
    safe_distance_obstacle) is then the teammates' safe distance (at least the vehicle)."""
    lim = mission.limits
    return max(lim.safe_distance_uav - lim.safe_distance_obstacle, lim.collision_radius)


def passes_within(start: Any, end: Any, point: Any, radius: float) -> bool:
    """Whether the segment start → end (or the point ``end`` alone when ``start`` is None)
    comes within ``radius`` of ``point``: telemetry at 10 Hz can step over a 10 m sphere."""
    if start is None:
        return bool(np.linalg.norm(end - point) <= radius)
    seg = end - start
    length2 = float(seg @ seg)
    s = 0.0 if length2 == 0.0 else min(max(float((point - start) @ seg) / length2, 0.0), 1.0)
    return bool(np.linalg.norm(start + s * seg - point) <= radius)


def _min(a: float | None, b: float | None) -> float | None:
    if a is None:
        return b
    if b is None:
        return a
    return min(a, b)


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
        await self._loiter_all(run)
        self._finish(run, RunState.ABORTED, "aborted by the operator")
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
                        "lost": vid in run.lost_ids,
                    }
                )
        return {
            "mission_id": mission_id,
            "run_id": run.record.id,
            "state": run.state,
            "outcome": run.outcome,
            "mission_time_s": round(run.mission_time_s, 3),
            "formation_formed": run.formed,
            "min_separation_m": run.min_separation_m,
            "min_obstacle_clearance_m": run.min_clearance_m,
            "safety_violations": run.safety.count,
            "tick_latency_ms": self._latency(run),
            "lag_s": {
                **run.fleet_lag.as_dict(),
                "budget_s": run.lag_budget.budget_s,
                "worst_s": round(run.lag_budget.worst_s, 3),
                "over_budget": run.lag_budget.over,
            },
            "vehicles": per_vehicle,
        }

    def events(self, mission_id: int) -> list[dict[str, Any]]:
        self.mission(mission_id)
        out = []
        for r in self.store.runs(mission_id):
            for e in self.store.events(r.id):
                out.append(
                    {
                        "run_id": e.run_id,
                        "mission_time_s": e.mission_time_s,
                        "kind": e.kind,
                        "vehicle_id": e.vehicle_id,
                        "detail": e.detail,
                    }
                )
        return out

    def runs(self) -> list[StoredRun]:
        return self.store.runs()

    @staticmethod
    def _latency(run: Run) -> dict[str, float] | None:
        """Tick latency (telemetry received → commands sent) percentiles, ms."""
        if not run.tick_latency_s:
            return None
        ms = np.array(run.tick_latency_s) * 1e3
        return {
            "p50": round(float(np.percentile(ms, 50)), 3),
            "p99": round(float(np.percentile(ms, 99)), 3),
            "ticks": int(ms.size),
        }

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

    def _finish(self, run: Run, state: RunState, outcome: str) -> None:
        if run.state in FINISHED:
            return
        if state == RunState.COMPLETED and run.safety.count:
            state = RunState.COMPLETED_UNSAFE
            outcome = f"{outcome}; {run.safety.count} safety violation(s)"
        run.state = state
        run.outcome = outcome
        summary = {
            "mission_time_s": run.mission_time_s,
            "min_separation_m": run.min_separation_m,
            "min_obstacle_clearance_m": run.min_clearance_m,
            "safety_violations": run.safety.count,
            "deepest_violation_m": run.safety.deepest_m,
            "tick_latency_ms": self._latency(run),
            "worst_lag_s": round(run.lag_budget.worst_s, 3),
        }
        self.store.update_run(run.record.id, state, ended=True, outcome=outcome, summary=summary)
        self._event(run, f"run_{state}", outcome=outcome)
        self._publish()

    async def _loiter_all(self, run: Run) -> None:
        """Abort, failure: every vehicle holds at its height on a circle clear of every
        obstacle (``gcs_ppf.holding``); one that has not reported a state, in LOITER."""
        states, _, _ = self._states(list(self._located(run)))
        await self._hold(run, states, stacked=False)

    async def _loiter_stacked(self, run: Run, states: dict[int, VehicleState]) -> None:
        """After the mission: each vehicle circles a point ahead of it, vehicle k of the
        mission ``LOITER_STACK_M``·k above the target, so the circles of a formation that
        flies close together do not cross at one height (plain LOITER would)."""
        await self._hold(run, states, stacked=True)

    async def _hold(self, run: Run, states: dict[int, VehicleState], stacked: bool) -> None:
        """Each vehicle to a holding circle that cuts no obstacle's keep-out (twice the safe
        distance) at the radius it flies (``HOLD_TURN_RADII`` turn radii at its speed), every
        command confirmed by its ACK and sent again while unanswered (``HOLD_RETRY``): a hold
        lost on a lossy link left a vehicle flying its last course into an obstacle."""
        mission = run.mission
        obstacles = obstacles_from_mission(mission).at(run.mission_time_s)
        keep_out = 2.0 * mission.limits.safe_distance_obstacle
        orders: list[confirmation.Order] = []
        for k, v in enumerate(mission.vehicles):
            s = states.get(v.id)
            vehicle = self.fleet.by_id.get(v.id)
            if s is None or vehicle is None:
                orders.append(confirmation.Order(
                    v.id, partial(commands.set_mode, v.id, PlaneMode.LOITER),
                    commands.MAV_CMD_DO_SET_MODE, "hold: mode LOITER",
                    lambda t: t.custom_mode == PlaneMode.LOITER,
                ))  # fmt: skip
                continue
            airframe_omega = Airframe.from_telemetry(vehicle.telemetry).max_turn_rate(s.speed_m_s)
            omega = min(airframe_omega or math.inf, mission.limits.max_yaw_rate)
            radius = max(HOLD_MIN_RADIUS_M, HOLD_TURN_RADII * s.speed_m_s / omega)
            z = mission.target[2] + LOITER_STACK_M * k if stacked else s.pos_m[2]
            hold = holding.holding_circle(
                np.array(s.pos_m), s.yaw_rad, z, radius, LOITER_AHEAD_M, obstacles, keep_out
            )
            if hold.clearance_m < keep_out:
                self._event(run, "hold_not_clear", v.id, clearance_m=round(hold.clearance_m, 1))
            lat, lon, alt = enu_to_geodetic(hold.x_m, hold.y_m, hold.z_m, mission.origin)
            orders.append(confirmation.Order(
                v.id, partial(commands.reposition, v.id, lat, lon, alt, radius),
                commands.MAV_CMD_DO_REPOSITION, "hold: guided loiter",
            ))  # fmt: skip
            if self.settings.guidance == "course":  # the guided altitude outlives the course
                altitude = slew.sendable_altitude(alt)
                orders.append(confirmation.Order(
                    v.id, partial(commands.guided_change_altitude, v.id, altitude, 0.0),
                    commands.MAV_CMD_GUIDED_CHANGE_ALTITUDE, "hold: altitude",
                ))  # fmt: skip

        def event(kind: str, vehicle_id: int | None = None, **detail: Any) -> None:
            self._event(run, kind, vehicle_id, **detail)

        rate = max([self.fleet.by_id[o.vehicle_id].clock.rate for o in orders
                    if o.vehicle_id in self.fleet.by_id] or [1.0])  # fmt: skip
        retry = replace(HOLD_RETRY, ack_timeout_s=min(1.5, max(0.2, HOLD_ACK_VEHICLE_S / rate)))
        await confirmation.confirm_all(self.fleet, orders, event, retry)

    def _vehicle_time_s(self, run: Run) -> float | None:
        leader = self.fleet.by_id.get(run.mission.leader.id)
        if leader is None or leader.telemetry.time_boot_ms is None:
            return None
        return leader.telemetry.time_boot_ms / 1000.0

    async def _launch(self, run: Run) -> None:
        """Every vehicle flying in GUIDED (``gcs_ppf.launch``: those on the ground taken off
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
            await self._loiter_all(run)
            self._finish(run, RunState.FAILED, f"error: {exc}")

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
            last_tick = now_v
            run.mission_time_s = now_v - run.start_vehicle_time_s
            done = await self._tick(run)
            run.tick_latency_s.append(time.perf_counter() - received)
            run.recent_work_s.append(run.tick_latency_s[-1])
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
        if run.mission.leader.id not in run.lost_ids:
            return False
        await self._loiter_all(run)
        self._finish(run, RunState.FAILED, "leader lost")
        return True

    def _watch_safety(
        self, run: Run, located: list[tuple[Vehicle, tuple[float, float, float]]],
        ground_z_m: float | None,
    ) -> None:  # fmt: skip
        """The safety monitor on the positions the vehicles report (not carried on, not
        planned): a ``safety_violation`` event for each keep-out entered."""
        if not located:
            return
        lim = run.mission.limits
        began = run.safety.watch(
            [v.system_id for v, _ in located], np.array([p for _, p in located], dtype=float),
            obstacles_from_mission(run.mission).at(run.mission_time_s), ground_z_m,
            lim.safe_distance_uav, lim.safe_distance_obstacle,
        )  # fmt: skip
        for v in began:
            self._event(run, "safety_violation", v.vehicle_id, keep_out=v.kind, other=v.other,
                        depth_m=round(v.depth_m, 1))  # fmt: skip

    def _obedience(
        self, run: Run, located: list[tuple[Vehicle, tuple[float, float, float]]]
    ) -> bool:
        """Which vehicles obey (GUIDED, the course command ACCEPTED): events when one stops
        for ``not_responding_s`` of vehicle time or comes back; True if it is the leader."""
        command = COURSE_COMMAND[self.settings.guidance]
        reports = []
        for v, _ in located:
            ack = v.telemetry.ack(command)
            guided = v.telemetry.custom_mode == PlaneMode.GUIDED
            reports.append(obedience.Report(v.system_id, guided, ack.result if ack else None))
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

    @staticmethod
    def _states(
        located: list[tuple[Vehicle, tuple[float, float, float]]], tick_work_s: float = 0.0
    ) -> tuple[dict[int, VehicleState], set[int], dict[int, lag.Lag]]:
        """Each located vehicle's state carried on to the moment a command sent now acts on
        it (its lag, ``gcs_ppf.lag``: since its GLOBAL_POSITION_INT arrived, the link's
        round trip, ``tick_work_s`` of ours; at most ``MAX_PREDICTION_S``), and its lag."""
        states: dict[int, VehicleState] = {}
        active: set[int] = set()
        lags: dict[int, lag.Lag] = {}
        now = time.monotonic()
        for vehicle, pos in located:
            t = vehicle.telemetry
            if t.vn_m_s is None or t.ve_m_s is None or t.vd_m_s is None:
                continue
            since = 0.0 if t.position_received_s is None else max(0.0, now - t.position_received_s)
            lags[vehicle.system_id] = lag.vehicle_lag(
                since, vehicle.round_trip_s, tick_work_s, vehicle.clock.rate
            )
            ahead = min(lags[vehicle.system_id].total_s, MAX_PREDICTION_S)
            ground_speed = math.hypot(t.vn_m_s, t.ve_m_s)
            turn = coordinated_turn_rate(t.roll_rad, ground_speed)
            states[vehicle.system_id] = state_from_velocity(
                pos, t.vn_m_s, t.ve_m_s, t.vd_m_s, ahead, turn
            )
            if not vehicle.lost:
                active.add(vehicle.system_id)
        return states, active, lags

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
        work = statistics.median(run.recent_work_s) if run.recent_work_s else 0.0
        states, active, lags = self._states(located, work)
        self._account_lag(run, [lags[i] for i in active if i in lags])
        if leader_id not in states:
            return False
        positions = np.array([states[i].pos_m for i in sorted(active)], dtype=float)
        obstacles = obstacles_from_mission(mission).at(run.mission_time_s)
        run.min_separation_m = _min(run.min_separation_m, separations(positions))
        run.min_clearance_m = _min(run.min_clearance_m, clearance(positions, obstacles))

        leader_pos = np.array(states[leader_id].pos_m)
        previous, run.leader_pos = run.leader_pos, leader_pos
        if passes_within(
            previous, leader_pos, np.array(mission.target), mission.limits.target_accuracy
        ):
            await self._loiter_stacked(run, states)
            self._finish(run, RunState.COMPLETED, "leader reached the target")
            return True

        if run.mission_time_s > mission.planner.max_time:
            await self._loiter_all(run)
            self._finish(run, RunState.FAILED, "planner.max_time passed before the target")
            return True

        if self._obedience(run, located):
            await self._loiter_all(run)
            self._finish(run, RunState.FAILED, "leader not responding")
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
        envelope = tick_envelope(
            list(airframes.values()), [states[i].speed_m_s for i in active], lim.v_min,
            lim.v_max, lim.accel, self.settings.lookahead_s, lagging_s,
            self.settings.planning_margin_m,
        )  # fmt: skip
        scene = scene_now(
            mission, states, active, obstacles, envelope.planning_margin_m, ground,
            envelope=envelope.limits,
        )  # fmt: skip
        g = guidance(
            scene,
            lookahead_s=self.settings.lookahead_s,
            dt=self.settings.planner_dt_s,
            carrot_m=self.settings.carrot_m,
        )
        ordered = [airframes.get(vid, Airframe()) for vid in g.ids]
        if self.settings.guard_horizon_s != 0.0:
            tuning = guard_tuning(
                ordered, scene.fleet.speed.tolist(), lim.safe_distance_uav,
                lagging_s, horizon_s=self.settings.guard_horizon_s,
                margin_m=self.settings.guard_margin_m,
                resolution_m=self.settings.guard_resolution_m,
            )  # fmt: skip
            points, resolving = separation_guard.resolve(
                scene,
                g.guided_point_m,
                distance_m=lim.safe_distance_uav + tuning.margin_m,
                horizon_s=tuning.horizon_s,
                resolution_m=tuning.resolution_up_m,
                resolution_down_m=tuning.resolution_down_m,
                release_m=tuning.margin_m,
                previous=run.last.resolving if run.last is not None else None,
                in_formation=in_formation(g, formation_tolerance(mission)),
            )
            g = replace(g, guided_point_m=points, resolving=resolving)
        self._note_changes(run, g)
        run.last = g
        keep = assurance.KeepOut(
            obstacles, mission.ground if mission.ground is not None else ground,
            lim.safe_distance_obstacle, lim.safe_distance_uav,
        )  # fmt: skip
        hold_s = 1.0 / self.settings.tick_hz + telemetry_interval_s + run.fleet_lag.command_delay_s

        def event(kind: str, vehicle_id: int | None = None, **detail: Any) -> None:
            self._event(run, kind, vehicle_id, **detail)

        await commanding.command_fleet(
            self.fleet, g, active, states, ordered, run.orders, keep, hold_s,
            run.commanded_speed, event,
        )  # fmt: skip
        return False

    def _note_changes(self, run: Run, g: Guidance) -> None:
        """Events for what changed since the last tick."""
        before = run.last
        wingmen_formed = all(
            f for i, f in enumerate(g.formed) if i and g.ids[i] not in run.lost_ids
        )
        if wingmen_formed != run.formed:
            run.formed = wingmen_formed
            self._event(run, "formation_formed" if wingmen_formed else "formation_broken")
        if before is None:
            return
        for i, vid in enumerate(g.ids):
            if g.avoiding[i] != before.avoiding[i]:
                self._event(run, "avoidance_entered" if g.avoiding[i] else "avoidance_left", vid)
            if g.resolving and before.resolving and g.resolving[i] != before.resolving[i]:
                kind = "conflict_resolution_" + ("began" if g.resolving[i] else "ended")
                self._event(run, kind, vid)
            if g.state[i] == "s2" and before.state[i] != "s2":
                self._event(run, "local_minimum_escape", vid)

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

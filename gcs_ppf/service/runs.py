"""The ground-station service: missions and their runs (the imperative shell).

It owns the clocks and the tasks.  The vehicles and their links are ``service.fleet``
(each vehicle's state carried on by its measured lag, ``guidance.lag``); a run's record and
status are ``service.run``; what a run is flown with of this service is
``service.station``.  Flying a run is ``service.flight``: launching the vehicles
(``service.launch``, commands confirmed by ``service.confirmation``), then each tick planned
with ``guidance.tick_plan`` (pure: the envelope, PPF guidance, the separation guard) and
commanded with ``service.commanding`` (every command through the run-time assurance,
``guidance.assurance``), obedience by ``guidance.obedience``; its end, the holds and the
watch after, is ``service.ending``; the safety monitor on the reported positions is
``service.watch`` (``guidance.safety_monitor``); storage is ``service.store``.  Routes in
``api/`` call the public methods here and of ``fleet``, nothing else.  (Modules under
``gcs_ppf``.)
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import time
from collections.abc import AsyncIterator
from typing import Any

from gcs_ppf.guidance import start_check
from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.mission import CylinderZone, Mission, Obstacle, PolygonZone, Waypoint
from gcs_ppf.service import commanding, ending, flight, launch, resumption, vehicle_fences
from gcs_ppf.service.errors import Conflict, NotFound, ServiceError
from gcs_ppf.service.fleet import Fleet
from gcs_ppf.service.forwarding import Forwarding
from gcs_ppf.service.kernels import load_kernels
from gcs_ppf.service.run import FINISHED, Run, RunState
from gcs_ppf.service.run import status as run_status
from gcs_ppf.service.settings import Settings
from gcs_ppf.service.station import Station
from gcs_ppf.service.store import Store, StoredMission, StoredRun

log = logging.getLogger("gcs_ppf.service.runs")

__all__ = ["FINISHED", "FormationService", "RunState"]


class FormationService:
    """Links, vehicles, missions and runs; see the module docstring."""

    def __init__(self, settings: Settings, store: Store) -> None:
        self.settings = settings
        self.store = store
        self.fleet = Fleet(settings, self._spawn)
        self._runs: dict[int, Run] = {}  # mission id → its current or last run
        self._subscribers: set[asyncio.Queue[dict[str, Any]]] = set()
        self._tasks: asyncio.TaskGroup | None = None
        self._spawned: set[asyncio.Task[Any]] = set()  # ``_spawn``'s, until done
        self._kernels: asyncio.Task[None] | None = None  # loading them (``running``)
        self._station = Station(
            settings,
            store,
            self.fleet,
            self._runs,
            self._spawn,
            self._publish,
            self._kernels_loaded,
        )
        for stale in store.interrupted_runs():  # a previous process stopped mid-flight
            outcome = f"the service stopped while the run was {stale.state}"
            store.add_event(stale.id, "run_interrupted", detail={"outcome": outcome})
            store.update_run(stale.id, RunState.INTERRUPTED, ended=True, outcome=outcome)
            log.warning("run %d of mission %d: %s", stale.id, stale.mission_id, outcome)

    # Lifetime ----------------------------------------------------------------------------
    @contextlib.asynccontextmanager
    async def running(self) -> AsyncIterator[FormationService]:
        """Run the background tasks (links, heartbeats, watchdog) for the body's duration.
        The links come up at once; the planner's and the assurance's kernels load meanwhile
        in a thread (``load_kernels``), and a run launches only once they have (loaded first,
        under two CPU burners a vehicle set to die 3 s after its SITL started was dead
        before the service heard it; awaited in the start request, a cold cache held it
        past an HTTP client's timeout)."""
        async with asyncio.TaskGroup() as tg:
            self._tasks = tg
            background = [
                tg.create_task(self.fleet.heartbeats()),
                tg.create_task(self.fleet.watchdog()),
            ]
            for url in self.settings.links:
                await self.fleet.add_link(url)
            for url, allow_unsigned in self.store.links():  # added over the API before
                if url not in self.settings.links:
                    await self.fleet.add_link(url, allow_unsigned=allow_unsigned)
            if self.settings.forward:
                self.fleet.forwarding = Forwarding(
                    self.settings.forward,
                    system_id=self.settings.system_id,
                    to_vehicles=self.fleet.relay,
                    on_takeover=self._taken_over,
                )
                background.append(tg.create_task(self.fleet.forwarding.run()))
            self._kernels = tg.create_task(
                asyncio.to_thread(load_kernels, self.settings.planner_dt_s)
            )
            try:
                yield self
            finally:
                await self._hand_over_holds()
                self.fleet.close()
                if self.fleet.forwarding is not None:
                    self.fleet.forwarding.close()
                for task in background:
                    task.cancel()
                # The links closed, nothing still being sent arrives: waiting for a
                # parameter's retries to run out held a stop 5 s.
                for task in list(self._spawned):
                    task.cancel()
                self._tasks = None

    async def _hand_over_holds(self) -> None:
        """On stopping: a run in flight ends ``failed`` and its vehicles get their holds;
        every hold being flown (``ending.hold``) is cancelled, which sends its circles to
        the autopilots once, and waited for (``ending.HANDOVER_ON_STOP_S`` at most) before
        the links close: no vehicle is left on the last course it was sent."""
        flying = []  # runs cancelled: one launching hands its holds over as it stops
        for run in self._runs.values():
            if run.task is not None and not run.task.done():
                run.abort.set()
                run.task.cancel()
                flying.append(run.task)
                if run.state == RunState.RUNNING:
                    ending.end(self._station, run, RunState.FAILED, "the service stopped")
        await asyncio.sleep(0)  # a hold just spawned plans its circles before it is cancelled
        holds = [
            r.hold_task
            for r in self._runs.values()
            if r.hold_task is not None and not r.hold_task.done()
        ]
        for task in holds:
            task.cancel()  # the holds and the watch after the end
        if holds or flying:
            await asyncio.wait(holds + flying, timeout=ending.HANDOVER_ON_STOP_S)

    async def _kernels_loaded(self) -> None:
        if self._kernels is not None:
            if not self._kernels.done():
                log.info(
                    "waiting for the planner's compiled kernels (compiled on the first "
                    "run after an install: about 2 min on 2 cores)"
                )
            await asyncio.shield(self._kernels)

    def _spawn(self, coro: Any) -> asyncio.Task[Any]:
        if self._tasks is None:
            raise ServiceError("the service is not running")
        task = self._tasks.create_task(coro)
        self._spawned.add(task)
        task.add_done_callback(self._spawned.discard)
        return task

    # Links -----------------------------------------------------------------------------
    async def add_link(self, url: str, *, allow_unsigned: bool | None = None) -> dict[str, Any]:
        """``Fleet.add_link``, remembered: a service started again opens it again (and so
        hears the vehicles of a run it may resume)."""
        info = await self.fleet.add_link(url, allow_unsigned=allow_unsigned)
        self.store.add_link(url, allow_unsigned)
        return info

    async def remove_link(self, link_id: int) -> None:
        """``Fleet.remove_link``, and forgotten."""
        url = next((e["url"] for e in self.fleet.links() if e["id"] == link_id), None)
        await self.fleet.remove_link(link_id)
        if url is not None:
            self.store.remove_link(url)

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
        return self._revise(mission_id, obstacles=[o.model_dump() for o in obstacles])

    def add_zones(
        self,
        mission_id: int,
        zones: list[CylinderZone | PolygonZone],
        route: tuple[list[Waypoint], tuple[float, float, float]] | None = None,
    ) -> StoredMission:
        """Zones added to the mission's; a running mission keeps out of them from its next
        tick on, and its vehicles' fences are put up again with them
        (``vehicle_fences.put_up``).  With ``route`` (waypoints and target, a ``.plan``'s),
        the route and target replaced as well, never while the mission flies
        (``Conflict``).  A set that does not fit the mission (a start inside one) adds
        none."""
        kept = [z.model_dump() for z in self.mission(mission_id).mission.zones]
        fields: dict[str, Any] = {"zones": [*kept, *(z.model_dump() for z in zones)]}
        if route is not None:
            run = self._runs.get(mission_id)
            if run is not None and run.state not in FINISHED:
                raise Conflict(f"mission {mission_id} flies: its route cannot change in flight")
            fields["route"] = [w.model_dump() for w in route[0]]
            fields["target"] = list(route[1])
        return self._revise(mission_id, **fields)

    def _revise(self, mission_id: int, **fields: Any) -> StoredMission:
        """The stored mission with ``fields`` of its document replaced, validated whole."""
        stored = self.mission(mission_id)
        doc = stored.mission.model_dump()
        doc.update(fields)
        try:
            mission = Mission.model_validate(doc)
        except ValueError as exc:
            raise ServiceError(str(exc)) from None
        run = self._runs.get(mission_id)
        if run is not None and run.state not in FINISHED:
            # the run's own document changed the same way: its leader and slots may not be
            # the uploaded ones any more (``leader_succeeded``)
            flown = run.mission.model_dump()
            flown.update(fields)
            run.mission = Mission.model_validate(flown)
            run.orders = dataclasses.replace(run.orders, mission=run.mission)
            if "zones" in fields and self.settings.fences and run.state == RunState.RUNNING:
                ids = [v.id for v in run.mission.vehicles if v.id not in run.lost_ids]
                self._spawn(vehicle_fences.put_up(self._station, run, ids))
        return self.store.replace_mission(mission_id, mission)

    # Runs --------------------------------------------------------------------------------
    def _active_run(self) -> Run | None:
        return next((r for r in self._runs.values() if r.state not in FINISHED), None)

    async def start(self, mission_id: int, from_where_they_are: bool = False) -> dict[str, Any]:
        """A run created and answered at once (``starting``); it launches the fleet once the
        kernels are loaded (``flight.fly``), so that no tick compiles or loads one.  A
        vehicle inside a keep-out or far from its start position (``start_check``) is a 409
        naming it, unless ``from_where_they_are``: then the run starts as they are (the
        assurance's escape first), and ``run_started`` says so."""
        stored = self.mission(mission_id)
        self._check_startable([v.id for v in stored.mission.vehicles])
        positions = {v.system_id: p for v, p in self._station.located_of(stored.mission)}
        found = start_check.misplaced(stored.mission, positions)
        if found and not from_where_they_are:
            raise Conflict(
                "; ".join(m.words() for m in found)
                + ": move them, or start from where they are (from_where_they_are=true)",
                {"misplaced": [dataclasses.asdict(m) for m in found]},
            )
        record = self.store.add_run(mission_id, RunState.STARTING)
        run = self._new_run(record, stored.mission)
        if found:  # the operator's choice, and what it was made over
            misplaced = [dataclasses.asdict(m) for m in found]
            self._station.event(run, "run_started", None, from_where_they_are=misplaced)
        else:
            self._station.event(run, "run_started")
        run.task = self._spawn(flight.fly(self._station, run))
        return self.status(mission_id)

    async def resume(self, mission_id: int) -> dict[str, Any]:
        """The mission's ``interrupted`` run flown on (``service.resumption``): its record
        reopened, the run as its events left it (leader, leg, vehicles lost, violations),
        mission time on as if the service had never stopped; the vehicles taken back in
        GUIDED (confirmed) and planned for from their telemetry.  409 unless the last run
        is interrupted, or with a vehicle it had not lost unheard."""
        run = self._reopened(mission_id, RunState.STARTING)
        self._station.event(
            run,
            "run_resumed",
            run.mission.leader.id,
            leg=run.legs[run.leg].index,
            lost=sorted(run.lost_ids),
        )
        run.task = self._spawn(flight.fly(self._station, run))
        return self.status(mission_id)

    def _taken_over(self, vehicle_id: int, what: str, by: tuple[int, int]) -> None:
        """Another ground station sent ``vehicle_id`` a command of flight (``what``): in a
        run, the vehicle leaves the run's command until ``hand_back`` (it is avoided as
        traffic meanwhile; a leader hands the lead on); ``vehicle_taken_over``."""
        run = self._active_run()
        if run is None or vehicle_id in run.taken_over:
            return
        if vehicle_id not in {v.id for v in run.mission.vehicles}:
            return
        run.taken_over.add(vehicle_id)
        detail = {"by_system": by[0], "by_component": by[1], "message": what}
        self._station.event(run, "vehicle_taken_over", vehicle_id, **detail)

    async def hand_back(self, mission_id: int, vehicle_id: int) -> dict[str, Any]:
        """The operator gives a vehicle taken over back to the run: switched to GUIDED
        (confirmed) and commanded again; ``vehicle_handed_back``.  409 unless the mission's
        run is flying and the vehicle was taken over."""
        run = self._runs.get(mission_id)
        if run is None or run.state != RunState.RUNNING:
            raise Conflict(f"mission {mission_id}: no run is flying")
        if vehicle_id not in run.taken_over:
            raise Conflict(f"vehicle {vehicle_id} was not taken over in this run")
        await launch.set_mode(
            self.fleet, vehicle_id, PlaneMode.GUIDED, self._station.events_of(run)
        )
        run.taken_over.discard(vehicle_id)
        self._station.event(run, "vehicle_handed_back", vehicle_id)
        return run_status(run)

    def _check_startable(self, ids: list[int]) -> None:
        """No other run active, every one of ``ids`` heard and on one link only (409)."""
        active = self._active_run()
        if active is not None:
            raise Conflict(
                f"mission {active.mission_id} is {active.state}; abort it first",
                {"mission_id": active.mission_id, "state": active.state},
            )
        missing = [i for i in ids if i not in self.fleet.by_id or self.fleet.by_id[i].lost]
        if missing:
            raise Conflict(f"vehicles not connected: {missing}", {"missing_ids": missing})
        duplicates = self.fleet.duplicates(ids)
        if duplicates:
            said = "; ".join(
                f"vehicle {vid} on links {', '.join(map(str, links))}"
                for vid, links in sorted(duplicates.items())
            )
            raise Conflict(
                f"system ids heard on more than one link at once ({said}): two vehicles "
                "with one id, or one vehicle on two links; give each vehicle its own "
                "SYSID_THISMAV or remove the extra link (DELETE /links/{id})",
                {"duplicate_links": {str(k): list(v) for k, v in duplicates.items()}},
            )

    def _new_run(self, record: StoredRun, mission: Mission) -> Run:
        orders = commanding.Orders(mission, self.settings.guidance, self.settings.lookahead_s)
        run = Run(record=record, mission_id=record.mission_id, mission=mission, orders=orders)
        for v in self.fleet.by_id.values():  # links changed before the run are not its events
            if v.link_change is not None:
                run.link_changes[v.system_id] = v.link_change
        self._runs[record.mission_id] = run
        return run

    def _reopened(self, mission_id: int, state: RunState) -> Run:
        """The mission's last run, ``interrupted``, in memory again as its records left it
        (``resumption.standing``), its record unended (``state``); for ``resume`` the
        vehicles it had not lost must be heard (``_check_startable``).  409 otherwise."""
        stored = self.mission(mission_id)
        past = self.store.runs(mission_id)
        last = past[-1] if past else None
        if last is None or last.state != RunState.INTERRUPTED:
            raise Conflict(
                f"mission {mission_id} has no interrupted run",
                {"state": last.state if last else RunState.PENDING},
            )
        was = resumption.standing(stored.mission, self.store.events(last.id))
        if state == RunState.STARTING:
            self._check_startable([v.id for v in was.mission.vehicles if v.id not in was.lost_ids])
        run = self._new_run(self.store.reopen_run(last.id, state), was.mission)
        run.state = state
        run.leg = min(was.leg, len(run.legs) - 1)
        run.waypoint_times_s = list(was.waypoint_times_s)
        run.lost_ids = set(was.lost_ids)
        run.safety.count = was.violations
        run.safety.deepest_m = dict(was.deepest_m)
        rows = self.store.telemetry(last.id)
        run.min_separation_m, run.min_clearance_m = resumption.closest_m(was.mission, rows)
        now_v = flight.vehicle_time_s(self._station, run)
        run.mission_time_s = resumption.mission_time_now_s(
            was, now_v, time.time(), self.fleet.clock_rate()
        )
        if was.flew and now_v is not None:  # on the leader's clock from here (``flight``)
            run.start_vehicle_time_s = now_v - run.mission_time_s
        return run

    async def abort(self, mission_id: int) -> dict[str, Any]:
        """The run stopped, every vehicle held clear of every keep-out (``ending.end``);
        an ``interrupted`` run too, its vehicles as they are heard now."""
        self.mission(mission_id)
        run = self._runs.get(mission_id)
        if run is None or run.state in FINISHED:
            past = self.store.runs(mission_id)
            if not past or past[-1].state != RunState.INTERRUPTED:
                raise Conflict(
                    f"mission {mission_id} is not running",
                    {"state": run.state if run else RunState.PENDING},
                )
            run = self._reopened(mission_id, RunState.RUNNING)
        run.abort.set()
        ending.end(self._station, run, RunState.ABORTED, "aborted by the operator")
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

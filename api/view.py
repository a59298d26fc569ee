"""What the operator's page (``api/static/``) reads: read-only, added beside the API.

* ``GET /`` serves the page, ``/ui/…`` its ES modules and style sheet (plain files, no
  build step, nothing fetched from elsewhere at run time).
* ``WS /ws/view?mission_id=N`` sends *view frames*: the telemetry snapshot in the mission's
  ICS (positions converted here with ``gcs_ppf.geodesy``, never in the browser), each
  wingman's local target point (Eq. 6, from the leader's flight-path attitude), the
  obstacles where they are now with their keep-out and influence radii, the zones'
  footprints in the ICS (``zone_view``), and the run's events
  as they are stored.  At most ``MAX_FRAME_HZ`` frames a second (a SITL at 10x publishes
  100 a second), and one every ``IDLE_FRAME_S`` when nothing flies, so the vehicle list
  stays current between runs.  The run shown is the active one, else the requested
  mission's last, else the service's last.
* ``GET /runs/{run_id}/telemetry``: a past run's sampled telemetry, for replay.

``WS /ws/telemetry`` and every other route are unchanged.  The page's files hold no data
and need no token; its routes and its socket do (``api.auth``): the page asks for a token
once when the service answers 401 (or refuses the socket) and keeps it in the browser's
``sessionStorage``.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from fastapi import FastAPI, Query, Request, WebSocket, WebSocketDisconnect
from fastapi import Path as PathParam
from fastapi.responses import FileResponse
from fastapi.staticfiles import StaticFiles
from starlette.websockets import WebSocketState

from api.auth import READ, WsCaller, accept
from api.deps import AUTH_ERRORS
from gcs_ppf.frames import local_target_point
from gcs_ppf.geodesy import heading_ned_to_yaw
from gcs_ppf.guidance.online import state_from_velocity
from gcs_ppf.mission import CylinderZone, Limits, Mission, Obstacle, PolygonZone, zone_footprint
from gcs_ppf.planning.ppf.primitives import influence_radius
from gcs_ppf.service.errors import NotFound
from gcs_ppf.service.fleet import Vehicle
from gcs_ppf.service.runs import FormationService

STATIC_DIR = Path(__file__).parent / "static"
MAX_FRAME_HZ = 20.0
IDLE_FRAME_S = 0.5
EVENTS_EVERY_S = 0.25  # the run's events are read from the store at most this often
# Run states (API) in which a run no longer flies.
FINISHED = frozenset({"completed", "completed_unsafe", "aborted", "failed", "interrupted"})
MOVING_M_S = 1.0  # below this ground speed the heading comes from the attitude, not velocity


def zone_view(zone: CylinderZone | PolygonZone, mission: Mission) -> dict[str, Any]:
    """A zone as the page draws it: its footprint in the mission's ICS (a cylinder's
    ``center_m`` and ``radius_m``, a polygon's ``vertices_m``; lat/lon converted here),
    its height band (``floor_m`` / ``ceiling_m``, None: unbounded) and whether vehicles
    stay inside (``inclusion``)."""
    footprint = [[round(float(c), 2) for c in p] for p in zone_footprint(zone, mission.origin)]
    view: dict[str, Any] = {
        "name": zone.name,
        "kind": zone.kind,
        "inclusion": zone.inclusion,
        "floor_m": zone.floor,
        "ceiling_m": zone.ceiling,
    }
    if isinstance(zone, CylinderZone):
        return {**view, "center_m": footprint[0], "radius_m": zone.radius}
    return {**view, "vertices_m": footprint}


def obstacle_view(obstacle: Obstacle, limits: Limits, mission_time_s: float) -> dict[str, Any]:
    """An obstacle where it is at ``mission_time_s``, with its keep-out (radius + safe
    distance) and the planner's influence radius at ``limits.v_max`` (the largest; the
    paper's Eq. 10 as corrected in ``gcs_ppf.planning.ppf.primitives.influence_radius``)."""
    centre = np.asarray(obstacle.center) + mission_time_s * np.asarray(obstacle.velocity)
    keep_out_m = obstacle.radius + limits.safe_distance_obstacle
    return {
        "center_m": [round(float(c), 2) for c in centre],
        "radius_m": obstacle.radius,
        "velocity_m_s": list(obstacle.velocity),
        "keep_out_m": keep_out_m,
        "influence_m": round(influence_radius(limits.v_max, limits.max_yaw_rate, keep_out_m), 2),
    }


def vehicle_view(
    vehicle: dict[str, Any],
    pos_m: Sequence[float] | None,
    velocity_ned_m_s: tuple[float | None, float | None, float | None],
) -> dict[str, Any]:
    """One row of ``Fleet.vehicles()`` with its ICS position, course (ICS yaw from the
    velocity, or from the attitude when slower than ``MOVING_M_S``), speed and flight-path
    pitch."""
    vn, ve, vd = velocity_ned_m_s
    yaw = pitch = speed = None
    if pos_m is not None and vn is not None and ve is not None and vd is not None:
        s = state_from_velocity((pos_m[0], pos_m[1], pos_m[2]), vn, ve, vd)
        speed = s.speed_m_s
        if math.hypot(vn, ve) >= MOVING_M_S:
            yaw, pitch = s.yaw_rad, s.pitch_rad
    attitude_yaw = vehicle.get("attitude", {}).get("yaw_rad")
    if yaw is None and attitude_yaw is not None:
        yaw = heading_ned_to_yaw(attitude_yaw)
    return {
        "id": vehicle["system_id"],
        "link_id": vehicle["link_id"],
        "mode": vehicle["mode"],
        "armed": vehicle["armed"],
        "lost": vehicle["lost"],
        "seconds_since_heard": vehicle["seconds_since_heard"],
        "pos_m": None if pos_m is None else [round(float(c), 2) for c in pos_m],
        "yaw_rad": None if yaw is None else round(yaw, 4),
        "pitch_rad": None if pitch is None else round(pitch, 4),
        "speed_m_s": None if speed is None else round(speed, 2),
    }


def with_formation(
    vehicles: list[dict[str, Any]], mission: Mission | None, status: dict[str, Any] | None
) -> list[dict[str, Any]]:
    """Each vehicle's role in ``mission``, its PPF state, avoidance and slot distance from
    the run's ``status``, and each wingman's local target point (Eq. 6) from the leader's
    position and flight-path attitude (None while the leader has none).  A run whose leader
    was lost flies another leader and other slots (``planning.succession``): the run's
    ``leader_id`` and ``slots`` are shown, not the document's."""
    run = status or {}
    per_vehicle = {p["id"]: p for p in run.get("vehicles", [])}
    members = {v.id for v in mission.vehicles} if mission else set()
    leader_id = run.get("leader_id", mission.leader.id if mission else None)
    if "slots" in run:
        slots = {int(vid): list(slot) for vid, slot in run["slots"].items()}
    else:
        slots = {w.id: list(w.slot) for w in mission.wingmen if w.slot} if mission else {}
    leader = next((v for v in vehicles if v["id"] == leader_id), None)

    def role(vid: int) -> str:
        if vid not in members:
            return "other"
        return "leader" if vid == leader_id else "wingman"

    out = []
    for v in vehicles:
        slot = slots.get(v["id"])
        p = per_vehicle.get(v["id"], {})
        ltp = None
        if (
            slot is not None
            and leader is not None
            and leader["pos_m"] is not None
            and leader["yaw_rad"] is not None
        ):
            point = local_target_point(
                np.asarray(leader["pos_m"], dtype=float),
                leader["pitch_rad"] or 0.0,
                leader["yaw_rad"],
                np.asarray(slot, dtype=float),
            )
            ltp = [round(float(c), 2) for c in point]
        out.append(
            {
                **v,
                "role": role(v["id"]),
                "slot_m": slot,
                "ppf_state": p.get("ppf_state"),
                "avoiding": p.get("avoiding"),
                "formed": p.get("formed"),
                "local_target_m": ltp,
                "local_target_distance_m": p.get("local_target_distance_m"),
                "nearest_keep_out": p.get("nearest_keep_out"),
                "clearance_m": p.get("clearance_m"),
            }
        )
    return out


def frame(
    mission_id: int | None,
    mission: Mission | None,
    status: dict[str, Any] | None,
    vehicles: list[dict[str, Any]],
    events: list[dict[str, Any]],
    wall_s: float,
) -> dict[str, Any]:
    """A view frame (see the module docstring); ``vehicles`` from ``vehicle_view``."""
    t = float((status or {}).get("mission_time_s") or 0.0)
    return {
        "type": "frame",
        "wall_s": round(wall_s, 3),
        "mission_id": mission_id,
        "run": status,
        "target_m": list(mission.target) if mission else None,
        "route": [w.model_dump() for w in mission.route] if mission else [],
        "obstacles": [obstacle_view(o, mission.limits, t) for o in mission.obstacles]
        if mission
        else [],
        "zones": [zone_view(z, mission) for z in mission.zones] if mission else [],
        "vehicles": with_formation(vehicles, mission, status),
        "events": events,
    }


class FrameSource:
    """Builds the frames of one page's connection from the running service."""

    def __init__(self, service: FormationService, mission_id: int | None) -> None:
        self.service = service
        self.requested = mission_id
        self._events_sent: dict[int, int] = {}  # run id → events already sent
        self._events_read_s = -math.inf

    def _shown(self, snapshot: dict[str, Any]) -> int | None:
        running = snapshot["mission"]
        if running is not None and running["state"] not in FINISHED:
            return int(running["mission_id"])
        if self.requested is not None:
            return self.requested
        return None if running is None else int(running["mission_id"])

    def _new_events(self, mission_id: int, run_id: int | None) -> list[dict[str, Any]]:
        now = time.monotonic()
        if run_id is None or now - self._events_read_s < EVENTS_EVERY_S:
            return []
        self._events_read_s = now
        events = [e for e in self.service.events(mission_id) if e["run_id"] == run_id]
        sent = self._events_sent.get(run_id, 0)
        self._events_sent[run_id] = len(events)
        return events[sent:]

    def next_frame(self) -> dict[str, Any]:
        """The frame of this moment.  The stored mission is the one flown: ``PUT
        …/obstacles`` replaces both at once."""
        fleet = self.service.fleet
        rows = fleet.vehicles()
        mission_id = self._shown(self.service.snapshot())
        mission = status = None
        events: list[dict[str, Any]] = []
        if mission_id is not None:
            try:
                mission = self.service.mission(mission_id).mission
                status = self.service.status(mission_id)
            except NotFound:
                mission_id = None
        if mission_id is not None and status is not None:
            events = self._new_events(mission_id, status.get("run_id"))
        views = []
        for row in rows:
            v: Vehicle | None = fleet.by_id.get(row["system_id"])
            t = None if v is None else v.telemetry
            pos = None if mission is None or v is None else fleet.vehicle_enu(v, mission)
            vel = (None, None, None) if t is None else (t.vn_m_s, t.ve_m_s, t.vd_m_s)
            views.append(vehicle_view(row, pos, vel))
        return frame(mission_id, mission, status, views, events, time.time())


async def stream_frames(
    websocket: WebSocket,
    next_frame: Callable[[], dict[str, Any]],
    updated: asyncio.Queue[Any],
) -> None:
    """Send ``next_frame()`` when ``updated`` yields (coalesced, at most ``MAX_FRAME_HZ``)
    or every ``IDLE_FRAME_S``, until the page goes away.  What the page sends is read and
    dropped: nothing on this socket changes the service."""

    async def until_closed() -> None:
        while (await websocket.receive())["type"] != "websocket.disconnect":
            pass

    closed = asyncio.create_task(until_closed())  # awaited in ``finally``
    try:
        while not closed.done():
            started = time.monotonic()
            await websocket.send_json(next_frame())
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout(IDLE_FRAME_S):
                    await updated.get()
            while not updated.empty():
                updated.get_nowait()
            wait = 1.0 / MAX_FRAME_HZ - (time.monotonic() - started)
            if wait > 0:
                await asyncio.wait({closed}, timeout=wait)
    except (WebSocketDisconnect, RuntimeError, OSError):
        pass  # the page went away mid-send
    finally:
        closed.cancel()
        with contextlib.suppress(asyncio.CancelledError, WebSocketDisconnect, RuntimeError):
            await closed
        if websocket.application_state == WebSocketState.CONNECTED:
            with contextlib.suppress(WebSocketDisconnect, RuntimeError, OSError):
                await websocket.close()


def telemetry_history(rows: Sequence[Sequence[float]]) -> dict[str, dict[str, list[Any]]]:
    """Stored telemetry rows (``Store.telemetry``) → per vehicle id, its times, ICS
    positions and speeds: the shape of ``POST /missions/{id}/plan``'s trajectories."""
    out: dict[str, dict[str, list[Any]]] = {}
    for t, vid, _lat, _lon, _alt, x, y, z, speed in rows:
        track = out.setdefault(str(int(vid)), {"t": [], "position_m": [], "speed_m_s": []})
        track["t"].append(round(t, 3))
        track["position_m"].append([round(x, 2), round(y, 2), round(z, 2)])
        track["speed_m_s"].append(None if speed is None or math.isnan(speed) else round(speed, 2))
    return out


RunId = Annotated[int, PathParam(ge=1, le=2**63 - 1)]


def install(app: FastAPI) -> None:
    """Add the page, its files and its read-only routes to ``app``."""

    @app.get("/", include_in_schema=False)
    async def page() -> FileResponse:
        return FileResponse(STATIC_DIR / "index.html", headers={"Cache-Control": "no-cache"})

    app.mount("/ui", StaticFiles(directory=STATIC_DIR), name="ui")

    @app.get(
        "/runs/{run_id}/telemetry",
        responses={404: {"description": "unknown run"}, **AUTH_ERRORS},
        dependencies=[READ],
    )
    async def run_telemetry(run_id: RunId, request: Request) -> dict[str, Any]:
        """A run's sampled telemetry (``telemetry_sample_hz`` of mission time), per
        vehicle: mission times, ICS positions (metres) and ground speeds."""
        service: FormationService = request.state.service
        try:
            run = service.store.run(run_id)
        except KeyError:
            raise NotFound(f"run {run_id} does not exist") from None
        rows = await asyncio.to_thread(service.store.telemetry, run_id)
        return {
            "run_id": run.id,
            "mission_id": run.mission_id,
            "vehicles": telemetry_history(rows),
        }

    @app.websocket("/ws/view")
    async def view(
        websocket: WebSocket,
        _caller: WsCaller,
        mission_id: Annotated[int | None, Query(ge=1)] = None,
    ) -> None:
        service: FormationService = websocket.state.service
        await accept(websocket)
        source = FrameSource(service, mission_id)
        queue = service.subscribe()
        try:
            await stream_frames(websocket, source.next_frame, queue)
        finally:
            service.unsubscribe(queue)

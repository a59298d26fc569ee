"""Routes of missions: stored, planned offline, their obstacles replaced, started, aborted,
and their status and events."""

from __future__ import annotations

import asyncio
from typing import TYPE_CHECKING, Annotated, Any

from fastapi import APIRouter, Body, status

from api.deps import AUTH_ERRORS, COMMANDS, ERRORS, READ_ONLY, MissionId, Service, SystemId
from api.models import (
    ErrorBody,
    FieldErrors,
    MissionDetail,
    MissionSummary,
    mission_detail,
    mission_summary,
)
from gcs_ppf.mission import Mission, Obstacle
from gcs_ppf.plan_route import RouteImportError, route_from_plan
from gcs_ppf.service.errors import TooLarge, Unprocessable
from gcs_ppf.service.settings import Settings
from gcs_ppf.zone_import import ZoneImportError, zones_from_document

if TYPE_CHECKING:
    from gcs_ppf.offline.plan import PlanRun

router = APIRouter(responses=AUTH_ERRORS)
TOO_LARGE: dict[int | str, dict[str, Any]] = {413: {"description": "more than the service takes"}}


def check_size(settings: Settings, vehicles: int | None, obstacles: int) -> None:
    """413 naming the list and the limit when a document has more vehicles or obstacles
    than the settings' ``max_vehicles`` / ``max_obstacles``."""
    if vehicles is not None and vehicles > settings.max_vehicles:
        raise TooLarge(
            f"vehicles: {vehicles} vehicles, the service takes at most {settings.max_vehicles} "
            "(max_vehicles, GCS_PPF_MAX_VEHICLES)",
            {"field": "vehicles", "count": vehicles, "limit": settings.max_vehicles},
        )
    if obstacles > settings.max_obstacles:
        raise TooLarge(
            f"obstacles: {obstacles} obstacles, the service takes at most "
            f"{settings.max_obstacles} (max_obstacles, GCS_PPF_MAX_OBSTACLES)",
            {"field": "obstacles", "count": obstacles, "limit": settings.max_obstacles},
        )


@router.post(
    "/missions", status_code=status.HTTP_201_CREATED, responses=TOO_LARGE, dependencies=COMMANDS
)
async def create_mission(mission: Mission, service: Service) -> MissionDetail:
    check_size(service.settings, len(mission.vehicles), len(mission.obstacles))
    return mission_detail(service.create_mission(mission))


@router.get("/missions", dependencies=READ_ONLY)
async def list_missions(service: Service) -> list[MissionSummary]:
    return [mission_summary(m) for m in service.missions()]


@router.get("/missions/{mission_id}", responses=ERRORS, dependencies=READ_ONLY)
async def get_mission(mission_id: MissionId, service: Service) -> MissionDetail:
    return mission_detail(service.mission(mission_id))


@router.post("/missions/{mission_id}/plan", responses=ERRORS, dependencies=READ_ONLY)
async def plan(mission_id: MissionId, service: Service, every_s: float = 1.0) -> dict[str, Any]:
    """The offline plan from the same planner: metrics (CONVENTIONS §4) and the
    trajectories decimated to one point every ``every_s`` seconds."""
    from gcs_ppf.offline.plan import plan_mission

    mission = service.mission(mission_id).mission
    every_s = min(max(every_s, mission.planner.dt), 60.0)
    run = await asyncio.to_thread(plan_mission, mission)
    return {"metrics": run.metrics, "trajectories": decimated_trajectories(run, every_s)}


def decimated_trajectories(run: PlanRun, every_s: float) -> dict[str, dict[str, Any]]:
    """Each vehicle's times, positions and speeds every ``every_s`` seconds, the last
    record always kept, by vehicle id."""
    tr = run.trajectory
    step = max(1, round(every_s / run.dt))
    keep = list(range(0, len(tr), step)) + ([len(tr) - 1] if (len(tr) - 1) % step else [])
    return {
        str(vid): {
            "t": tr.t[keep].round(3).tolist(),
            "position_m": tr.pos[keep, i].round(2).tolist(),
            "speed_m_s": tr.speed[keep, i].round(2).tolist(),
        }
        for i, vid in enumerate(tr.ids.tolist())
    }


@router.put("/missions/{mission_id}/obstacles", responses=ERRORS | TOO_LARGE, dependencies=COMMANDS)
async def put_obstacles(
    mission_id: MissionId, obstacles: list[Obstacle], service: Service
) -> MissionDetail:
    check_size(service.settings, None, len(obstacles))
    return mission_detail(service.replace_obstacles(mission_id, obstacles))


UNREADABLE: dict[int | str, dict[str, Any]] = {
    422: {
        "model": ErrorBody | FieldErrors,
        "description": "a body that does not validate (field errors), or a document whose "
        "zones cannot be read (the feature and the field named)",
    }
}


@router.post(
    "/missions/{mission_id}/zones", responses={**ERRORS, **UNREADABLE}, dependencies=COMMANDS
)
async def post_zones(
    mission_id: MissionId,
    document: Annotated[dict[str, Any], Body()],
    service: Service,
    route: bool = False,
) -> MissionDetail:
    """The zones of a GeoJSON document or a QGroundControl ``.plan`` (the file's JSON as
    the body) added to the mission's (``gcs_ppf.zone_import``): 422 naming the feature and
    the field of the first that cannot be read, and nothing added.  With ``route`` (a
    ``.plan`` only), its waypoints become the mission's route and target as well
    (``gcs_ppf.plan_route``: takeoff, land, loiters and ``DO_`` items are left out; 409
    while the mission flies)."""
    try:
        zones = zones_from_document(document, required=not route)
        flown = None
        if route:
            plan = route_from_plan(document, service.mission(mission_id).mission.origin)
            flown = (plan.route, plan.target)
    except (ZoneImportError, RouteImportError) as exc:
        raise Unprocessable(f"zones: {exc}; nothing imported") from None
    return mission_detail(service.add_zones(mission_id, zones, flown))


@router.post(
    "/missions/{mission_id}/start",
    status_code=status.HTTP_202_ACCEPTED,
    responses=ERRORS,
    dependencies=COMMANDS,
)
async def start(
    mission_id: MissionId, service: Service, from_where_they_are: bool = False
) -> dict[str, Any]:
    """A run of the mission (202, ``starting``).  409 when a vehicle is not heard, heard
    on two links, inside a keep-out or far from its start position (each named), unless
    ``from_where_they_are`` for the last two: then the run starts as they are."""
    return await service.start(mission_id, from_where_they_are)


@router.post(
    "/missions/{mission_id}/resume",
    status_code=status.HTTP_202_ACCEPTED,
    responses=ERRORS,
    dependencies=COMMANDS,
)
async def resume(mission_id: MissionId, service: Service) -> dict[str, Any]:
    """The mission's ``interrupted`` run (the service stopped while it flew) flown on from
    where its record left it; 409 unless its last run is interrupted, or with a vehicle
    it had not lost unheard."""
    return await service.resume(mission_id)


@router.post(
    "/missions/{mission_id}/vehicles/{vehicle_id}/hand-back",
    responses=ERRORS,
    dependencies=COMMANDS,
)
async def hand_back(
    mission_id: MissionId, vehicle_id: SystemId, service: Service
) -> dict[str, Any]:
    """A vehicle another ground station took over (``vehicle_taken_over``) given back to
    the run: switched to GUIDED, confirmed, and commanded again; the run's status.  409
    unless the run flies and the vehicle was taken over."""
    return await service.hand_back(mission_id, vehicle_id)


@router.post("/missions/{mission_id}/abort", responses=ERRORS, dependencies=COMMANDS)
async def abort(mission_id: MissionId, service: Service) -> dict[str, Any]:
    """The run stopped (an ``interrupted`` one too): every vehicle holds clear of every
    keep-out."""
    return await service.abort(mission_id)


@router.get("/missions/{mission_id}/status", responses=ERRORS, dependencies=READ_ONLY)
async def mission_status(mission_id: MissionId, service: Service) -> dict[str, Any]:
    return service.status(mission_id)


@router.get("/missions/{mission_id}/events", responses=ERRORS, dependencies=READ_ONLY)
async def mission_events(mission_id: MissionId, service: Service) -> list[dict[str, Any]]:
    return service.events(mission_id)

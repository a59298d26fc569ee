"""The FastAPI app: thin routes over ``gcs_ppf.service.runs.FormationService``.

Every error a client can cause answers 4xx with a message a person understands:
422 for a body or path that does not validate (pydantic names the field), 404 for an
unknown id, 409 for a call in the wrong state; the stored state is left as it was.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from typing import Annotated, Any

from fastapi import Depends, FastAPI, Path, Request, WebSocket, WebSocketDisconnect, status
from fastapi.responses import JSONResponse
from pydantic import BaseModel, Field

from api import view
from gcs_ppf.mission import Mission, Obstacle
from gcs_ppf.service.errors import ServiceError
from gcs_ppf.service.runs import FormationService
from gcs_ppf.service.settings import Settings
from gcs_ppf.service.store import Store, StoredMission, StoredRun


class LinkRequest(BaseModel):
    """A MAVLink connection in pymavlink's syntax."""

    url: str = Field(min_length=1, max_length=300, examples=["tcp:127.0.0.1:5760"])


class MissionSummary(BaseModel):
    id: int
    name: str
    created_s: float
    vehicle_ids: list[int]


class MissionDetail(MissionSummary):
    mission: Mission


class RunSummary(BaseModel):
    id: int
    mission_id: int
    state: str
    started_s: float
    ended_s: float | None
    outcome: str | None
    summary: dict[str, Any] | None


class ErrorBody(BaseModel):
    detail: str
    info: dict[str, Any] = Field(default_factory=dict)


def _summary(m: StoredMission) -> MissionSummary:
    return MissionSummary(
        id=m.id, name=m.name, created_s=m.created_s, vehicle_ids=[v.id for v in m.mission.vehicles]
    )


def _detail(m: StoredMission) -> MissionDetail:
    return MissionDetail(**_summary(m).model_dump(), mission=m.mission)


def _run(r: StoredRun) -> RunSummary:
    return RunSummary.model_validate(r, from_attributes=True)


def get_service(request: Request) -> FormationService:
    service: FormationService = request.state.service
    return service


Service = Annotated[FormationService, Depends(get_service)]
# Ids are SQLite integers: anything outside 1 … 2⁶³−1 cannot exist (422, not a server error).
MissionId = Annotated[int, Path(ge=1, le=2**63 - 1)]
LinkId = Annotated[int, Path(ge=1, le=2**63 - 1)]
ERRORS: dict[int | str, dict[str, Any]] = {
    404: {"model": ErrorBody},
    409: {"model": ErrorBody},
    400: {"model": ErrorBody},
}


def create_app(settings: Settings | None = None) -> FastAPI:
    """The app; its lifespan opens the store and runs the service."""
    settings = settings or Settings()

    @contextlib.asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[dict[str, Any]]:
        store = Store(settings.db)
        try:
            service = FormationService(settings, store)
            async with service.running():
                yield {"service": service}
        finally:
            store.close()

    app = FastAPI(
        title="gcs-ppf",
        version="0.1.0",
        lifespan=lifespan,
        description="Fixed-wing formation planning (PPF) over MAVLink.",
    )

    @app.exception_handler(ServiceError)
    async def service_error(request: Request, exc: ServiceError) -> JSONResponse:
        return JSONResponse(
            status_code=exc.status, content={"detail": exc.message, "info": exc.detail}
        )

    @app.post("/links", status_code=status.HTTP_201_CREATED, responses=ERRORS)
    async def add_link(body: LinkRequest, service: Service) -> dict[str, Any]:
        return await service.fleet.add_link(body.url)

    @app.get("/links")
    async def list_links(service: Service) -> list[dict[str, Any]]:
        return service.fleet.links()

    @app.delete("/links/{link_id}", status_code=status.HTTP_204_NO_CONTENT, responses=ERRORS)
    async def delete_link(link_id: LinkId, service: Service) -> None:
        await service.fleet.remove_link(link_id)

    @app.get("/vehicles")
    async def list_vehicles(service: Service) -> list[dict[str, Any]]:
        return service.fleet.vehicles()

    @app.post("/missions", status_code=status.HTTP_201_CREATED)
    async def create_mission(mission: Mission, service: Service) -> MissionDetail:
        return _detail(service.create_mission(mission))

    @app.get("/missions")
    async def list_missions(service: Service) -> list[MissionSummary]:
        return [_summary(m) for m in service.missions()]

    @app.get("/missions/{mission_id}", responses=ERRORS)
    async def get_mission(mission_id: MissionId, service: Service) -> MissionDetail:
        return _detail(service.mission(mission_id))

    @app.post("/missions/{mission_id}/plan", responses=ERRORS)
    async def plan(mission_id: MissionId, service: Service, every_s: float = 1.0) -> dict[str, Any]:
        """The offline plan from the same planner: metrics (CONVENTIONS §4) and the
        trajectories decimated to one point every ``every_s`` seconds."""
        from gcs_ppf.offline.plan import plan_mission

        mission = service.mission(mission_id).mission
        every_s = min(max(every_s, mission.planner.dt), 60.0)
        run = await asyncio.to_thread(plan_mission, mission)
        tr = run.trajectory
        step = max(1, round(every_s / run.dt))
        keep = list(range(0, len(tr), step)) + ([len(tr) - 1] if (len(tr) - 1) % step else [])
        trajectories = {
            str(vid): {
                "t": tr.t[keep].round(3).tolist(),
                "position_m": tr.pos[keep, i].round(2).tolist(),
                "speed_m_s": tr.speed[keep, i].round(2).tolist(),
            }
            for i, vid in enumerate(tr.ids.tolist())
        }
        return {"metrics": run.metrics, "trajectories": trajectories}

    @app.put("/missions/{mission_id}/obstacles", responses=ERRORS)
    async def put_obstacles(
        mission_id: MissionId, obstacles: list[Obstacle], service: Service
    ) -> MissionDetail:
        return _detail(service.replace_obstacles(mission_id, obstacles))

    @app.post(
        "/missions/{mission_id}/start", status_code=status.HTTP_202_ACCEPTED, responses=ERRORS
    )
    async def start(mission_id: MissionId, service: Service) -> dict[str, Any]:
        return await service.start(mission_id)

    @app.post("/missions/{mission_id}/abort", responses=ERRORS)
    async def abort(mission_id: MissionId, service: Service) -> dict[str, Any]:
        return await service.abort(mission_id)

    @app.get("/missions/{mission_id}/status", responses=ERRORS)
    async def mission_status(mission_id: MissionId, service: Service) -> dict[str, Any]:
        return service.status(mission_id)

    @app.get("/missions/{mission_id}/events", responses=ERRORS)
    async def mission_events(mission_id: MissionId, service: Service) -> list[dict[str, Any]]:
        return service.events(mission_id)

    @app.get("/runs")
    async def list_runs(service: Service) -> list[RunSummary]:
        return [_run(r) for r in service.runs()]

    @app.websocket("/ws/telemetry")
    async def telemetry(websocket: WebSocket) -> None:
        service: FormationService = websocket.state.service
        await websocket.accept()
        queue = service.subscribe()
        try:
            await websocket.send_json(service.snapshot())
            while True:
                await websocket.send_json(await queue.get())
        except WebSocketDisconnect:
            pass
        finally:
            service.unsubscribe(queue)

    view.install(app)  # the operator's page and its read-only routes (api/view.py)
    return app

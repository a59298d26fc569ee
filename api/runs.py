"""Routes of runs: the stored runs, and the live telemetry of what flies (WS /ws/telemetry)."""

from __future__ import annotations

from fastapi import APIRouter, WebSocket, WebSocketDisconnect

from api.auth import WsCaller, accept
from api.deps import AUTH_ERRORS, READ_ONLY, Service
from api.models import RunSummary, run_summary
from gcs_ppf.service.runs import FormationService

router = APIRouter(responses=AUTH_ERRORS)


@router.get("/runs", dependencies=READ_ONLY)
async def list_runs(service: Service) -> list[RunSummary]:
    return [run_summary(r) for r in service.runs()]


@router.websocket("/ws/telemetry")
async def telemetry(websocket: WebSocket, _caller: WsCaller) -> None:
    service: FormationService = websocket.state.service
    await accept(websocket)
    queue = service.subscribe()
    try:
        await websocket.send_json(service.snapshot())
        while True:
            await websocket.send_json(await queue.get())
    except WebSocketDisconnect:
        pass
    finally:
        service.unsubscribe(queue)

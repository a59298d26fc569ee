"""Routes of runs: the stored runs, and the live telemetry of what flies (WS /ws/telemetry)."""

from __future__ import annotations

from fastapi import APIRouter, WebSocket, WebSocketDisconnect

from api.deps import Service
from api.models import RunSummary, run_summary
from gcs_ppf.service.runs import FormationService

router = APIRouter()


@router.get("/runs")
async def list_runs(service: Service) -> list[RunSummary]:
    return [run_summary(r) for r in service.runs()]


@router.websocket("/ws/telemetry")
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

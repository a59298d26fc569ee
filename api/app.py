"""The FastAPI app: thin routes over ``gcs_ppf.service.runs.FormationService``.

Every error a client can cause answers 4xx with a message a person understands:
422 for a body or path that does not validate (pydantic names the field), 404 for an
unknown id, 409 for a call in the wrong state; the stored state is left as it was.
The routes are routers per resource: ``api.fleet`` (links, vehicles), ``api.missions``,
``api.runs`` (runs, live telemetry); the operator's page is ``api.view``.
"""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator
from typing import Any

from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse

from api import fleet, missions, runs, view
from gcs_ppf.service.errors import ServiceError
from gcs_ppf.service.runs import FormationService
from gcs_ppf.service.settings import Settings
from gcs_ppf.service.store import Store


async def service_error(request: Request, exc: ServiceError) -> JSONResponse:
    """A ServiceError as its HTTP status and ``{"detail": message, "info": detail}``."""
    return JSONResponse(status_code=exc.status, content={"detail": exc.message, "info": exc.detail})


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
    app.exception_handler(ServiceError)(service_error)
    for router in (fleet.router, missions.router, runs.router):
        app.include_router(router)
    view.install(app)  # the operator's page and its read-only routes (api/view.py)
    return app

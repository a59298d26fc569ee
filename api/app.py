"""The FastAPI app: thin routes over ``gcs_ppf.service.runs.FormationService``.

Every error a client can cause answers 4xx with a message a person understands:
422 for a body or path that does not validate (pydantic names the field), 404 for an
unknown id, 409 for a call in the wrong state, 413 for a document too large; the stored
state is left as it was.  Who may call what is ``api.auth`` (bearer tokens, scopes); request
sizes and the audit log are ``api.guard``.  The routes are routers per resource:
``api.fleet`` (links, vehicles), ``api.missions``, ``api.runs`` (runs, live telemetry); the
operator's page is ``api.view``.
"""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator
from typing import Any

from fastapi import FastAPI, Request
from fastapi.encoders import jsonable_encoder
from fastapi.exception_handlers import http_exception_handler
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, Response
from starlette.exceptions import HTTPException as StarletteHTTPException

from api import fleet, missions, runs, view
from api.auth import Keyring, check_exposure
from api.guard import AuditLog, Guard
from gcs_ppf.service.errors import ServiceError
from gcs_ppf.service.runs import FormationService
from gcs_ppf.service.settings import Settings
from gcs_ppf.service.store import Store


async def service_error(request: Request, exc: ServiceError) -> JSONResponse:
    """A ServiceError as its HTTP status and ``{"detail": message, "info": detail}``."""
    return JSONResponse(status_code=exc.status, content={"detail": exc.message, "info": exc.detail})


ECHO_CHARS = 200  # a 422's field error quotes the input it rejects up to this many characters


async def validation_error(request: Request, exc: RequestValidationError) -> JSONResponse:
    """FastAPI's 422 body, but never echoing back more than ``ECHO_CHARS`` of the input."""
    errors = []
    for error in jsonable_encoder(exc.errors()):
        if "input" in error and len(text := repr(error["input"])) > ECHO_CHARS:
            error["input"] = text[:ECHO_CHARS] + f"… ({len(text)} characters)"
        errors.append(error)
    return JSONResponse(status_code=422, content={"detail": errors})


UNREADABLE_BODY = "There was an error parsing the body"
"""FastAPI's 400 for a body it cannot decode at all (not UTF-8, say), where a body that is
not JSON is a 422 (``json_invalid``)."""


async def http_error(request: Request, exc: StarletteHTTPException) -> Response:
    """A body that cannot be decoded is a body that does not validate: 422, as documented
    on every route that takes one (schemathesis found the undocumented 400 on POST
    /missions with a body of bytes that are not UTF-8)."""
    if exc.status_code == 400 and exc.detail == UNREADABLE_BODY:
        error = {"type": "json_invalid", "loc": ["body"], "msg": "the body is not UTF-8 JSON"}
        return JSONResponse(status_code=422, content={"detail": [error]})
    return await http_exception_handler(request, exc)


def create_app(settings: Settings | None = None) -> FastAPI:
    """The app; its lifespan opens the store and runs the service.  Raises
    ``ExposureError`` for an open API (no tokens) on an address that is not loopback, and
    ``TokenFileError`` for a token file that cannot be read."""
    settings = settings or Settings()
    keyring = Keyring(settings.api_tokens())
    check_exposure(settings, keyring)

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
    app.state.keyring = keyring
    app.exception_handler(ServiceError)(service_error)
    app.exception_handler(RequestValidationError)(validation_error)
    app.exception_handler(StarletteHTTPException)(http_error)

    @app.get("/health", tags=["health"])
    async def health() -> dict[str, str]:
        """The one route without a token: the service is up."""
        return {"status": "ok"}

    for router in (fleet.router, missions.router, runs.router):
        app.include_router(router)
    view.install(app)  # the operator's page and its read-only routes (api/view.py)
    app.add_middleware(
        Guard, max_body_bytes=settings.max_body_bytes, audit=AuditLog(settings.audit_path())
    )
    return app

"""What every router shares: the service the lifespan runs, the ids in paths, the error bodies,
the security dependencies of routes that read (``READ_ONLY``) and that command (``COMMANDS``)."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import Depends, Path, Request

from api.auth import COMMAND, READ
from api.models import ErrorBody
from gcs_ppf.service.runs import FormationService


def get_service(request: Request) -> FormationService:
    service: FormationService = request.state.service
    return service


Service = Annotated[FormationService, Depends(get_service)]
# Ids are SQLite integers: anything outside 1 … 2⁶³−1 cannot exist (422, not a server error).
MissionId = Annotated[int, Path(ge=1, le=2**63 - 1)]
LinkId = Annotated[int, Path(ge=1, le=2**63 - 1)]
SystemId = Annotated[int, Path(ge=1, le=255, description="a vehicle's MAVLink system id")]
ERRORS: dict[int | str, dict[str, Any]] = {
    404: {"model": ErrorBody},
    409: {"model": ErrorBody},
    400: {"model": ErrorBody},
}
# What every route may answer besides: no or a bad token, a token without the scope.
AUTH_ERRORS: dict[int | str, dict[str, Any]] = {
    401: {"model": ErrorBody, "description": "no bearer token, or one the service does not know"},
    403: {"model": ErrorBody, "description": "the token lacks the scope the route needs"},
}
READ_ONLY = [READ]
COMMANDS = [COMMAND]

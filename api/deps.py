"""What every router shares: the service the lifespan runs, the ids in paths, the error bodies."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import Depends, Path, Request

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

"""The API's request and response bodies, and how the store's records become them."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, Field

from gcs_ppf.mission import Mission
from gcs_ppf.service.store import StoredMission, StoredRun


class LinkRequest(BaseModel):
    """A MAVLink connection in pymavlink's syntax."""

    url: str = Field(min_length=1, max_length=300, examples=["tcp:127.0.0.1:5760"])
    allow_unsigned: bool | None = Field(
        default=None,
        description="with a signing key: accept unsigned frames on this link (a vehicle that "
        "does not sign); unset: whether the URL is in the settings' unsigned_links",
    )


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


class FieldErrors(BaseModel):
    """FastAPI's 422 for a body or path that does not validate: pydantic's field errors."""

    detail: list[dict[str, Any]]


def mission_summary(m: StoredMission) -> MissionSummary:
    return MissionSummary(
        id=m.id, name=m.name, created_s=m.created_s, vehicle_ids=[v.id for v in m.mission.vehicles]
    )


def mission_detail(m: StoredMission) -> MissionDetail:
    return MissionDetail(**mission_summary(m).model_dump(), mission=m.mission)


def run_summary(r: StoredRun) -> RunSummary:
    return RunSummary.model_validate(r, from_attributes=True)

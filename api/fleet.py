"""Routes of the fleet: MAVLink links (added, listed, removed) and the vehicles heard on them."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, status

from api.deps import ERRORS, LinkId, Service, SystemId
from api.models import LinkRequest

router = APIRouter()


@router.post("/links", status_code=status.HTTP_201_CREATED, responses=ERRORS)
async def add_link(body: LinkRequest, service: Service) -> dict[str, Any]:
    return await service.fleet.add_link(body.url, allow_unsigned=body.allow_unsigned)


@router.get("/links")
async def list_links(service: Service) -> list[dict[str, Any]]:
    return service.fleet.links()


@router.delete("/links/{link_id}", status_code=status.HTTP_204_NO_CONTENT, responses=ERRORS)
async def delete_link(link_id: LinkId, service: Service) -> None:
    await service.fleet.remove_link(link_id)


@router.post("/vehicles/{system_id}/signing", responses=ERRORS)
async def setup_signing(system_id: SystemId, service: Service) -> dict[str, Any]:
    """Install the service's MAVLink signing key on the vehicle (SETUP_SIGNING): from then
    on it signs, and refuses unsigned commands.  The key itself is never answered."""
    return await service.fleet.setup_signing(system_id)


@router.get("/vehicles")
async def list_vehicles(service: Service) -> list[dict[str, Any]]:
    return service.fleet.vehicles()

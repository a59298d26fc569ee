"""Routes of the fleet: MAVLink links (added, listed, removed) and the vehicles heard on them."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, status

from api.deps import ERRORS, LinkId, Service
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


@router.get("/vehicles")
async def list_vehicles(service: Service) -> list[dict[str, Any]]:
    return service.fleet.vehicles()

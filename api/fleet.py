"""Routes of the fleet: MAVLink links (added, listed, removed) and the vehicles heard on them."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, status

from api.auth import link_allowed
from api.deps import AUTH_ERRORS, COMMANDS, ERRORS, READ_ONLY, LinkId, Service, SystemId
from api.models import LinkRequest
from gcs_ppf.service.errors import Forbidden
from gcs_ppf.service.links import parse_link_url

router = APIRouter(responses=AUTH_ERRORS)


@router.post("/links", status_code=status.HTTP_201_CREATED, responses=ERRORS, dependencies=COMMANDS)
async def add_link(body: LinkRequest, service: Service) -> dict[str, Any]:
    """A link to a loopback address, to a host or network of the settings' ``link_allow``,
    or to a serial device it names (403 otherwise: the service would connect wherever it is
    told, and open whatever device)."""
    try:
        host = parse_link_url(body.url).host
    except ValueError:
        host = None  # the service names what is wrong with the URL
    if host is not None and not link_allowed(host, service.settings.link_allow):
        if host.startswith("/"):
            raise Forbidden(
                f"url: {host} is not a serial terminal (/dev/tty*, /dev/pts/*, /dev/serial/*) nor "
                "in the service's link_allow (GCS_PPF_LINK_ALLOW='[\"/opt/radio*\"]')",
                {"host": host},
            )
        raise Forbidden(
            f"url: {host} is neither loopback nor in the service's link_allow "
            '(GCS_PPF_LINK_ALLOW=\'["HOST", "10.0.0.0/24"]\')',
            {"host": host},
        )
    return await service.add_link(body.url, allow_unsigned=body.allow_unsigned)


@router.get("/links", dependencies=READ_ONLY)
async def list_links(service: Service) -> list[dict[str, Any]]:
    return service.fleet.links()


@router.get("/forwards", dependencies=READ_ONLY)
async def list_forwards(service: Service) -> list[dict[str, Any]]:
    """The other ground stations the vehicles' frames are relayed to (``--forward``): each
    endpoint's URL, whether a GCS is there, frames in and out, frames dropped."""
    forwarding = service.fleet.forwarding
    return [] if forwarding is None else forwarding.info()


@router.delete(
    "/links/{link_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    responses=ERRORS,
    dependencies=COMMANDS,
)
async def delete_link(link_id: LinkId, service: Service) -> None:
    await service.remove_link(link_id)


@router.post("/vehicles/{system_id}/signing", responses=ERRORS, dependencies=COMMANDS)
async def setup_signing(system_id: SystemId, service: Service) -> dict[str, Any]:
    """Install the service's MAVLink signing key on the vehicle (SETUP_SIGNING): from then
    on it signs, and refuses unsigned commands.  The key itself is never answered."""
    return await service.fleet.setup_signing(system_id)


@router.get("/vehicles", dependencies=READ_ONLY)
async def list_vehicles(service: Service) -> list[dict[str, Any]]:
    return service.fleet.vehicles()

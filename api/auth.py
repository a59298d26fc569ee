"""Who may call the API: bearer tokens with scopes, checked by FastAPI's security
dependencies (``HTTPBearer``, ``SecurityScopes``), and where links may go.

* Every route but ``GET /health`` (and the static files of the page and the API's own
  documentation, which hold no data) depends on ``READ`` or ``COMMAND``: no or an unknown
  token → 401 (with ``WWW-Authenticate: Bearer``), a token without the scope → 403.
* The WebSockets take the token as ``Authorization: Bearer TOKEN`` or, from a browser
  (which cannot set headers on a WebSocket), as the subprotocol ``bearer.TOKEN`` beside
  ``gcs-ppf`` (the one the service answers with), so that it never appears in a URL or an
  access log; without a valid one the handshake is refused (close code 1008, HTTP 403).
* With no token configured the API is *open*: every caller is ``open`` with every scope.
  ``check_exposure`` refuses that on any address but loopback.
"""

from __future__ import annotations

import fnmatch
import ipaddress
import os
from dataclasses import dataclass
from typing import Annotated

from fastapi import Depends, HTTPException, Request, Security, WebSocket, WebSocketException
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer, SecurityScopes
from fastapi.security.utils import get_authorization_scheme_param
from starlette.status import WS_1008_POLICY_VIOLATION

from gcs_ppf.service.settings import Settings
from gcs_ppf.tokens import SCOPES, Scope, TokenEntry, grants, token_hash

OPEN_ID = "open"
WS_SUBPROTOCOL = "gcs-ppf"
WS_TOKEN_PREFIX = "bearer."
HOW_TO = (
    "make one with `gcs-ppf token NAME --file tokens.json` and start the service with "
    "--token-file tokens.json (or GCS_PPF_TOKEN_FILE=tokens.json, or GCS_PPF_TOKENS)"
)

bearer = HTTPBearer(
    auto_error=False,
    description="a token of `gcs-ppf token`; scopes `read` (GETs, streams) and `command`",
)


@dataclass(frozen=True)
class Caller:
    """Who a request comes from: a token's id (``open`` without tokens) and its scopes."""

    token_id: str
    scopes: tuple[Scope, ...]


class Keyring:
    """The tokens the service accepts, by hash (the tokens themselves are not kept)."""

    def __init__(self, entries: list[TokenEntry]) -> None:
        self.by_hash = {e.sha256: e for e in entries}

    @property
    def open(self) -> bool:
        return not self.by_hash

    def identify(self, token: str | None, scopes: list[str]) -> Caller:
        """Who holds ``token`` (``open`` without tokens), whatever their scopes; raises 401
        for no or an unknown token."""
        if self.open:
            return Caller(OPEN_ID, SCOPES)
        challenge = {"WWW-Authenticate": f'Bearer scope="{" ".join(scopes) or "read"}"'}
        if not token:
            raise HTTPException(
                401, "a bearer token is needed (Authorization: Bearer TOKEN)", challenge
            )
        entry = self.by_hash.get(token_hash(token))
        if entry is None:
            raise HTTPException(401, "the bearer token is not one this service knows", challenge)
        return Caller(entry.id, entry.scopes)

    def caller(self, token: str | None, scopes: list[str]) -> Caller:
        """The caller holding ``token``; raises 401 (no or unknown token) or 403 (a scope of
        ``scopes`` missing)."""
        return require(self.identify(token, scopes), scopes)


def require(caller: Caller, scopes: list[str]) -> Caller:
    """``caller`` if it holds every scope of ``scopes`` (``command`` includes ``read``),
    else 403."""
    missing = [s for s in scopes if not grants(caller.scopes, s)]
    if missing:
        needed = " ".join(scopes)
        raise HTTPException(
            403,
            f"token {caller.token_id!r} lacks the scope {' '.join(missing)!r} this request needs",
            {"WWW-Authenticate": f'Bearer error="insufficient_scope" scope="{needed}"'},
        )
    return caller


def keyring_of(request: Request) -> Keyring:
    keyring: Keyring = request.app.state.keyring
    return keyring


async def authorize(
    security_scopes: SecurityScopes,
    request: Request,
    credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer)],
) -> Caller:
    """The caller of an HTTP request, who must hold ``security_scopes``; recorded in the
    request's state for the audit log (``api.guard``)."""
    request.state.token_id = None
    caller = keyring_of(request).identify(
        None if credentials is None else credentials.credentials, security_scopes.scopes
    )
    request.state.token_id = caller.token_id
    return require(caller, security_scopes.scopes)


READ = Security(authorize, scopes=["read"])
COMMAND = Security(authorize, scopes=["command"])


def ws_token(websocket: WebSocket) -> str | None:
    """The token of a WebSocket handshake: its Authorization header, else its subprotocol
    ``bearer.TOKEN``."""
    scheme, token = get_authorization_scheme_param(websocket.headers.get("authorization"))
    if scheme.lower() == "bearer" and token:
        return token
    for protocol in websocket.scope.get("subprotocols", []):
        if protocol.startswith(WS_TOKEN_PREFIX):
            return str(protocol)[len(WS_TOKEN_PREFIX) :]
    return None


async def authorize_ws(websocket: WebSocket) -> Caller:
    """The caller of a WebSocket, who must hold ``read``; refuses the handshake otherwise."""
    keyring: Keyring = websocket.app.state.keyring
    try:
        return keyring.caller(ws_token(websocket), ["read"])
    except HTTPException as exc:
        raise WebSocketException(WS_1008_POLICY_VIOLATION, str(exc.detail)) from None


WsCaller = Annotated[Caller, Depends(authorize_ws)]


async def accept(websocket: WebSocket) -> None:
    """Accept, answering the subprotocol ``gcs-ppf`` when the client offered it (a browser
    that offered subprotocols drops a connection that answers none)."""
    offered = websocket.scope.get("subprotocols", [])
    await websocket.accept(subprotocol=WS_SUBPROTOCOL if WS_SUBPROTOCOL in offered else None)


def is_loopback(host: str) -> bool:
    """``localhost`` or a loopback address (127.0.0.0/8, ::1); names are not resolved."""
    host = host.strip().strip("[]").lower()
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class ExposureError(ValueError):
    """An open API (no tokens) asked to listen beyond loopback."""


def check_exposure(settings: Settings, keyring: Keyring) -> None:
    if keyring.open and not is_loopback(settings.host):
        raise ExposureError(
            f"host {settings.host}: no API token is configured, and without one the API "
            f"answers anyone, so it listens on loopback only; {HOW_TO}"
        )


SERIAL_DEVICES = ("/dev/tty*", "/dev/pts/*", "/dev/serial/*", "/dev/rfcomm*")
"""Serial devices ``POST /links`` may open without ``link_allow`` naming them: terminals
(USB radios are /dev/ttyUSB*, /dev/ttyACM*), pseudo-terminals, udev's /dev/serial links,
Bluetooth serial."""


def link_allowed(host: str, allow: list[str]) -> bool:
    """May ``POST /links`` connect to (or listen on) ``host``: loopback, a name or address
    of ``allow`` (case-insensitive, not resolved), or an address in one of its networks;
    a serial device (a path) if it is, or links to, a terminal of ``SERIAL_DEVICES``, or
    ``allow`` names it or a pattern of it: the service opens whatever device it is told,
    and no other device file is a radio."""
    if host.startswith("/"):
        paths = (host, os.path.realpath(host))
        patterns = [*SERIAL_DEVICES, *(e for e in allow if e.startswith("/"))]
        return any(fnmatch.fnmatchcase(p, pattern) for p in paths for pattern in patterns)
    if is_loopback(host):
        return True
    host = host.strip("[]").lower()
    try:
        address: ipaddress.IPv4Address | ipaddress.IPv6Address | None = ipaddress.ip_address(host)
    except ValueError:
        address = None
    for entry in allow:
        entry = entry.strip().lower()
        if entry == host:
            return True
        if address is not None and "/" in entry:
            try:
                if address in ipaddress.ip_network(entry, strict=False):
                    return True
            except ValueError:
                continue
    return False

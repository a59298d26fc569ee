"""The API's outer wall, as plain ASGI middleware: request bodies limited in size (413
before the app reads them) and the audit log of command requests.

Every request that is not a GET, HEAD or OPTIONS (the ones that can change the service or
the vehicles: missions stored, obstacles replaced, starts, aborts, links added and removed;
and the offline plans) is one JSON line in the audit log, written when its answer has been
sent, refused ones included: ``time`` (ISO 8601, UTC), ``token_id`` (who: the token's id,
``open`` without tokens, null when no valid token came), ``client``, ``method``, ``path``,
``query``, ``body`` (the JSON of bodies up to ``AUDIT_BODY_BYTES``, otherwise its size and
SHA-256), ``status`` and ``outcome`` (``ok`` or the answer's ``detail``).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import logging
from pathlib import Path
from typing import Any

from starlette.types import ASGIApp, Message, Receive, Scope, Send

log = logging.getLogger("gcs_ppf.audit")

AUDITED = frozenset({"POST", "PUT", "PATCH", "DELETE"})
AUDIT_BODY_BYTES = 2048
DETAIL_CHARS = 500


def body_record(body: bytes) -> Any:
    """What the audit log keeps of a request body."""
    if not body:
        return None
    if len(body) <= AUDIT_BODY_BYTES:
        try:
            return json.loads(body)
        except ValueError:
            pass
    return {"bytes": len(body), "sha256": hashlib.sha256(body).hexdigest()}


def outcome(status: int, response_body: bytes) -> str:
    """``ok`` for a 2xx/3xx, else the answer's ``detail`` (422: its first field error)."""
    if status < 400:
        return "ok"
    try:
        detail = json.loads(response_body).get("detail")
    except (ValueError, AttributeError):
        detail = None
    if isinstance(detail, list) and detail and isinstance(detail[0], dict):
        first = detail[0]
        detail = f"{'.'.join(str(p) for p in first.get('loc', []))}: {first.get('msg')}"
    text = str(detail) if detail is not None else f"HTTP {status}"
    return text[:DETAIL_CHARS]


class AuditLog:
    """Appends one JSON line per record to ``path`` (None: logs nothing)."""

    def __init__(self, path: Path | None) -> None:
        self.path = path
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)

    def write(self, record: dict[str, Any]) -> None:
        if self.path is None:
            return
        try:
            with self.path.open("a", encoding="utf-8") as f:
                f.write(json.dumps(record, separators=(",", ":")) + "\n")
        except OSError as exc:  # the request was answered; say loudly that it went unlogged
            log.error("audit log %s: %s; unrecorded: %s", self.path, exc, record)


async def _read_body(receive: Receive, limit: int) -> bytes | None:
    """The whole body, or None once it exceeds ``limit`` bytes (the rest is not read)."""
    chunks: list[bytes] = []
    size = 0
    while True:
        message = await receive()
        if message["type"] != "http.request":
            break  # the client went away: the app sees an empty body
        chunk = message.get("body", b"")
        size += len(chunk)
        if size > limit:
            return None
        chunks.append(chunk)
        if not message.get("more_body", False):
            break
    return b"".join(chunks)


async def _send_json(send: Send, status: int, content: dict[str, Any]) -> None:
    body = json.dumps(content).encode()
    headers = [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]
    await send({"type": "http.response.start", "status": status, "headers": headers})
    await send({"type": "http.response.body", "body": body})


class Guard:
    """Limits request bodies to ``max_body_bytes`` and audits command requests."""

    def __init__(self, app: ASGIApp, max_body_bytes: int, audit: AuditLog) -> None:
        self.app = app
        self.max_body_bytes = max_body_bytes
        self.audit = audit

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        declared = dict(scope["headers"]).get(b"content-length")
        too_big = {
            "detail": f"request body larger than {self.max_body_bytes} bytes "
            "(the service's max_body_bytes, GCS_PPF_MAX_BODY_BYTES)"
        }
        body: bytes | None = b""
        if declared is not None and declared.isdigit() and int(declared) > self.max_body_bytes:
            body = None
        else:
            body = await _read_body(receive, self.max_body_bytes)
        audited = scope["method"] in AUDITED
        if body is None:
            await _send_json(send, 413, too_big)
            if audited:
                self._record(scope, b"", 413, json.dumps(too_big).encode())
            return
        replayed = False

        async def replay() -> Message:
            nonlocal replayed
            if not replayed:
                replayed = True
                return {"type": "http.request", "body": body, "more_body": False}
            return await receive()

        status = 500
        answer: list[bytes] = []

        async def watch(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = int(message["status"])
            elif (
                message["type"] == "http.response.body"
                and status >= 400
                and sum(map(len, answer)) < 4 * DETAIL_CHARS
            ):
                answer.append(message.get("body", b""))
            await send(message)

        try:
            await self.app(scope, replay, watch)
        finally:
            if audited:
                self._record(scope, body, status, b"".join(answer))

    def _record(self, scope: Scope, body: bytes, status: int, answer: bytes) -> None:
        state = scope.get("state") or {}
        client = scope.get("client")
        self.audit.write(
            {
                "time": dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds"),
                "token_id": state.get("token_id"),
                "client": None if client is None else f"{client[0]}:{client[1]}",
                "method": scope["method"],
                "path": scope["path"],
                "query": scope.get("query_string", b"").decode("latin-1"),
                "body": body_record(body),
                "status": status,
                "outcome": outcome(status, answer),
            }
        )

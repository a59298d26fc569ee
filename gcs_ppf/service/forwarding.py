"""Forwarding to other ground stations beside the service, as mavlink-router does.

Each ``--forward`` endpoint is another GCS (QGroundControl, MAVProxy, a pymavlink script):
``udpout:HOST:PORT`` sends to one listening there (QGroundControl listens on udp 14550),
``udpin:HOST:PORT`` waits for one to send first, ``tcpin:HOST:PORT`` accepts any number
that connect.  Every frame a vehicle sends is relayed to every endpoint unchanged, once (a
vehicle heard on two links is relayed from the link it is commanded on); what a GCS sends
goes to the vehicle it addresses (``target_system``; to every link when it addresses none)
and to the other endpoints.  The service's own frames are not relayed: another GCS sees the
vehicles and the other ground stations, never the service's commands.  A frame from another
GCS that takes a vehicle's flight (``gcs_ppf.mavlink.takeover``) is told to ``on_takeover``.
"""

from __future__ import annotations

import asyncio
import logging
import socket
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from gcs_ppf.mavlink.codec import Codec, MAVLinkMessage
from gcs_ppf.mavlink.takeover import taken_over
from gcs_ppf.service.links import (
    FORWARD_BUFFER_BYTES,
    LinkKind,
    LinkUrl,
    MavlinkLink,
    parse_forward_url,
)

log = logging.getLogger(__name__)

ToVehicles = Callable[[int | None, bytes], None]
"""Relays a frame to the vehicle with that system id (None: to every link)."""
OnTakeover = Callable[[int, str, tuple[int, int]], None]
"""(vehicle id, what took it, (system, component) of the GCS that sent it)."""


class Endpoint(Protocol):
    url: str

    async def run(self) -> None: ...

    def close(self) -> None: ...

    def forward_frame(self, frame: bytes) -> bool: ...

    def info(self) -> dict[str, Any]: ...


@dataclass
class _Client:
    writer: asyncio.StreamWriter
    codec: Codec


class TcpServerEndpoint:
    """``tcpin:HOST:PORT``: ground stations connect; each one is relayed to and from."""

    def __init__(self, url: str, parsed: LinkUrl, on_message: Callable[[Any, Any], None]) -> None:
        self.url = url
        self._parsed = parsed
        self._on_message = on_message
        self._clients: list[_Client] = []
        self._server: asyncio.Server | None = None
        self.frames_out = 0
        self.dropped_out = 0
        self.frames_in = 0

    async def run(self) -> None:
        self._server = await asyncio.start_server(
            self._serve, self._parsed.host, self._parsed.port, reuse_address=True
        )
        log.info("forward %s: listening", self.url)
        async with self._server:
            await self._server.serve_forever()

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        sock = writer.get_extra_info("socket")
        if sock is not None:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        client = _Client(writer, Codec(accept_unsigned=True))
        self._clients.append(client)
        log.info("forward %s: %s connected", self.url, writer.get_extra_info("peername"))
        try:
            while data := await reader.read(65536):
                for msg in client.codec.parse(data):
                    self.frames_in += 1
                    self._on_message(self, msg)
        except (OSError, EOFError):
            pass
        finally:
            self._clients.remove(client)
            writer.close()
            log.info("forward %s: a ground station left", self.url)

    def forward_frame(self, frame: bytes) -> bool:
        sent = False
        for client in self._clients:
            if client.writer.is_closing():
                continue
            if client.writer.transport.get_write_buffer_size() > FORWARD_BUFFER_BYTES:
                self.dropped_out += 1
                continue
            client.writer.write(frame)
            self.frames_out += 1
            sent = True
        return sent

    def close(self) -> None:
        if self._server is not None:
            self._server.close()
        for client in list(self._clients):
            client.writer.close()

    def info(self) -> dict[str, Any]:
        return {
            "url": self.url,
            "connected": bool(self._clients),
            "clients": len(self._clients),
            "frames_in": self.frames_in,
            "frames_out": self.frames_out,
            "dropped_out": self.dropped_out,
        }


class UdpEndpoint:
    """``udpout:`` / ``udpin:``: one ground station over UDP (a ``MavlinkLink``)."""

    def __init__(self, url: str, on_message: Callable[[Any, Any], None]) -> None:
        self.url = url
        self.link = MavlinkLink(url, lambda _link, msg: on_message(self, msg), accept_unsigned=True)

    async def run(self) -> None:
        await self.link.run()

    def forward_frame(self, frame: bytes) -> bool:
        return self.link.forward_frame(frame)

    def close(self) -> None:
        self.link.close()

    def info(self) -> dict[str, Any]:
        s = self.link.stats
        return {
            "url": self.url,
            "connected": self.link.connected,
            "clients": 1 if self.link.connected else 0,
            "frames_in": s.messages_in,
            "frames_out": s.messages_out,
            "dropped_out": s.dropped_out,
        }


class Forwarding:
    """The service's ``--forward`` endpoints; see the module docstring."""

    def __init__(
        self,
        urls: list[str],
        *,
        system_id: int,
        to_vehicles: ToVehicles,
        on_takeover: OnTakeover,
    ) -> None:
        self._system_id = system_id
        self._to_vehicles = to_vehicles
        self._on_takeover = on_takeover
        self._warned: set[tuple[str, int]] = set()
        self.endpoints: list[Endpoint] = []
        for url in urls:
            parsed = parse_forward_url(url)
            if parsed.kind is LinkKind.TCP:
                self.endpoints.append(TcpServerEndpoint(url, parsed, self._from_gcs))
            else:
                self.endpoints.append(UdpEndpoint(url, self._from_gcs))

    async def run(self) -> None:
        """Every endpoint, until cancelled; one that cannot listen is logged, not fatal."""
        await asyncio.gather(*(self._run(e) for e in self.endpoints))

    async def _run(self, endpoint: Endpoint) -> None:
        try:
            await endpoint.run()
        except OSError as exc:
            log.error("forward %s: %s", endpoint.url, exc)

    def close(self) -> None:
        for endpoint in self.endpoints:
            endpoint.close()

    def from_vehicles(self, frame: bytes) -> None:
        """A vehicle's frame, to every endpoint."""
        for endpoint in self.endpoints:
            endpoint.forward_frame(frame)

    def _from_gcs(self, endpoint: Endpoint, msg: MAVLinkMessage) -> None:
        frame = bytes(msg.get_msgbuf())
        sender = (int(msg.get_srcSystem()), int(msg.get_srcComponent()))
        same_id = msg.get_type() == "HEARTBEAT" and sender[0] == self._system_id
        if same_id and (endpoint.url, sender[0]) not in self._warned:
            self._warned.add((endpoint.url, sender[0]))
            log.warning(
                "forward %s: a ground station there uses the service's own system id "
                "%d: the vehicles cannot tell the two apart (start the service with "
                "GCS_PPF_SYSTEM_ID, or give that GCS another MAVLink system id)",
                endpoint.url,
                sender[0],
            )
        for other in self.endpoints:
            if other is not endpoint:
                other.forward_frame(frame)
        target = int(getattr(msg, "target_system", 0)) or None
        self._to_vehicles(target, frame)
        vehicle = taken_over(msg)
        if vehicle is not None:
            kind = msg.get_type()
            what = f"{kind} {int(msg.command)}" if kind.startswith("COMMAND_") else kind
            try:
                self._on_takeover(vehicle, what, sender)
            except Exception:
                log.exception(
                    "forward %s: telling the takeover of %d failed", endpoint.url, vehicle
                )

    def info(self) -> list[dict[str, Any]]:
        return [e.info() for e in self.endpoints]

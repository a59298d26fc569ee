"""asyncio MAVLink links (TCP client, UDP server, UDP client, serial device) that reconnect,
with a tlog.

A ``MavlinkLink`` owns one transport, one ``Codec`` and optionally one tlog file.  ``run()``
connects, reads and hands every decoded message to ``on_message``; when the connection fails or
ends it waits (exponential backoff) and connects again, until ``close()``.  URLs use pymavlink's
syntax: ``tcp:HOST:PORT`` (client), ``udpin:HOST:PORT`` and ``udp:HOST:PORT`` (listen; answer each
system where it was heard from, the last sender for one not heard: ``udp:`` listens in
pymavlink too), ``udpout:HOST:PORT`` (send to HOST:PORT), and a
serial device at a baud rate: ``serial:/dev/ttyUSB0:57600``, or pymavlink's ``/dev/ttyUSB0,57600``
(a telemetry radio; pyserial-asyncio's transport; a device that goes away, a radio
unplugged, is opened again as a TCP peer is connected again).

The tlog is the format MAVProxy writes and ``mavlogdump.py`` reads: every frame in and out,
each preceded by its UNIX time in microseconds as an 8-byte big-endian integer.
"""

from __future__ import annotations

import asyncio
import contextlib
import enum
import logging
import math
import socket
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import IO

import serial_asyncio

from gcs_ppf.datagrams import DatagramSocket
from gcs_ppf.mavlink.ardupilot import GCS_COMPONENT_ID, GCS_SYSTEM_ID
from gcs_ppf.mavlink.codec import Codec, MAVLinkMessage, message_id, signing_timestamp

log = logging.getLogger(__name__)

_READ_SIZE = 65536
_SETUP_SIGNING_ID = 256
"""SETUP_SIGNING carries a signing key: never written to a tlog."""
_TLOG_FLUSH_S = 1.0
FORWARD_BUFFER_BYTES = 1 << 18
"""Unsent bytes to a peer beyond which forwarded frames are dropped (it is not reading)."""
REFUSED_LOG_PERIOD_S = 10.0
"""Frames refused for their signature are logged at the first, then at most this often..."""
REFUSED_NEWS_LOG_PERIOD_S = 1.0
"""...or this often when a new sender, or a kind of refusal not seen before, appears."""


class LinkKind(enum.StrEnum):
    TCP = "tcp"
    """TCP client: connects to HOST:PORT (ArduPilot SITL serves MAVLink on tcp 5760)."""
    UDP_IN = "udpin"
    """UDP server: binds HOST:PORT and sends to whoever sent last."""
    UDP_OUT = "udpout"
    """UDP client: sends to HOST:PORT and reads its answers."""
    SERIAL = "serial"
    """Serial device at a baud rate (a telemetry radio on USB: ``serial:/dev/ttyUSB0:57600``)."""


@dataclass(frozen=True, slots=True)
class LinkUrl:
    """A parsed link URL.  For SERIAL, ``host`` is the device path and ``port`` the baud rate."""

    kind: LinkKind
    host: str
    port: int

    def __str__(self) -> str:
        if self.kind is LinkKind.SERIAL:
            return f"serial:{self.host}:{self.port}"
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{self.kind}:{host}:{self.port}"


_SCHEMES = {
    "tcp": LinkKind.TCP,
    "udpin": LinkKind.UDP_IN,
    "udp": LinkKind.UDP_IN,
    "udpout": LinkKind.UDP_OUT,
}


def parse_link_url(url: str) -> LinkUrl:
    """Parse ``tcp:HOST:PORT``, ``udpin:HOST:PORT``, ``udp:HOST:PORT``, ``udpout:HOST:PORT``,
    ``serial:DEVICE[:BAUD]`` and pymavlink's ``DEVICE[,BAUD]`` (``/dev/ttyUSB0,57600``,
    ``COM3,115200``; baud 57600, a SiK radio's, when not given).

    IPv6 hosts go in brackets (``tcp:[::1]:5760``).  Raises ValueError naming what is wrong.
    """
    text = url.strip()
    if not text:
        raise ValueError("link URL is empty; expected e.g. tcp:127.0.0.1:5760")
    if text.lower().startswith("serial:"):
        return _serial(url, text[len("serial:") :])
    if text.startswith("/dev/") or text.upper().startswith("COM"):
        return _serial(url, text)
    scheme, sep, rest = text.partition(":")
    kind = _SCHEMES.get(scheme.lower())
    if not sep or kind is None:
        raise ValueError(
            f"link URL {url!r}: unknown scheme {scheme!r}; expected one of "
            "tcp:HOST:PORT, udpin:HOST:PORT, udp:HOST:PORT, udpout:HOST:PORT, "
            "serial:DEVICE:BAUD"
        )
    host, sep, port_text = rest.rpartition(":")
    if not sep or not host:
        raise ValueError(f"link URL {url!r}: expected {scheme}:HOST:PORT, missing host or port")
    if host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    elif ":" in host:
        raise ValueError(f"link URL {url!r}: put an IPv6 host in brackets, e.g. tcp:[::1]:5760")
    if not host or any(c.isspace() for c in host):
        raise ValueError(f"link URL {url!r}: host {host!r} is not a host name or address")
    if not port_text.isdigit() or not 1 <= int(port_text) <= 65535:
        raise ValueError(f"link URL {url!r}: port {port_text!r} is not a number in 1..65535")
    return LinkUrl(kind, host, int(port_text))


def parse_forward_url(url: str) -> LinkUrl:
    """``udpout:HOST:PORT``, ``udpin:HOST:PORT`` or ``tcpin:HOST:PORT``; ValueError otherwise."""
    text = url.strip()
    if text.lower().startswith("tcpin:"):
        parsed = parse_link_url("tcp:" + text[len("tcpin:") :])
        return LinkUrl(LinkKind.TCP, parsed.host, parsed.port)  # TCP here: we listen
    parsed = parse_link_url(text)
    if parsed.kind not in (LinkKind.UDP_OUT, LinkKind.UDP_IN):
        raise ValueError(
            f"forward {url!r}: expected udpout:HOST:PORT, udpin:HOST:PORT or tcpin:HOST:PORT"
        )
    return parsed


SERIAL_BAUD_DEFAULT = 57600
"""A SiK / RFD900 telemetry radio's serial rate, as MAVProxy and QGroundControl assume."""


SERIAL_BACKOFF_MAX_S = 1.0
"""The longest wait between attempts to open a serial device: a radio plugged back in is
talking again within a second (a network peer keeps the links' 5 s)."""


def _serial(url: str, text: str) -> LinkUrl:
    """``DEVICE``, ``DEVICE:BAUD`` or ``DEVICE,BAUD`` (``serial:`` already taken off)."""
    device, _, baud_text = text.replace(",", ":").partition(":")
    device = device.strip()
    if not device or any(c.isspace() for c in device):
        raise ValueError(f"link URL {url!r}: device {device!r} is not a serial device path")
    baud = SERIAL_BAUD_DEFAULT
    if baud_text:
        if not baud_text.isdigit() or not 0 < int(baud_text) <= 20_000_000:
            raise ValueError(f"link URL {url!r}: baud {baud_text!r} is not a number in 1..20000000")
        baud = int(baud_text)
    return LinkUrl(LinkKind.SERIAL, device, baud)


@dataclass(frozen=True, slots=True)
class LinkStats:
    """Counters of one link since it was created."""

    bytes_in: int = 0
    bytes_out: int = 0
    messages_in: int = 0
    messages_out: int = 0
    parse_errors: int = 0
    """Frames dropped as bad (CRC, header, signature, truncated datagram)."""
    refused_unsigned: int = 0
    """Of ``parse_errors``: unsigned frames refused on a signing link."""
    refused_bad_signature: int = 0
    """Of ``parse_errors``: frames signed with another key, or replayed."""
    bytes_skipped: int = 0
    """Noise between frames."""
    dropped_out: int = 0
    """Messages not sent because the link was down (or had no peer yet)."""
    connect_attempts: int = 0
    connects: int = 0
    """Successful connections (TCP connected, UDP socket bound)."""
    reconnects: int = 0
    """Successful connections after the first."""
    callback_errors: int = 0
    """Exceptions raised by ``on_message`` (logged, then ignored)."""
    backoff_s: float = 0.0
    """The wait before the next connection attempt."""


OnMessage = Callable[["MavlinkLink", MAVLinkMessage], None]


class MavlinkLink:
    """One MAVLink link to one or more vehicles; see the module docstring."""

    def __init__(
        self,
        url: str,
        on_message: OnMessage,
        *,
        source_system: int = GCS_SYSTEM_ID,
        source_component: int = GCS_COMPONENT_ID,
        tlog_path: Path | None = None,
        backoff_initial_s: float = 0.5,
        backoff_max_s: float = 5.0,
        connect_timeout_s: float = 5.0,
        send_timeout_s: float = 2.0,
        signing_key: bytes | None = None,
        signing_link_id: int = 0,
        accept_unsigned: bool = False,
    ) -> None:
        self.url = parse_link_url(url)
        if self.url.kind is LinkKind.SERIAL:  # a local device: trying it again costs nothing
            backoff_max_s = min(backoff_max_s, SERIAL_BACKOFF_MAX_S)
            backoff_initial_s = min(backoff_initial_s, backoff_max_s)
        if not (0 < backoff_initial_s <= backoff_max_s and math.isfinite(backoff_max_s)):
            raise ValueError(
                "backoff must satisfy 0 < backoff_initial_s <= backoff_max_s < inf, got "
                f"{backoff_initial_s}, {backoff_max_s}"
            )
        self._on_message = on_message
        self._codec = Codec(
            source_system,
            source_component,
            signing_key=signing_key,
            signing_link_id=signing_link_id,
            signing_timestamp=signing_timestamp(time.time()) if signing_key else 0,
            accept_unsigned=accept_unsigned,
        )
        self._refused_logged = (0, 0)  # (unsigned, bad signature) counts last logged
        self._refused_logged_s = -math.inf
        self._refused_logged_from: tuple[int, int, int] | None = None
        self._tlog_path = tlog_path
        self._tlog: IO[bytes] | None = None
        self._tlog_flushed_s = 0.0
        self._backoff_initial_s = backoff_initial_s
        self._backoff_max_s = backoff_max_s
        self._connect_timeout_s = connect_timeout_s
        self._send_timeout_s = send_timeout_s
        self._closed = False
        self._close_event = asyncio.Event()
        self._stats = LinkStats()
        # The counters every frame moves, kept apart from ``_stats`` (a frozen record
        # rebuilt per frame cost a tenth of the decoding at 100 vehicles): (bytes,
        # messages) in and out.
        self._traffic = [0, 0, 0, 0]
        # The live connection: set by a session, cleared when it ends.
        self._writer: asyncio.StreamWriter | None = None
        self._udp: DatagramSocket | None = None
        self._peer: tuple[str, int] | None = None
        self._peers: dict[int, tuple[str, int]] = {}
        """``udpin``: each system's address, where it was last heard from (several vehicles
        each streaming from a socket of its own to one port, as SITL instances do)."""
        self._running = False
        self.receiving_s = 0.0
        """Our seconds spent decoding what was received and handing it on (perf_counter)."""

    # -- state -----------------------------------------------------------------------------
    @property
    def connected(self) -> bool:
        """True while messages can be sent (TCP connected; UDP bound with a known peer)."""
        if self._writer is not None:
            return not self._writer.is_closing()
        return self._udp is not None and self._peer is not None and not self._udp.is_closing()

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def stats(self) -> LinkStats:
        codec = self._codec.stats
        bytes_in, messages_in, bytes_out, messages_out = self._traffic
        return replace(
            self._stats,
            bytes_in=bytes_in,
            messages_in=messages_in,
            bytes_out=bytes_out,
            messages_out=messages_out,
            parse_errors=codec.errors,
            bytes_skipped=codec.bytes_skipped,
            refused_unsigned=codec.refused_unsigned,
            refused_bad_signature=codec.refused_bad_signature,
        )

    @property
    def codec(self) -> Codec:
        return self._codec

    def close(self) -> None:
        """Stop: ``run()`` returns soon after.  Safe to call more than once, and before ``run``."""
        self._closed = True
        self._close_event.set()
        if self._writer is not None:
            self._writer.close()
        if self._udp is not None:
            self._udp.close()

    # -- running ---------------------------------------------------------------------------
    async def run(self) -> None:
        """Connect, read, reconnect with exponential backoff, until ``close()``.

        Never raises (except CancelledError when the task is cancelled).
        """
        if self._running:
            raise RuntimeError("MavlinkLink.run() is already running")
        self._running = True
        backoff = self._backoff_initial_s
        try:
            self._open_tlog()
            while not self._closed:
                self._stats = replace(
                    self._stats, connect_attempts=self._stats.connect_attempts + 1
                )
                heard = False
                try:
                    heard = await self._session()
                except (OSError, TimeoutError, EOFError) as exc:
                    log.info("link %s: %s", self.url, exc or type(exc).__name__)
                except Exception:
                    log.exception("link %s: unexpected error", self.url)
                if self._closed:
                    break
                if heard:
                    backoff = self._backoff_initial_s
                self._stats = replace(self._stats, backoff_s=backoff)
                with contextlib.suppress(TimeoutError):
                    async with asyncio.timeout(backoff):
                        await self._close_event.wait()
                backoff = min(backoff * 2.0, self._backoff_max_s)
        finally:
            self._running = False
            self._drop_connection()
            self._close_tlog()

    async def _session(self) -> bool:
        """One connection, until it ends; True if any message was received on it."""
        self._codec.reset()
        if self.url.kind is LinkKind.TCP:
            return await self._tcp_session()
        if self.url.kind in (LinkKind.UDP_IN, LinkKind.UDP_OUT):
            return await self._udp_session()
        if self.url.kind is LinkKind.SERIAL:
            return await self._serial_session()
        raise NotImplementedError(f"link kind {self.url.kind} is not supported")

    async def _tcp_session(self) -> bool:
        async with asyncio.timeout(self._connect_timeout_s):
            reader, writer = await asyncio.open_connection(self.url.host, self.url.port)
        sock = writer.get_extra_info("socket")
        if sock is not None:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        return await self._stream_session(reader, writer)

    async def _serial_session(self) -> bool:
        """The device opened raw at the baud rate (8N1, no flow control, as SiK radios ship);
        a device that cannot be opened, or goes away, raises ``SerialException`` (an OSError):
        ``run`` opens it again after its backoff."""
        async with asyncio.timeout(self._connect_timeout_s):
            reader, writer = await serial_asyncio.open_serial_connection(
                url=self.url.host, baudrate=self.url.port, exclusive=True
            )
        return await self._stream_session(reader, writer)

    async def _stream_session(
        self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter
    ) -> bool:
        """Read a byte stream (TCP, serial) until it ends; True if any message came."""
        self._writer = writer
        self._connected_once()
        heard = False
        try:
            while not self._closed:
                data = await reader.read(_READ_SIZE)
                if not data:
                    log.info("link %s: connection closed by the peer", self.url)
                    return heard
                start = time.perf_counter()
                heard = self._received(self._codec.parse(data), len(data)) or heard
                self.receiving_s += time.perf_counter() - start
            return heard
        finally:
            self._drop_connection()

    async def _udp_session(self) -> bool:
        address = (self.url.host, self.url.port)
        if self.url.kind is LinkKind.UDP_IN:
            udp = await DatagramSocket.open(local=address)
            self._peer = None
        else:
            udp = await DatagramSocket.open(remote=address)
            self._peer = address
        self._udp = udp
        self._connected_once()
        heard = False
        try:
            while not self._closed:
                batch = await udp.batches.get()
                if batch is None:
                    return heard
                for data, addr in batch:
                    start = time.perf_counter()
                    messages = self._codec.parse_datagram(data)
                    if self.url.kind is LinkKind.UDP_IN:
                        self._peer = addr  # answer whoever spoke last...
                        for msg in messages:  # ...and each system where it speaks from
                            self._peers[int(msg.get_srcSystem())] = addr
                    heard = self._received(messages, len(data)) or heard
                    self.receiving_s += time.perf_counter() - start
            return heard
        finally:
            self._drop_connection()

    def _connected_once(self) -> None:
        s = self._stats
        self._stats = replace(
            s, connects=s.connects + 1, reconnects=s.reconnects + (1 if s.connects else 0)
        )
        log.info("link %s: connected", self.url)

    def _drop_connection(self) -> None:
        writer, udp = self._writer, self._udp
        self._writer = None
        self._udp = None
        self._peer = None
        self._peers = {}
        if writer is not None:
            writer.close()
        if udp is not None:
            udp.close()

    def _received(self, messages: list[MAVLinkMessage], n_bytes: int) -> bool:
        """Log and deliver decoded messages; True if there were any."""
        self._log_refused()
        traffic = self._traffic
        traffic[0] += n_bytes
        traffic[1] += len(messages)
        for msg in messages:
            self._tlog_write(bytes(msg.get_msgbuf()))
            try:
                self._on_message(self, msg)
            except Exception:
                self._stats = replace(self._stats, callback_errors=self._stats.callback_errors + 1)
                log.exception("link %s: on_message failed on %s", self.url, msg.get_type())
        return bool(messages)

    def _log_refused(self) -> None:
        """A warning when frames were refused for their signature: at the first, then at most
        every ``REFUSED_LOG_PERIOD_S`` (``REFUSED_NEWS_LOG_PERIOD_S`` for a new sender or a
        new kind of refusal), with the counts since the last one and who sent the last
        (never anything of the key).  Called on every read and every send, so refusals
        that no others follow are told too, with the next heartbeat at the latest."""
        codec = self._codec.stats
        counts = (codec.refused_unsigned, codec.refused_bad_signature)
        if counts == self._refused_logged:
            return
        now = time.monotonic()
        who = self._codec.last_refused
        new_kind = any(c and not old for c, old in zip(counts, self._refused_logged, strict=True))
        news = new_kind or who != self._refused_logged_from
        wait = REFUSED_NEWS_LOG_PERIOD_S if news else REFUSED_LOG_PERIOD_S
        if now - self._refused_logged_s < wait:
            return
        unsigned = counts[0] - self._refused_logged[0]
        bad = counts[1] - self._refused_logged[1]
        self._refused_logged, self._refused_logged_s = counts, now
        self._refused_logged_from = who
        sender = "" if who is None else f"; last from system {who[0]} component {who[1]}, "
        sender += "" if who is None else f"message id {who[2]}"
        log.warning(
            "link %s: refused %d unsigned and %d wrongly signed or replayed frames "
            "(%d and %d in all)%s",
            self.url,
            unsigned,
            bad,
            counts[0],
            counts[1],
            sender,
        )

    # -- sending ---------------------------------------------------------------------------
    async def send(self, msg: MAVLinkMessage) -> bool:
        """Encode ``msg`` and hand it to the transport (True); False, and counted, if the link
        is down or (``udpin``) no peer has spoken yet.

        Raises ValueError if ``msg`` cannot be encoded.  A TCP peer that stops reading for
        ``send_timeout_s`` is treated as gone: the connection is dropped and remade.
        """
        self._log_refused()  # refusals since the last read are told even if none follow
        if not self.connected:
            self._stats = replace(self._stats, dropped_out=self._stats.dropped_out + 1)
            return False
        if self._codec.signing:
            self._codec.advance_signing_clock(signing_timestamp(time.time()))
        target = int(getattr(msg, "target_system", 0)) or None
        return await self._send_frame(self._codec.encode(msg), target)

    def forward_frame(self, frame: bytes, target_system: int | None = None) -> bool:
        """Hand a whole frame, as another system encoded it, to the transport unchanged (its
        sequence number and signature are its sender's), without waiting: dropped, and
        counted, when the link is down or a TCP peer has ``FORWARD_BUFFER_BYTES`` unread.
        ``target_system``: the system it addresses (``udpin`` sends it there)."""
        writer = self._writer
        behind = writer is not None and writer.transport.get_write_buffer_size() > (
            FORWARD_BUFFER_BYTES
        )
        if not self.connected or behind:
            self._stats = replace(self._stats, dropped_out=self._stats.dropped_out + 1)
            return False
        self._put(frame, target_system)
        return True

    def _put(self, frame: bytes, target_system: int | None = None) -> None:
        """Write ``frame`` to the live transport, tlog and count it.  On ``udpin``, to the
        address ``target_system`` was last heard from; a frame for every system (none
        named) to every address heard; one for a system not heard to the last sender."""
        if self._writer is not None:
            self._writer.write(frame)
        elif self._udp is not None and self._peer is not None:
            if self.url.kind is LinkKind.UDP_OUT:
                self._udp.sendto(frame)
            elif target_system is None:
                for address in {self._peer, *self._peers.values()}:
                    self._udp.sendto(frame, address)
            else:
                self._udp.sendto(frame, self._peers.get(target_system, self._peer))
        self._tlog_write(frame)
        traffic = self._traffic
        traffic[2] += len(frame)
        traffic[3] += 1

    async def _send_frame(self, frame: bytes, target_system: int | None = None) -> bool:
        writer = self._writer
        self._put(frame, target_system)
        if writer is not None and writer.transport.get_write_buffer_size() > 0:
            # Only a peer that is behind is waited for (the rest is written already); a
            # timeout armed on every send cost a twentieth of a tick at ×10.
            try:
                async with asyncio.timeout(self._send_timeout_s):
                    await writer.drain()
            except (TimeoutError, OSError) as exc:
                log.warning("link %s: send failed (%s), reconnecting", self.url, exc or "timeout")
                if writer is self._writer:
                    writer.transport.abort()
        return True

    # -- tlog ------------------------------------------------------------------------------
    def _open_tlog(self) -> None:
        """Open the tlog for appending; a tlog that cannot be written is logged, not fatal."""
        if self._tlog_path is not None and self._tlog is None:
            try:
                self._tlog_path.parent.mkdir(parents=True, exist_ok=True)
                self._tlog = self._tlog_path.open("ab")
            except OSError as exc:
                log.error("link %s: cannot write tlog %s: %s", self.url, self._tlog_path, exc)
                return
            self._tlog_flushed_s = time.monotonic()

    def _tlog_write(self, frame: bytes) -> None:
        if self._tlog is None or message_id(frame) == _SETUP_SIGNING_ID:
            return
        self._tlog.write(struct.pack(">Q", int(time.time() * 1e6)) + frame)
        now = time.monotonic()
        if now - self._tlog_flushed_s >= _TLOG_FLUSH_S:
            self._tlog.flush()
            self._tlog_flushed_s = now

    def _close_tlog(self) -> None:
        if self._tlog is not None:
            self._tlog.close()
            self._tlog = None

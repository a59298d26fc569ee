"""The asyncio shell: sockets, wall-clock pacing, faults on the wire, signing, tlogs.

Per vehicle i a TCP server on 127.0.0.1:base_port + 10·i accepts any number of clients; all
of them receive the telemetry stream, replies go to the client that asked. With ``--out``
each vehicle also has a UDP socket that streams to that address and accepts commands from it.
With ``--serial`` a vehicle is also on a serial device (a pseudo-terminal standing in for a
telemetry radio), or every vehicle on one, as one radio carries a fleet: each vehicle reads
every frame on the line and takes what is addressed to it; a device that goes away is
opened again.
Every client has its own pymavlink codec (``MAVLink(None, sysid, 1)``): ``parse_buffer`` in,
``pack`` out. Nothing here decides what a vehicle does; ``sitl.engine`` does.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import math
import random
import signal
import struct
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

import serial_asyncio
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from gcs_ppf.datagrams import DatagramSocket
from gcs_ppf.mavlink.codec import guard_stream_timestamps, signing_key_from_text
from gcs_ppf.mavlink.enums import MAV_SEVERITY_WARNING
from sitl.autopilot import Outbox
from sitl.engine import Simulation
from sitl.messages import Message, statustext
from sitl.physics import DT_S
from sitl.radio import RadioBudget

#: Write buffer above which a slow client's telemetry is dropped (bytes).
MAX_BUFFERED = 1 << 20
#: MAVLink signing epoch, 2015-01-01 UTC (timestamps count 10 µs from it).
SIGNING_EPOCH_S = 1420070400
#: Physics steps run between two reads of the links (0.1 s of simulated time): a SITL behind
#: its schedule on a busy machine catches up in small batches, so a command waits at most
#: this long for the vehicle to see it (with 200 steps, 4 s of vehicle time, measured flown
#: closed loop: commands took up to 5–6 s to act, and vehicles flew into obstacles).
MAX_STEPS_UNREAD = 5
MAX_CATCH_UP_S = 0.1
"""Wall seconds a SITL behind its schedule may catch up; beyond that its clock slips, as
ArduPilot's SITL does (``Aircraft::sync_frame_time``, SIM_Aircraft.cpp: the sleep debt is
kept above −1e5 µs).  With 0.25 s, ×10 under two CPU burners, a vehicle flew 2.5 s of its
time in one burst while the starved service could not answer, 15 m into a keep-out."""


def signing_key(text: str) -> bytes:
    """A 32-byte key: 64 hex digits as they are, anything else hashed with SHA-256 (as
    MAVProxy's ``signing setup PASSPHRASE`` does)."""
    return signing_key_from_text(text)


def signing_now() -> int:
    """The MAVLink signing timestamp of now: 10 µs units since 2015-01-01 UTC."""
    return max(0, int((time.time() - SIGNING_EPOCH_S) * 1e5))


class Peer:
    """One client of one vehicle: its codec and how to write to it."""

    def __init__(self, link: VehicleLink, write: Callable[[bytes], None], label: str) -> None:
        self.link = link
        self.write = write
        self.label = label
        self.mav = mavlink.MAVLink(None, srcSystem=link.sysid, srcComponent=1)
        self.mav.robust_parsing = True
        self.buffered: Callable[[], int] = lambda: 0
        self.close: Callable[[], None] = lambda: None
        # Each client is a link of its own, as each serial port or UDP/TCP connection is
        # a MAVLink channel of ArduPilot's: its frames carry its own signing link id.
        self.link_id = link.next_link_id()
        guard_stream_timestamps(self.mav)
        self.use_key(link.key)

    def use_key(self, key: bytes | None, timestamp: int = 0) -> None:
        """Sign with ``key`` from now on and refuse unsigned or wrongly signed frames
        (None: signing off, everything accepted).  The timestamp goes on from the later of
        the wall clock, ``timestamp`` and what it was (signing timestamps never go back)."""
        signing = self.mav.signing
        signing.secret_key = key
        signing.sign_outgoing = key is not None
        signing.link_id = self.link_id
        signing.timestamp = max(signing.timestamp, signing_now(), timestamp)
        signing.allow_unsigned_callback = None if key is None else lambda _mav, _msgid: False

    def pack(self, msg: Message) -> bytes:
        self.mav.srcSystem = self.link.sysid
        data: bytes = msg.pack(self.mav)
        return data

    def parse(self, data: bytes) -> list[Any]:
        try:
            return list(self.mav.parse_buffer(data) or [])
        except Exception:  # a malformed frame must never take the vehicle down
            self.mav.buf = bytearray()
            self.mav.buf_index = 0
            return []


@dataclass
class LinkStats:
    rx_msgs: int = 0
    tx_msgs: int = 0
    dropped: int = 0
    bad: int = 0


class VehicleLink:
    """The wire side of vehicle ``index``: its peers, the link faults, signing and tlog."""

    def __init__(
        self,
        sim: Simulation,
        index: int,
        speedup: float,
        seed: int,
        key: bytes | None,
        tlog: BinaryIO | None,
    ) -> None:
        self.sim = sim
        self.index = index
        self.ap = sim.autopilots[index]
        self.speedup = speedup
        self.rng = random.Random(seed * 1000003 + self.ap.sysid)
        self.key = key
        self.tlog = tlog
        self.tlog_mav = mavlink.MAVLink(None, srcSystem=self.ap.sysid, srcComponent=1)
        self.peers: list[Peer] = []
        self.stats = LinkStats()
        self.signing_warned = False
        self.refused_signature = 0
        self._link_ids = 0
        self.loop = asyncio.get_event_loop()

    def next_link_id(self) -> int:
        """The signing link id of the next client (0, 1, …, wrapping at 256)."""
        link_id = self._link_ids % 256
        self._link_ids += 1
        return link_id

    @property
    def sysid(self) -> int:
        return self.ap.sysid

    # ---- faults --------------------------------------------------------------------------
    def _blocked(self) -> bool:
        f = self.ap.faults
        if f.dead or f.link_cut(self.sim.sim_s):
            return True
        return f.loss_pct > 0 and self.rng.random() * 100.0 < f.loss_pct

    def _delay_s(self) -> float:
        return self.ap.faults.latency_ms / 1000.0 / self.speedup

    # ---- inbound -------------------------------------------------------------------------
    def receive(self, peer: Peer, data: bytes) -> None:
        for msg in peer.parse(data):
            if self._blocked():
                self.stats.dropped += 1
                continue
            delay = self._delay_s()
            if delay > 0:
                self.loop.call_later(delay, self._deliver, peer, msg)
            else:
                self._deliver(peer, msg)

    def _deliver(self, peer: Peer, msg: Any) -> None:
        if msg.get_type() == "BAD_DATA":
            self.stats.bad += 1
            if "signature" in str(msg.reason):
                self.refused_signature += 1
                if not self.signing_warned:
                    self.signing_warned = True
                    text = "Bad or missing signature: message ignored"
                    self.send(Outbox(broadcast=[statustext(MAV_SEVERITY_WARNING, text)]), None)
            return
        self.stats.rx_msgs += 1
        if msg.get_type() == "SETUP_SIGNING":  # not in the tlog: it carries the key
            self._setup_signing(msg)
            return
        self._log(msg.get_msgbuf())
        try:
            out = self.sim.handle(self.index, msg, self.loop.time())
        except Exception as exc:  # never let one message kill the vehicle; say why
            print(f"sitl: vehicle {self.sysid}: {msg.get_type()} raised {exc!r}", file=sys.stderr)
            return
        if out is not None:
            self.send(out, peer)

    def _setup_signing(self, msg: Any) -> None:
        """SETUP_SIGNING as ArduPlane takes it (``GCS_MAVLINK::handle_setup_signing``): the
        key (all zeros: signing off) and initial timestamp apply at once to every client of
        the vehicle.  It arrives here only past the signature checks: with signing on, only a
        client that signs with the current key can change it.  Not answered (ArduPlane sends
        no acknowledgement); stderr says what changed, never the key."""
        if msg.target_system not in (0, self.sysid):
            return
        key = bytes(msg.secret_key)
        new = None if not any(key) else key
        self.key = new
        self.signing_warned = False
        for peer in self.peers:
            peer.use_key(new, int(msg.initial_timestamp))
        state = "off" if new is None else "on, with the key received"
        print(f"sitl: vehicle {self.sysid}: SETUP_SIGNING: signing {state}", file=sys.stderr)

    # ---- outbound ------------------------------------------------------------------------
    def send(self, out: Outbox, reply_to: Peer | None) -> None:
        for msg in out.broadcast:
            self._log_out(msg)
            for peer in self.peers:
                self._write(peer, msg)
        for msg in out.reply:
            self._log_out(msg)
            if reply_to is not None:
                self._write(reply_to, msg)

    def _write(self, peer: Peer, msg: Message) -> None:
        if self._blocked() or peer.buffered() > MAX_BUFFERED:
            self.stats.dropped += 1
            return
        data = peer.pack(msg)
        self.stats.tx_msgs += 1
        delay = self._delay_s()
        if delay > 0:
            self.loop.call_later(delay, peer.write, data)
        else:
            peer.write(data)

    def _log_out(self, msg: Message) -> None:
        if self.tlog is not None and not self.ap.faults.dead:
            self.tlog_mav.srcSystem = self.sysid
            self._log(msg.pack(self.tlog_mav))

    def _log(self, frame: bytes | bytearray) -> None:
        if self.tlog is not None:
            self.tlog.write(struct.pack(">Q", self.sim.boot_unix_us + round(self.sim.sim_s * 1e6)))
            self.tlog.write(bytes(frame))


class _TcpClient(asyncio.Protocol):
    def __init__(self, link: VehicleLink) -> None:
        self.link = link
        self.peer: Peer | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport
        self.peer = Peer(self.link, self._write, str(transport.get_extra_info("peername")))
        self.peer.buffered = transport.get_write_buffer_size
        self.peer.close = transport.close
        self.link.peers.append(self.peer)

    def _write(self, data: bytes) -> None:
        if not self.transport.is_closing():
            self.transport.write(data)

    def data_received(self, data: bytes) -> None:
        if self.peer is not None:
            self.link.receive(self.peer, data)

    def connection_lost(self, exc: Exception | None) -> None:
        if self.peer in self.link.peers:
            self.link.peers.remove(self.peer)


async def _stream_udp(link: VehicleLink, out: tuple[str, int]) -> None:
    """Stream ``link``'s vehicle to ``out`` from a socket of its own and take commands from
    it, the whole backlog at each wake-up (``DatagramSocket``: read one datagram a wake-up,
    the service's commands at ×10 came faster than the loop woke, and 4 in 10 were lost)."""
    udp = await DatagramSocket.open(remote=out)
    peer = Peer(link, udp.sendto, "udp-out")
    link.peers.append(peer)
    try:
        while (batch := await udp.batches.get()) is not None:
            for data, _ in batch:
                link.receive(peer, data)
    finally:
        udp.close()
        if peer in link.peers:
            link.peers.remove(peer)


class _SerialLine(asyncio.Protocol):
    """One serial device carrying one or more vehicles (their links)."""

    def __init__(self, links: list[VehicleLink], label: str, radio_baud: int | None = None) -> None:
        self.links = links
        self.label = label
        self.peers: list[Peer] = []
        self.lost: asyncio.Future[None] = asyncio.get_event_loop().create_future()
        # the radio's budget each way (None: the line carries whatever is written)
        self.down = None if radio_baud is None else RadioBudget(radio_baud)
        self.up = None if radio_baud is None else RadioBudget(radio_baud)

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport
        for link in self.links:
            peer = Peer(link, self._write, self.label)
            peer.buffered = transport.get_write_buffer_size
            peer.close = transport.close
            link.peers.append(peer)
            self.peers.append(peer)

    def _write(self, data: bytes) -> None:
        if self.transport.is_closing():
            return
        if self.down is not None and not self.down.admit(len(data), self.links[0].sim.sim_s):
            return  # the radio's buffer is full: lost in the air
        self.transport.write(data)

    def data_received(self, data: bytes) -> None:
        if self.up is not None and not self.up.admit(len(data), self.links[0].sim.sim_s):
            return
        for peer in self.peers:
            peer.link.receive(peer, data)

    def connection_lost(self, exc: Exception | None) -> None:
        for peer in self.peers:
            if peer in peer.link.peers:
                peer.link.peers.remove(peer)
        if not self.lost.done():
            self.lost.set_result(None)


SERIAL_RETRY_S = 0.5
"""Wall seconds between attempts to open a serial device that is not there (yet)."""


async def serve_serial(
    links: list[VehicleLink], device: str, baud: int, radio_baud: int | None = None
) -> None:
    """Keep ``links``' vehicles on ``device`` at ``baud``: open it, serve it until it goes
    away (a radio unplugged, a pseudo-terminal closed), open it again; until cancelled.
    ``radio_baud``: the bytes a second the radio carries each way (``sitl.radio``)."""
    loop = asyncio.get_running_loop()
    said = False
    while True:
        line = _SerialLine(links, f"serial:{device}", radio_baud)
        try:
            transport, _ = await serial_asyncio.create_serial_connection(
                loop, functools.partial(_same, line), device, baudrate=baud
            )
        except OSError as exc:  # serial.SerialException is one
            if not said:
                print(f"sitl: {device}: {exc}; trying again", file=sys.stderr)
                said = True
            await asyncio.sleep(SERIAL_RETRY_S)
            continue
        said = False
        try:
            await line.lost
        finally:
            transport.close()
        await asyncio.sleep(SERIAL_RETRY_S)


def _same(line: _SerialLine) -> _SerialLine:
    return line


def parse_serial(text: str) -> tuple[str, int]:
    """``DEVICE`` or ``DEVICE:BAUD`` (also ``DEVICE,BAUD``) → (device, baud; 57600 when
    not given, a SiK radio's)."""
    device, _, baud = text.replace(",", ":").partition(":")
    if not device or (baud and (not baud.isdigit() or int(baud) <= 0)):
        raise ValueError(f"--serial: expected DEVICE[:BAUD], got {text!r}")
    return device, int(baud) if baud else 57600


@dataclass(frozen=True, slots=True)
class ServerConfig:
    base_port: int = 5760
    speedup: float = 1.0
    out: tuple[str, int] | None = None
    seed: int = 0
    signing_key: bytes | None = None
    tlog_dir: Path | None = None
    host: str = "127.0.0.1"
    duration_s: float | None = None  # stop after this much simulated time (tests, benchmarks)
    serial: tuple[tuple[str, int], ...] = ()
    """(device, baud): one per vehicle in order, or one for every vehicle."""
    radio: bool = False
    """Each serial line carries only what a radio at its baud rate does (``sitl.radio``)."""


async def pace(
    sim: Simulation,
    links: list[VehicleLink],
    speedup: float,
    stop: asyncio.Event,
    duration_s: float | None = None,
) -> None:
    """Advance the simulation so that sim time = speedup × wall time (falling behind if the
    CPU cannot keep up, never bursting to catch up by more than ``MAX_CATCH_UP_S``)."""
    loop = asyncio.get_running_loop()
    t0 = loop.time()
    while not stop.is_set():
        now = loop.time()
        target = (now - t0) * speedup
        if target - sim.sim_s > MAX_CATCH_UP_S * speedup:  # too far behind: the clock slips
            t0 += (target - sim.sim_s) / speedup - MAX_CATCH_UP_S
            target = (now - t0) * speedup
        batch = 0
        while sim.sim_s + DT_S <= target + 1e-9 and batch < MAX_STEPS_UNREAD:
            for i, out in sim.step(loop.time()):
                links[i].send(out, None)
            batch += 1
            if duration_s is not None and sim.sim_s >= duration_s:
                stop.set()
                return
        wait = t0 + (sim.sim_s + DT_S) / speedup - loop.time()
        await asyncio.sleep(max(wait, 0.0) if batch < MAX_STEPS_UNREAD else 0.0)


async def serve(
    sim: Simulation, cfg: ServerConfig, *, ready: Callable[[str], None] = print
) -> None:
    """Run until SIGINT/SIGTERM (or ``cfg.duration_s`` of simulated time)."""
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.add_signal_handler(sig, stop.set)
    async with contextlib.AsyncExitStack() as stack:
        links: list[VehicleLink] = []
        for i, ap in enumerate(sim.autopilots):
            tlog: BinaryIO | None = None
            if cfg.tlog_dir is not None:
                cfg.tlog_dir.mkdir(parents=True, exist_ok=True)
                tlog = stack.enter_context((cfg.tlog_dir / f"vehicle{ap.sysid}.tlog").open("wb"))
            link = VehicleLink(sim, i, cfg.speedup, cfg.seed, cfg.signing_key, tlog)
            links.append(link)
            port = cfg.base_port + 10 * i
            server = await loop.create_server(
                functools.partial(_TcpClient, link), cfg.host, port, reuse_address=True
            )
            stack.push_async_callback(_close_server, server)
            if cfg.out is not None:
                streaming = asyncio.create_task(_stream_udp(link, cfg.out))
                stack.callback(streaming.cancel)
            ready(f"vehicle {ap.sysid}: tcp:{cfg.host}:{port}")
        lines = serial_lines(links, cfg.serial)
        serials = [
            asyncio.create_task(serve_serial(on, dev, baud, baud if cfg.radio else None))
            for dev, baud, on in lines
        ]
        for device, baud, on in lines:
            ids = ", ".join(str(link.sysid) for link in on)
            ready(f"vehicle{'s' if len(on) > 1 else ''} {ids}: serial:{device}:{baud}")
        ready(f"sitl ready: {len(links)} vehicles, speedup {cfg.speedup:g}")
        clock = asyncio.create_task(pace(sim, links, cfg.speedup, stop, cfg.duration_s))
        try:
            await stop.wait()
        finally:
            stop.set()
            for task in (clock, *serials):
                task.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await task
            for link in links:
                for peer in list(link.peers):
                    peer.close()


def serial_lines(
    links: list[VehicleLink], serial: tuple[tuple[str, int], ...]
) -> list[tuple[str, int, list[VehicleLink]]]:
    """Which vehicles go on which device: one device each, or all on the one given."""
    if not serial:
        return []
    if len(serial) == 1:
        return [(serial[0][0], serial[0][1], list(links))]
    if len(serial) != len(links):
        raise ValueError(
            f"--serial: {len(serial)} devices for {len(links)} vehicles; give one per "
            "vehicle, or one for all"
        )
    return [(dev, baud, [link]) for (dev, baud), link in zip(serial, links, strict=True)]


async def _close_server(server: asyncio.Server) -> None:
    server.close()
    with contextlib.suppress(Exception):
        await asyncio.wait_for(server.wait_closed(), 1.0)


def check_speedup(value: float) -> float:
    if not math.isfinite(value) or value <= 0:
        raise ValueError("--speedup must be a positive number")
    return value

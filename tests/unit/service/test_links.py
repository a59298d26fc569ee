"""MavlinkLink against a tiny fake vehicle on 127.0.0.1 (asyncio TCP server, UDP sockets).

The fake vehicle speaks plain pymavlink (not our Codec).  Every test runs its own event loop
under ``asyncio.timeout``; backoff times are shrunk so the file runs in a few seconds.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import random
import re
import time
import tty
from collections.abc import Callable, Coroutine
from pathlib import Path
from typing import Any

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_ppf.mavlink import commands
from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.mavlink.codec import MAVLinkMessage
from gcs_ppf.service.fleet import LinkEntry
from gcs_ppf.service.links import LinkKind, LinkUrl, MavlinkLink, parse_link_url
from gcs_ppf.tools.observer import free_port

pytestmark = pytest.mark.realtime  # sockets, pseudo-terminals, backoffs in wall time

TEST_TIMEOUT_S = 8.0
HEARTBEAT_PERIOD_S = 0.05


def run(coro: Coroutine[Any, Any, None]) -> None:
    """Run one test body in a fresh event loop, bounded in time."""

    async def bounded() -> None:
        async with asyncio.timeout(TEST_TIMEOUT_S):
            await coro

    asyncio.run(bounded())


async def wait_until(pred: Callable[[], bool], timeout_s: float = 3.0) -> None:
    async with asyncio.timeout(timeout_s):
        while not pred():
            await asyncio.sleep(0.01)


def vehicle_heartbeat(mav: Any) -> bytes:
    msg = mavlink2.MAVLink_heartbeat_message(1, 3, 128 | 1, int(PlaneMode.GUIDED), 4, 3)
    frame = bytes(msg.pack(mav))
    mav.seq = (mav.seq + 1) % 256
    return frame


class Inbox:
    """on_message callback that collects what the link delivers."""

    def __init__(self) -> None:
        self.messages: list[MAVLinkMessage] = []

    def __call__(self, link: MavlinkLink, msg: MAVLinkMessage) -> None:
        self.messages.append(msg)

    def count(self, msg_type: str) -> int:
        return sum(1 for m in self.messages if m.get_type() == msg_type)


class FakeTcpVehicle:
    """ArduPlane-ish TCP server: heartbeats at 20 Hz (plus optional noise), records what it gets."""

    def __init__(self, noise: bool = False) -> None:
        self.noise = noise
        self.received: list[MAVLinkMessage] = []
        self.connections = 0
        self.port = 0
        self._server: asyncio.Server | None = None
        self._writers: set[asyncio.StreamWriter] = set()

    async def start(self, port: int = 0) -> None:
        self._server = await asyncio.start_server(self._serve, "127.0.0.1", port)
        self.port = int(self._server.sockets[0].getsockname()[1])

    async def stop(self) -> None:
        """Stop listening and drop every connection."""
        assert self._server is not None
        self._server.close()
        for w in list(self._writers):
            w.transport.abort()
        await self._server.wait_closed()

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.connections += 1
        self._writers.add(writer)
        mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
        mav.robust_parsing = True
        rng = random.Random(self.connections)
        try:
            async with asyncio.TaskGroup() as tg:
                beat = tg.create_task(self._beat(writer, mav, rng))
                while data := await reader.read(4096):
                    for msg in mav.parse_buffer(data) or []:
                        if msg.get_type() != "BAD_DATA":
                            self.received.append(msg)
                beat.cancel()
        except* (ConnectionError, OSError):
            pass
        finally:
            self._writers.discard(writer)
            writer.close()

    async def _beat(self, writer: asyncio.StreamWriter, mav: Any, rng: random.Random) -> None:
        while True:
            if self.noise:
                writer.write(bytes(rng.randrange(256) for _ in range(rng.randrange(1, 300))))
            writer.write(vehicle_heartbeat(mav))
            await writer.drain()
            await asyncio.sleep(HEARTBEAT_PERIOD_S)

    def got(self, command: int) -> list[MAVLinkMessage]:
        return [m for m in self.received if getattr(m, "command", None) == command]


@contextlib.asynccontextmanager
async def running(link: MavlinkLink) -> Any:
    """Run ``link`` in a task group for the body's duration, then close it and join."""
    async with asyncio.TaskGroup() as tg:
        task = tg.create_task(link.run())
        try:
            yield task
        finally:
            link.close()


# -- URLs ---------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("url", "expected"),
    [
        ("tcp:127.0.0.1:5760", LinkUrl(LinkKind.TCP, "127.0.0.1", 5760)),
        ("udpin:0.0.0.0:14550", LinkUrl(LinkKind.UDP_IN, "0.0.0.0", 14550)),
        ("udp:0.0.0.0:14550", LinkUrl(LinkKind.UDP_IN, "0.0.0.0", 14550)),
        ("udpout:10.0.0.2:14555", LinkUrl(LinkKind.UDP_OUT, "10.0.0.2", 14555)),
        ("TCP:sitl.local:5762", LinkUrl(LinkKind.TCP, "sitl.local", 5762)),
        ("tcp:[::1]:5760", LinkUrl(LinkKind.TCP, "::1", 5760)),
        ("serial:/dev/ttyUSB0:57600", LinkUrl(LinkKind.SERIAL, "/dev/ttyUSB0", 57600)),
        ("/dev/ttyUSB0,115200", LinkUrl(LinkKind.SERIAL, "/dev/ttyUSB0", 115200)),
        ("/dev/ttyACM0", LinkUrl(LinkKind.SERIAL, "/dev/ttyACM0", 57600)),
        ("COM3,115200", LinkUrl(LinkKind.SERIAL, "COM3", 115200)),
    ],
)
def test_parse_link_url(url: str, expected: LinkUrl) -> None:
    assert parse_link_url(url) == expected
    assert parse_link_url(str(expected)) == expected


@pytest.mark.parametrize(
    ("url", "complaint"),
    [
        ("", "empty"),
        ("http://x:80", "unknown scheme 'http'"),
        ("tcpin:0.0.0.0:5760", "unknown scheme 'tcpin'"),
        ("127.0.0.1:5760", "unknown scheme '127.0.0.1'"),
        ("tcp:5760", "missing host or port"),
        ("tcp::5760", "missing host or port"),
        ("tcp:localhost:port", "port 'port'"),
        ("tcp:localhost:70000", "port '70000'"),
        ("tcp:localhost:0", "port '0'"),
        ("tcp:::1:5760", "IPv6"),
        ("/dev/ttyUSB0:fast", "baud 'fast'"),
        ("serial:/dev/ttyUSB0:0", "baud '0'"),
        ("serial::57600", "device ''"),
    ],
)
def test_parse_link_url_errors_name_the_problem(url: str, complaint: str) -> None:
    with pytest.raises(ValueError, match=complaint):
        parse_link_url(url)


def test_link_rejects_bad_url_and_backoff() -> None:
    with pytest.raises(ValueError, match="scheme"):
        MavlinkLink("bogus:1:2", Inbox())
    with pytest.raises(ValueError, match="backoff"):
        MavlinkLink("tcp:127.0.0.1:5760", Inbox(), backoff_initial_s=2.0, backoff_max_s=1.0)


# -- TCP ----------------------------------------------------------------------------------
def test_tcp_heartbeat_in_command_out() -> None:
    async def body() -> None:
        vehicle = FakeTcpVehicle()
        await vehicle.start()
        inbox = Inbox()
        link = MavlinkLink(f"tcp:127.0.0.1:{vehicle.port}", inbox)
        assert not link.connected
        assert await link.send(commands.gcs_heartbeat()) is False  # down: dropped, counted
        async with running(link):
            await wait_until(lambda: inbox.count("HEARTBEAT") >= 1)
            assert link.connected
            hb = next(m for m in inbox.messages if m.get_type() == "HEARTBEAT")
            assert (hb.get_srcSystem(), hb.custom_mode) == (1, 15)
            assert await link.send(commands.set_mode(1, PlaneMode.LOITER))
            await wait_until(lambda: bool(vehicle.got(176)))
            cmd = vehicle.got(176)[0]
            assert (cmd.get_srcSystem(), cmd.get_srcComponent()) == (255, 190)
            assert (cmd.target_system, cmd.param2) == (1, 12.0)
        stats = link.stats
        assert not link.connected
        assert stats.dropped_out == 1
        assert stats.messages_out == 1
        assert stats.messages_in == len(inbox.messages) >= 1
        assert stats.bytes_in > 0
        assert stats.bytes_out > 0
        assert stats.connects == 1
        assert stats.reconnects == 0
        assert stats.parse_errors == 0
        await vehicle.stop()

    run(body())


def test_tcp_reconnects_with_exponential_backoff() -> None:
    async def body() -> None:
        vehicle = FakeTcpVehicle()
        await vehicle.start()
        port = vehicle.port
        inbox = Inbox()
        link = MavlinkLink(
            f"tcp:127.0.0.1:{port}", inbox, backoff_initial_s=0.05, backoff_max_s=0.2
        )
        async with running(link):
            await wait_until(lambda: inbox.count("HEARTBEAT") >= 1)
            await vehicle.stop()
            await wait_until(lambda: not link.connected)
            attempts0 = link.stats.connect_attempts
            started = time.monotonic()
            await asyncio.sleep(1.0)
            elapsed = time.monotonic() - started
            attempts = link.stats.connect_attempts - attempts0
            # 0.05, 0.1, 0.2, 0.2, ... s: about 6 tries in a second; a fixed 0.05 s would give 20.
            assert 3 <= attempts <= int(elapsed / 0.2) + 4, attempts
            assert link.stats.backoff_s == pytest.approx(0.2)
            assert await link.send(commands.gcs_heartbeat()) is False
            heard = inbox.count("HEARTBEAT")
            await vehicle.start(port)
            await wait_until(lambda: inbox.count("HEARTBEAT") > heard, timeout_s=2.0)
            assert link.connected
            assert await link.send(commands.arm(1, True))
            await wait_until(lambda: bool(vehicle.got(400)))
        assert link.stats.connects == 2
        assert link.stats.reconnects == 1
        await vehicle.stop()

    run(body())


def test_tcp_noise_between_frames_does_not_break_the_link() -> None:
    async def body() -> None:
        vehicle = FakeTcpVehicle(noise=True)
        await vehicle.start()
        inbox = Inbox()
        link = MavlinkLink(f"tcp:127.0.0.1:{vehicle.port}", inbox)
        async with running(link):
            await wait_until(lambda: inbox.count("HEARTBEAT") >= 10)
        stats = link.stats
        assert stats.bytes_skipped > 0
        assert stats.connects == 1  # noise is dropped, not a reason to reconnect
        assert all(m.get_type() == "HEARTBEAT" for m in inbox.messages)
        await vehicle.stop()

    run(body())


def test_callback_errors_are_counted_not_fatal() -> None:
    async def body() -> None:
        vehicle = FakeTcpVehicle()
        await vehicle.start()
        calls: list[int] = []

        def explode(link: MavlinkLink, msg: MAVLinkMessage) -> None:
            calls.append(1)
            raise RuntimeError("bug in the service")

        link = MavlinkLink(f"tcp:127.0.0.1:{vehicle.port}", explode)
        async with running(link):
            await wait_until(lambda: len(calls) >= 3)
            assert link.connected
        assert link.stats.callback_errors >= 3
        await vehicle.stop()

    run(body())


def test_cancelling_run_cleans_up_and_close_before_run_returns_at_once() -> None:
    async def body() -> None:
        vehicle = FakeTcpVehicle()
        await vehicle.start()
        inbox = Inbox()
        link = MavlinkLink(f"tcp:127.0.0.1:{vehicle.port}", inbox)
        task = asyncio.create_task(link.run())
        await wait_until(lambda: inbox.count("HEARTBEAT") >= 1)
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
        assert not link.connected
        idle = MavlinkLink(f"tcp:127.0.0.1:{vehicle.port}", Inbox())
        idle.close()
        async with asyncio.timeout(0.5):
            await idle.run()
        assert idle.stats.connect_attempts == 0
        await vehicle.stop()

    run(body())


def test_unreachable_tcp_peer_keeps_retrying_without_raising() -> None:
    async def body() -> None:
        port = free_port()
        link = MavlinkLink(f"tcp:127.0.0.1:{port}", Inbox(), backoff_initial_s=0.02)
        async with running(link):
            await wait_until(lambda: link.stats.connect_attempts >= 3)
            assert not link.connected
        assert link.stats.connects == 0

    run(body())


# -- tlog ---------------------------------------------------------------------------------
def test_tlog_is_readable_by_mavutil(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "logs" / "run.tlog"
    t_start = time.time()

    async def body() -> None:
        vehicle = FakeTcpVehicle()
        await vehicle.start()
        inbox = Inbox()
        link = MavlinkLink(f"tcp:127.0.0.1:{vehicle.port}", inbox, tlog_path=path)
        async with running(link):
            await wait_until(lambda: inbox.count("HEARTBEAT") >= 2)
            await link.send(commands.reposition(1, 47.397742, 8.545594, 788.5))
            await wait_until(lambda: bool(vehicle.got(192)))
        await vehicle.stop()

    run(body())
    t_end = time.time()
    # mavutil picks its dialect from MAVLINK20 and switches globally: keep that to this test.
    monkeypatch.setenv("MAVLINK20", "1")
    monkeypatch.setattr(mavutil, "mavlink", mavutil.mavlink)
    log = mavutil.mavlink_connection(str(path))
    read: list[MAVLinkMessage] = []
    while (msg := log.recv_match()) is not None:
        read.append(msg)
    log.close()
    types = [(m.get_type(), m.get_srcSystem()) for m in read]
    assert types.count(("HEARTBEAT", 1)) >= 2
    assert ("COMMAND_INT", 255) in types
    reposition = next(m for m in read if m.get_type() == "COMMAND_INT")
    assert (reposition.command, reposition.x, reposition.z) == (192, 473977420, 788.5)
    stamps = [m._timestamp for m in read]
    assert stamps == sorted(stamps)
    assert t_start - 1.0 <= stamps[0] <= stamps[-1] <= t_end + 1.0


# -- UDP ----------------------------------------------------------------------------------
class UdpPeer(asyncio.DatagramProtocol):
    """A UDP vehicle socket that records what it receives (and from where)."""

    def __init__(self) -> None:
        self.mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
        self.mav.robust_parsing = True
        self.received: list[tuple[MAVLinkMessage, tuple[str, int]]] = []

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
        for msg in self.mav.parse_buffer(data) or []:
            self.received.append((msg, addr))


async def udp_peer(**kwargs: Any) -> tuple[asyncio.DatagramTransport, UdpPeer]:
    loop = asyncio.get_running_loop()
    transport, peer = await loop.create_datagram_endpoint(UdpPeer, **kwargs)
    return transport, peer


def test_udpin_answers_the_last_sender() -> None:
    async def body() -> None:
        port = free_port()
        inbox = Inbox()
        link = MavlinkLink(f"udpin:127.0.0.1:{port}", inbox)
        transport, vehicle = await udp_peer(remote_addr=("127.0.0.1", port))
        try:
            async with running(link):
                await wait_until(lambda: link.stats.connects == 1)
                assert not link.connected  # bound, but nobody to answer yet
                assert await link.send(commands.gcs_heartbeat()) is False

                async def send_beats() -> None:
                    while inbox.count("HEARTBEAT") < 1:
                        transport.sendto(vehicle_heartbeat(vehicle.mav))
                        await asyncio.sleep(HEARTBEAT_PERIOD_S)

                await send_beats()
                assert link.connected
                # noise datagrams and a truncated frame are dropped without harm
                transport.sendto(bytes(range(256)))
                transport.sendto(vehicle_heartbeat(vehicle.mav)[:7])
                transport.sendto(vehicle_heartbeat(vehicle.mav))
                await wait_until(lambda: inbox.count("HEARTBEAT") >= 2)
                assert await link.send(commands.change_speed(1, 25.0))
                await wait_until(lambda: bool(vehicle.received))
                msg, addr = vehicle.received[0]
                assert (msg.get_type(), msg.command, msg.param2) == ("COMMAND_LONG", 178, 25.0)
                assert addr == ("127.0.0.1", port)
            assert link.stats.parse_errors >= 1
        finally:
            transport.close()

    run(body())


def test_udpin_answers_each_vehicle_where_it_speaks_from() -> None:
    """Two vehicles, each streaming from a socket of its own to one port (as SITL
    instances do with --out): a command goes to the vehicle it addresses only, whichever
    spoke last; a heartbeat (addressed to none) to both."""

    async def body() -> None:
        port = free_port()
        inbox = Inbox()
        link = MavlinkLink(f"udpin:127.0.0.1:{port}", inbox)
        one, vehicle_1 = await udp_peer(remote_addr=("127.0.0.1", port))
        two, vehicle_2 = await udp_peer(remote_addr=("127.0.0.1", port))
        vehicle_2.mav.srcSystem = 2
        try:
            async with running(link):
                while {m.get_srcSystem() for m in inbox.messages} != {1, 2}:
                    one.sendto(vehicle_heartbeat(vehicle_1.mav))
                    two.sendto(vehicle_heartbeat(vehicle_2.mav))
                    await asyncio.sleep(HEARTBEAT_PERIOD_S)
                one.sendto(vehicle_heartbeat(vehicle_1.mav))  # vehicle 1 spoke last
                await asyncio.sleep(0.05)
                assert await link.send(commands.change_speed(2, 25.0))
                assert await link.send(commands.gcs_heartbeat())
                await wait_until(lambda: len(vehicle_2.received) >= 2)
                await wait_until(lambda: len(vehicle_1.received) >= 1)
                await asyncio.sleep(0.05)
        finally:
            one.close()
            two.close()
        kinds_1 = [m.get_type() for m, _ in vehicle_1.received]
        kinds_2 = [m.get_type() for m, _ in vehicle_2.received]
        assert kinds_1 == ["HEARTBEAT"]
        assert kinds_2 == ["COMMAND_LONG", "HEARTBEAT"]

    run(body())


def test_udpout_sends_first_and_reads_answers() -> None:
    async def body() -> None:
        transport, vehicle = await udp_peer(local_addr=("127.0.0.1", 0))
        port = int(transport.get_extra_info("sockname")[1])
        inbox = Inbox()
        link = MavlinkLink(f"udpout:127.0.0.1:{port}", inbox)
        try:
            async with running(link):
                await wait_until(lambda: link.connected)
                assert await link.send(commands.gcs_heartbeat())
                await wait_until(lambda: bool(vehicle.received))
                msg, gcs_addr = vehicle.received[0]
                assert (msg.get_type(), msg.type, msg.get_srcSystem()) == ("HEARTBEAT", 6, 255)
                transport.sendto(vehicle_heartbeat(vehicle.mav), gcs_addr)
                await wait_until(lambda: inbox.count("HEARTBEAT") >= 1)
        finally:
            transport.close()

    run(body())


def test_signing_link_drops_unsigned_vehicle_frames_and_signs_its_own() -> None:
    async def body() -> None:
        vehicle = FakeTcpVehicle()
        await vehicle.start()
        inbox = Inbox()
        link = MavlinkLink(f"tcp:127.0.0.1:{vehicle.port}", inbox, signing_key=bytes(range(32)))
        async with running(link):
            await wait_until(lambda: link.stats.parse_errors >= 2)
            assert await link.send(commands.gcs_heartbeat())
            await wait_until(lambda: bool(vehicle.received))
        assert inbox.messages == []
        assert vehicle.received[0].get_msgbuf()[2] & 0x01  # MAVLINK_IFLAG_SIGNED
        await vehicle.stop()

    run(body())


def test_refused_frames_are_logged_with_their_sender_and_never_the_key(
    caplog: pytest.LogCaptureFixture,
) -> None:
    key = bytes(range(100, 132))

    async def body() -> None:
        vehicle = FakeTcpVehicle()
        await vehicle.start()
        link = MavlinkLink(f"tcp:127.0.0.1:{vehicle.port}", Inbox(), signing_key=key)
        with caplog.at_level("WARNING", logger="gcs_ppf.service.links"):
            async with running(link):
                await wait_until(lambda: link.stats.refused_unsigned >= 3)
        await vehicle.stop()
        assert link.stats.refused_bad_signature == 0

    run(body())
    refused = [r.getMessage() for r in caplog.records if "refused" in r.getMessage()]
    assert len(refused) == 1  # the first at once, the next only after REFUSED_LOG_PERIOD_S
    # (the first read may hold more than one of the vehicle's 20 Hz heartbeats)
    assert re.search(r"refused [1-9]\d* unsigned and 0 wrongly signed", refused[0]), refused[0]
    assert "last from system 1 component 1, message id 0" in refused[0]
    assert key.hex() not in caplog.text


def test_a_link_allowed_unsigned_frames_takes_them_and_signs_its_own() -> None:
    async def body() -> None:
        vehicle = FakeTcpVehicle()
        await vehicle.start()
        inbox = Inbox()
        link = MavlinkLink(
            f"tcp:127.0.0.1:{vehicle.port}", inbox, signing_key=bytes(32), accept_unsigned=True
        )
        async with running(link):
            await wait_until(lambda: inbox.count("HEARTBEAT") >= 2)
            assert await link.send(commands.gcs_heartbeat())
            await wait_until(lambda: bool(vehicle.received))
        assert link.stats.refused_unsigned == 0
        assert vehicle.received[0].get_msgbuf()[2] & 0x01  # MAVLINK_IFLAG_SIGNED
        await vehicle.stop()

    run(body())


def test_setup_signing_is_sent_but_never_written_to_the_tlog(tmp_path: Path) -> None:
    key = bytes(range(7, 39))
    tlog = tmp_path / "link.tlog"

    async def body() -> None:
        vehicle = FakeTcpVehicle()
        await vehicle.start()
        link = MavlinkLink(
            f"tcp:127.0.0.1:{vehicle.port}", Inbox(), tlog_path=tlog, signing_key=key
        )
        async with running(link):
            await wait_until(lambda: link.connected)
            assert await link.send(mavlink2.MAVLink_setup_signing_message(1, 1, key, 5))
            assert await link.send(commands.gcs_heartbeat())
            await wait_until(lambda: len(vehicle.received) >= 2)
        await vehicle.stop()
        assert [m.get_type() for m in vehicle.received[:2]] == ["SETUP_SIGNING", "HEARTBEAT"]

    run(body())
    data = tlog.read_bytes()
    assert key not in data
    assert len(data) > 0  # the heartbeat is there


# -- serial -------------------------------------------------------------------------------
def test_serial_heartbeat_in_command_out_on_a_pseudo_terminal() -> None:
    """The link opens a pty's device end at 57,600 baud as a radio's USB port; the test
    is the radio on the other end."""
    radio, device = os.openpty()
    tty.setraw(device)  # as the link will set it: no echo of what comes before it opens
    os.set_blocking(radio, False)
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)

    async def body() -> None:
        inbox = Inbox()
        link = MavlinkLink(f"serial:{os.ttyname(device)}:57600", inbox)
        received = bytearray()
        async with running(link):
            for _ in range(100):
                os.write(radio, vehicle_heartbeat(mav))
                await asyncio.sleep(0.02)
                if inbox.count("HEARTBEAT"):
                    break
            assert link.connected
            assert await link.send(commands.set_mode(1, PlaneMode.LOITER))
            parser = mavlink2.MAVLink(None)
            parser.robust_parsing = True
            got: list[Any] = []
            for _ in range(100):
                with contextlib.suppress(BlockingIOError):
                    received.extend(os.read(radio, 4096))
                got = [m for m in parser.parse_buffer(bytes(received)) or []]
                received.clear()
                if got:
                    break
                await asyncio.sleep(0.02)
            assert [(m.get_type(), m.command, m.param2) for m in got] == [
                ("COMMAND_LONG", 176, 12.0)
            ]
        assert inbox.count("HEARTBEAT") >= 1
        assert link.stats.connects == 1

    try:
        run(body())
    finally:
        os.close(radio)
        os.close(device)


def test_a_serial_line_that_fills_up_drains_and_goes_quiet() -> None:
    """Frames sent faster than the line takes them (a radio's buffer full) wait and go out
    in order; once they are out the transport stops asking to write (pyserial-asyncio-fast
    0.16 kept its writer after a partial write and raised "Write buffer should not be
    empty" on every turn of the loop, a core spinning, until the next write)."""
    radio, device = os.openpty()
    tty.setraw(device)
    tty.setraw(radio)
    errors: list[dict[str, Any]] = []
    frames = 3000  # 3000 x 41 bytes: more than a pty holds

    frame_len = len(commands.set_mode(1, PlaneMode.RTL).pack(mavlink2.MAVLink(None)))

    def radio_reads(into: bytearray) -> None:
        """The other end, read from 0.3 s on (the line full meanwhile) until every frame is
        in, 5 s at most."""
        time.sleep(0.3)
        until = time.monotonic() + 5.0
        while len(into) < frames * frame_len and time.monotonic() < until:
            try:
                into.extend(os.read(radio, 65536))
            except BlockingIOError:
                time.sleep(0.005)

    async def body() -> None:
        asyncio.get_running_loop().set_exception_handler(lambda _loop, ctx: errors.append(ctx))
        link = MavlinkLink(f"serial:{os.ttyname(device)}:57600", Inbox())
        received = bytearray()
        os.set_blocking(radio, False)
        async with running(link):
            await wait_until(lambda: link.connected)
            reader = asyncio.create_task(asyncio.to_thread(radio_reads, received))
            for k in range(frames):  # the sends wait while the line is full
                await link.send(commands.set_mode(1, PlaneMode.LOITER if k % 2 else PlaneMode.RTL))
            await reader
            await asyncio.sleep(0.2)  # the loop turns with nothing left to write
        assert link.stats.reconnects == 0
        parser = mavlink2.MAVLink(None)
        got = parser.parse_buffer(bytes(received)) or []
        assert [m.param2 for m in got] == [12.0 if k % 2 else 11.0 for k in range(frames)]
        assert errors == []

    try:
        run(body())
    finally:
        os.close(radio)
        os.close(device)


def test_a_serial_device_that_is_not_there_is_tried_again() -> None:
    async def body() -> None:
        link = MavlinkLink(
            "serial:/dev/gcs-ppf-no-such-radio:57600",
            Inbox(),
            backoff_initial_s=0.05,
            backoff_max_s=0.1,
        )
        async with running(link):
            await wait_until(lambda: link.stats.connect_attempts >= 3)
            assert not link.connected
        assert link.stats.connects == 0

    run(body())


def test_a_serial_links_radio_load_is_its_bytes_against_its_baud() -> None:
    entry = LinkEntry(
        1, "serial:/dev/ttyUSB0:57600", MavlinkLink("serial:/dev/ttyUSB0:57600", Inbox())
    )
    assert entry.radio_load(1.0) is None  # no samples yet
    entry.traffic.extend([(100.0, 0, 0), (105.0, 5760 * 5, 2880 * 5)])
    assert entry.radio_load(1.0) == pytest.approx((1.0, 0.5))
    assert entry.radio_load(10.0) == pytest.approx((0.1, 0.05))  # five s of ours, 50 of theirs
    tcp = LinkEntry(2, "tcp:127.0.0.1:5760", MavlinkLink("tcp:127.0.0.1:5760", Inbox()))
    tcp.traffic.extend([(100.0, 0, 0), (105.0, 10**6, 10**6)])
    assert tcp.radio_load(1.0) is None

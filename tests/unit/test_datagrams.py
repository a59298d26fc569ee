"""DatagramSocket: a UDP backlog read whole at one wake-up, sends that never wait."""

from __future__ import annotations

import asyncio
import socket

import pytest

from gcs_ppf.datagrams import DatagramSocket

pytestmark = pytest.mark.realtime  # UDP on loopback, a port closed and bound again


def test_a_backlog_is_read_at_one_wake_up_in_order() -> None:
    """Datagrams that arrived while the event loop was busy come in one batch, in the
    order sent (asyncio's transport would hand over one per wake-up)."""

    async def main() -> list[bytes]:
        udp = await DatagramSocket.open(local=("127.0.0.1", 0))
        address = udp._sock.getsockname()
        sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        for k in range(200):  # the loop does not run meanwhile: a backlog builds up
            sender.sendto(k.to_bytes(2, "big"), address)
        batch = await asyncio.wait_for(udp.batches.get(), 5)
        assert batch is not None
        assert {a for _, a in batch} == {("127.0.0.1", sender.getsockname()[1])}
        sender.close()
        udp.close()
        assert await udp.batches.get() is None  # closed: the reader is told
        return [data for data, _ in batch]

    received = asyncio.run(main())
    assert received == [k.to_bytes(2, "big") for k in range(200)]


def test_a_peer_not_listening_is_counted_not_fatal() -> None:
    """A client socket whose peer is not up: the ICMP errors are counted, and the socket
    reads its peer's datagrams once it is up."""

    async def main() -> tuple[int, bytes]:
        peer = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        peer.bind(("127.0.0.1", 0))
        address = peer.getsockname()
        peer.close()  # nobody listens there now
        udp = await DatagramSocket.open(remote=address)
        for _ in range(3):
            udp.sendto(b"hello")
            await asyncio.sleep(0.02)
        errors = udp.errors
        peer = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        peer.bind(address)
        udp.sendto(b"again")
        data, back = peer.recvfrom(100)
        peer.sendto(b"answer", back)
        batch = await asyncio.wait_for(udp.batches.get(), 5)
        assert batch is not None
        assert data == b"again"
        peer.close()
        udp.close()
        return errors, batch[0][0]

    errors, answer = asyncio.run(main())
    assert errors >= 1
    assert answer == b"answer"

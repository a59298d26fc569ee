"""A UDP socket on the event loop that reads its whole backlog at each wake-up.

asyncio's own datagram transport reads one datagram each time the event loop wakes for the
socket.  On a busy machine the loop wakes a few hundred times a second, fewer than the
datagrams five vehicles stream at ×10 (about a thousand), so the rest waits in the kernel's
buffer: the positions the service read were seconds old, and when the buffer filled the
kernel dropped whole seconds of them at once (Table 3 on one ``udpin`` port with a CPU
burner per core: telemetry 1.5 vehicle s late at the median, 7.3 s at p99, the run failed).
A TCP read takes everything waiting; this does the same for UDP, as pymavlink's and
mavlink-router's readers do (a loop of ``recvfrom`` until the socket is empty).

Sending never waits: a datagram the kernel cannot take now is dropped and counted, as UDP
drops it anywhere else on the way.
"""

from __future__ import annotations

import asyncio
import socket

Address = tuple[str, int]

MAX_DATAGRAM = 65535
MAX_BATCH = 4096
"""Datagrams read at one wake-up at most (the rest at the next), so that a flood cannot
hold the event loop."""


class DatagramSocket:
    """A non-blocking UDP socket: ``batches`` holds what each wake-up read (None once
    closed); ``sendto`` writes without waiting."""

    def __init__(self, sock: socket.socket) -> None:
        sock.setblocking(False)
        self._sock = sock
        self._loop = asyncio.get_running_loop()
        self._closed = False
        self.batches: asyncio.Queue[list[tuple[bytes, Address]] | None] = asyncio.Queue()
        self.errors = 0
        """ICMP errors reported on the socket (a peer not listening yet): not fatal."""
        self.dropped = 0
        """Datagrams the kernel could not take when sent."""
        self._loop.add_reader(sock.fileno(), self._readable)

    @classmethod
    async def open(
        cls, local: Address | None = None, remote: Address | None = None
    ) -> DatagramSocket:
        """A socket bound to ``local`` (listening) or connected to ``remote`` (a client)."""
        loop = asyncio.get_running_loop()
        host, port = local or remote or ("", 0)
        infos = await loop.getaddrinfo(host, port, type=socket.SOCK_DGRAM)
        family, kind, proto, _, address = infos[0]
        sock = socket.socket(family, kind, proto)
        try:
            if local is not None:
                sock.bind(address)
            else:
                sock.connect(address)
        except OSError:
            sock.close()
            raise
        return cls(sock)

    def _readable(self) -> None:
        batch: list[tuple[bytes, Address]] = []
        for _ in range(MAX_BATCH):
            try:
                data, address = self._sock.recvfrom(MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:  # ICMP "port unreachable" after a send: the peer is not up yet
                self.errors += 1
                continue
            batch.append((data, address[:2]))
        if batch:
            self.batches.put_nowait(batch)

    def sendto(self, data: bytes, address: Address | None = None) -> None:
        if self._closed:
            return
        try:
            if address is None:
                self._sock.send(data)
            else:
                self._sock.sendto(data, address)
        except (BlockingIOError, InterruptedError):
            self.dropped += 1
        except OSError:
            self.errors += 1

    def is_closing(self) -> bool:
        return self._closed

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._loop.remove_reader(self._sock.fileno())
        self._sock.close()
        self.batches.put_nowait(None)

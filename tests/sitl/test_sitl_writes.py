"""How a vehicle's frames reach its clients: a TCP client gets the frames of one event in one
write (one system call), a datagram or radio peer one frame a write; the bytes, their order
and the drops are what one write a frame gave."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from gcs_ppf.mission import Mission
from sitl.engine import Simulation
from sitl.server import MAX_BUFFERED, Peer, VehicleLink

ROOT = Path(__file__).resolve().parents[2]


def _link() -> tuple[Simulation, VehicleLink]:
    mission = Mission.model_validate(json.loads((ROOT / "examples/paper_table2.json").read_text()))
    sim = Simulation(mission)
    return sim, VehicleLink(sim, 0, 1.0, 0, None, None)


def test_a_stream_peer_gets_an_event_in_one_write_with_the_same_bytes() -> None:
    async def main() -> None:
        sim, link = _link()
        stream_writes: list[bytes] = []
        frame_writes: list[bytes] = []
        link.peers.append(Peer(link, stream_writes.append, "tcp", stream=True))
        link.peers.append(Peer(link, frame_writes.append, "udp"))
        events = 0
        for _ in range(100):
            for i, out in sim.step(0.0):
                if i == 0:
                    link.send(out, None)
                    events += len(out.broadcast) > 0
        assert events > 0
        assert len(stream_writes) == events  # one write an event
        assert len(frame_writes) > events  # one write a frame
        assert b"".join(stream_writes) == b"".join(frame_writes)
        parser = mavlink.MAVLink(None)
        frames = parser.parse_buffer(b"".join(stream_writes)) or []
        assert [f.get_msgbuf() for f in frames] == frame_writes

    asyncio.run(main())


def test_a_full_client_buffer_drops_as_before() -> None:
    async def main() -> None:
        sim, link = _link()
        writes: list[bytes] = []
        peer = Peer(link, writes.append, "tcp", stream=True)
        peer.buffered = lambda: MAX_BUFFERED + 1
        link.peers.append(peer)
        for i, out in sim.step(0.0):
            if i == 0:
                link.send(out, None)
        assert writes == []
        assert link.stats.dropped > 0
        assert link.stats.tx_msgs == 0

    asyncio.run(main())

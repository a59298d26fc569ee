"""The fence list's transfer against the SITL's own server (in process): upload, download,
a refusal named, an unanswered vehicle given up on."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Iterator
from typing import Any

import pytest

from gcs_ppf.mavlink import fences
from gcs_ppf.service import mission_transfer
from sitl import fence
from sitl import mission_protocol as mp

ITEMS = [
    fences.FenceItem(fences.CIRCLE_EXCLUSION, 474000000, 85500000, 200.0),
    *[fences.FenceItem(fences.POLYGON_INCLUSION, 473900000 + k * 10000, 85400000, 3.0)
      for k in range(3)],
]  # fmt: skip


class Vehicle:
    """A fleet of one whose vehicle is the SITL's fence server; ``drop`` loses every
    ``drop``-th message we send."""

    def __init__(self, drop: int = 0, mute: bool = False) -> None:
        self.server = mp.MissionServer(mp.MISSION_TYPE_FENCE, fence.validate_item)
        self.inbox: asyncio.Queue[Any] | None = None
        self.sent = 0
        self.drop = drop
        self.mute = mute

    def clock_rate(self) -> float:
        return 10.0  # a SITL at x10: the timeouts are a tenth

    @contextlib.contextmanager
    def mission_inbox(self, vid: int) -> Iterator[asyncio.Queue[Any]]:
        self.inbox = asyncio.Queue()
        yield self.inbox

    async def send(self, vid: int, msg: Any) -> None:
        self.sent += 1
        if self.mute or (self.drop and self.sent % self.drop == 0):
            return
        src, kind = (255, 190), msg.get_type()
        if kind == "MISSION_COUNT":
            res = self.server.on_count(src, msg.count, msg.mission_type, 0.0)
        elif kind == "MISSION_ITEM_INT":
            res = self.server.on_item(
                src, msg.seq, mp.item_from_message(msg), msg.mission_type, 0.0
            )
        elif kind == "MISSION_REQUEST_LIST":
            res = self.server.on_request_list(src, msg.mission_type)
        elif kind == "MISSION_REQUEST_INT":
            res = self.server.on_request(src, msg.seq, msg.mission_type, None, as_int=True)  # type: ignore[arg-type]
        else:
            return
        assert self.inbox is not None
        for reply in res.replies:
            self.inbox.put_nowait(reply)


def test_upload_then_download_reads_back_what_was_sent_even_on_a_lossy_link() -> None:
    async def scenario(v: Vehicle) -> list[fences.FenceItem]:
        await mission_transfer.upload(v, 1, ITEMS)  # type: ignore[arg-type]
        return await mission_transfer.download(v, 1)  # type: ignore[arg-type]

    for drop in (0, 3):
        assert fences.same(ITEMS, asyncio.run(scenario(Vehicle(drop))))


def test_a_refusal_is_named_and_a_silent_vehicle_given_up_on() -> None:
    bad = [fences.FenceItem(fences.POLYGON_INCLUSION, 474000000, 85500000, 2.0)]
    with pytest.raises(mission_transfer.TransferFailed, match="MAV_MISSION_INVALID_PARAM1"):
        asyncio.run(mission_transfer.upload(Vehicle(), 1, bad))  # type: ignore[arg-type]
    with pytest.raises(mission_transfer.TransferFailed, match="not answered after 5 tries"):
        asyncio.run(mission_transfer.upload(Vehicle(mute=True), 1, ITEMS))  # type: ignore[arg-type]

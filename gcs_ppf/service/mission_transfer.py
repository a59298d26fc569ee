"""The ground station's half of the mission protocol for a vehicle's fence list: upload,
download, clear (``gcs_ppf.mavlink.fences`` builds the messages).

As the MAVLink guide has it and ArduPilot answers: MISSION_COUNT, then the vehicle asks
for each item by MISSION_REQUEST_INT and ends with MISSION_ACK; a download is
MISSION_REQUEST_LIST, MISSION_COUNT, each item asked for, and our MISSION_ACK.  A message
not answered within ``ITEM_TIMEOUT_S`` (the guide's 1.5 s for the count, here for each
step, in the vehicle's seconds) is sent again, up to ``ATTEMPTS`` times; a refusal is
final (``TransferFailed`` with the vehicle's MAV_MISSION_RESULT).
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Iterator
from typing import Any

from gcs_ppf.mavlink import fences
from gcs_ppf.mavlink.fences import FenceItem
from gcs_ppf.service.errors import Conflict
from gcs_ppf.service.fleet import Fleet

ITEM_TIMEOUT_S = 1.5
ATTEMPTS = 5


class TransferFailed(Exception):
    """A fence transfer the vehicle refused or never finished."""


async def _next(
    inbox: asyncio.Queue[Any], kinds: set[str], timeout_s: float, mission_type: int
) -> Any | None:
    """The next message of ``kinds`` about the fence list within ``timeout_s``; None."""
    deadline = time.monotonic() + timeout_s
    while (left := deadline - time.monotonic()) > 0:
        try:
            msg = await asyncio.wait_for(inbox.get(), left)
        except TimeoutError:
            return None
        if msg.get_type() in kinds and getattr(msg, "mission_type", 0) == mission_type:
            return msg
    return None


@contextlib.contextmanager
def _inbox(fleet: Fleet, vid: int) -> Iterator[asyncio.Queue[Any]]:
    """``Fleet.mission_inbox``; another transfer in progress is a ``TransferFailed``."""
    try:
        with fleet.mission_inbox(vid) as inbox:
            yield inbox
    except Conflict as exc:
        raise TransferFailed(str(exc)) from None


def _timeout_s(fleet: Fleet) -> float:
    return ITEM_TIMEOUT_S / fleet.clock_rate()


async def upload(fleet: Fleet, vid: int, items: list[FenceItem]) -> None:
    """``items`` as the vehicle's fence list (none: the list cleared).  A silence is met
    by sending again what the vehicle last had from us: the count, or the item it last
    asked for (a lost request, a lost item), ``ATTEMPTS`` times in a row at most."""
    kind = fences.MISSION_TYPE_FENCE
    with _inbox(fleet, vid) as inbox:
        last: Any = fences.count(vid, len(items))
        await fleet.send(vid, last)
        silences = 0
        while silences < ATTEMPTS:
            msg = await _next(
                inbox, {"MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"},
                _timeout_s(fleet), kind,
            )  # fmt: skip
            if msg is None:
                silences += 1
                await fleet.send(vid, last)
                continue
            silences = 0
            if msg.get_type() == "MISSION_ACK":
                if msg.type == 0:
                    return
                raise TransferFailed(f"fence upload refused: {fences.result_name(msg.type)}")
            if 0 <= msg.seq < len(items):
                last = fences.item(vid, msg.seq, items[msg.seq])
                await fleet.send(vid, last)
    raise TransferFailed(f"fence upload not answered after {ATTEMPTS} tries")


async def download(fleet: Fleet, vid: int) -> list[FenceItem]:
    """The vehicle's fence list as it holds it."""
    kind = fences.MISSION_TYPE_FENCE
    with _inbox(fleet, vid) as inbox:
        count = None
        for _ in range(ATTEMPTS):
            await fleet.send(vid, fences.request_list(vid))
            count = await _next(inbox, {"MISSION_COUNT"}, _timeout_s(fleet), kind)
            if count is not None:
                break
        if count is None:
            raise TransferFailed("fence download: no MISSION_COUNT")
        out: list[FenceItem] = []
        for seq in range(int(count.count)):
            for _ in range(ATTEMPTS):
                await fleet.send(vid, fences.request(vid, seq))
                msg = await _next(inbox, {"MISSION_ITEM_INT"}, _timeout_s(fleet), kind)
                if msg is not None and msg.seq == seq:
                    out.append(fences.item_of(msg))
                    break
            else:
                raise TransferFailed(f"fence download: item {seq} never came")
        await fleet.send(vid, fences.ack(vid))
        return out

"""The mission's zones as each vehicle's own fence for the run (issue 27 item 3): if the
service stalls, dies or loses the link, the autopilot itself refuses to enter a no-fly zone
or to leave a stay-inside one.

At the launch, for each vehicle at once: its fence list as it was (downloaded), the zones'
fence items (``gcs_ppf.mavlink.fences``) uploaded and downloaded again to verify, then
FENCE_TYPE with its polygon bit, FENCE_ACTION as the settings say and FENCE_ENABLE 1, each
read back (``fence_set``, or ``fence_failed`` with why); again when zones are added mid-run
(``FormationService.add_zones``), keeping what the vehicle had before the run.  When the
run's holds are handed over, the list it had goes back and the three parameters with it
(``fence_restored``).  Nothing here may take the service down: a failure is an event.
"""

from __future__ import annotations

import asyncio
import logging
import time
from typing import Any

from gcs_ppf.mavlink import commands, fences
from gcs_ppf.service import launch, mission_transfer
from gcs_ppf.service.confirmation import wait_until
from gcs_ppf.service.run import Run, SavedFence
from gcs_ppf.service.station import Station

log = logging.getLogger("gcs_ppf.service.runs")

POLYGON_TYPE = 4
"""FENCE_TYPE's bit of polygons and circles."""


async def put_up(station: Station, run: Run, ids: list[int]) -> None:
    """The zones as every vehicle's fence (nothing when the mission has none to upload)."""
    settings = station.settings
    items, left_out = fences.fence_items(run.mission, settings.fence_footprints)
    if left_out:
        station.event(run, "fence_zones_left_out", None, zones=left_out)
    if not items:
        return
    await asyncio.gather(*(_guarded(station, run, vid, _put_up_one(station, run, vid, items))
                           for vid in ids))  # fmt: skip


async def _guarded(station: Station, run: Run, vid: int, work: Any) -> None:
    """``work`` awaited; any failure an event (``fence_failed``), never the service's end."""
    try:
        await work
    except asyncio.CancelledError:
        raise
    except mission_transfer.TransferFailed as exc:
        station.event(run, "fence_failed", vid, reason=str(exc))
    except Exception as exc:
        log.exception("mission %d: the fence of vehicle %d", run.mission_id, vid)
        station.event(run, "fence_failed", vid, reason=f"error: {exc}")


FENCE_PARAMS = ("FENCE_ENABLE", "FENCE_TYPE", "FENCE_ACTION")
READ_TIMEOUT_S = 2.0
"""Vehicle seconds a parameter asked for (PARAM_REQUEST_READ) is waited for."""


async def _read(station: Station, vid: int, names: tuple[str, ...]) -> dict[str, float | None]:
    """The parameters as the vehicle holds them (None: not answered)."""
    fleet = station.fleet
    asked = time.monotonic()
    for name in names:
        await fleet.send(vid, commands.param_request_read(vid, name))

    def value(name: str) -> float | None:
        t = fleet.telemetry(vid)
        p = None if t is None else t.param(name)
        return p.value if p is not None and p.received_s >= asked else None

    await wait_until(
        lambda: all(value(n) is not None for n in names),
        READ_TIMEOUT_S / fleet.clock_rate(),
        0.05,
    )
    return {n: value(n) for n in names}


async def _param(station: Station, run: Run, vid: int, name: str, value: float) -> float | None:
    return await launch.set_param(station.fleet, vid, name, value, station.events_of(run))


async def _put_up_one(station: Station, run: Run, vid: int, items: list[fences.FenceItem]) -> None:
    fleet, settings = station.fleet, station.settings
    uploaded = "the items read back differ from those sent"
    try:
        before = await mission_transfer.download(fleet, vid)
        try:
            await mission_transfer.upload(fleet, vid, items)
        except mission_transfer.TransferFailed as exc:  # the list read back says (a lost ACK)
            uploaded = str(exc)
        read = await mission_transfer.download(fleet, vid)
    except mission_transfer.TransferFailed as exc:
        station.event(run, "fence_failed", vid, reason=str(exc))
        return
    if not fences.same(items, read):
        station.event(run, "fence_failed", vid, reason=uploaded)
        return
    was = await _read(station, vid, FENCE_PARAMS)
    # put up again (zones added mid-run): what the vehicle had before the run is kept
    run.fences_before.setdefault(vid, SavedFence(before, was))
    was = {**was, **run.fences_before[vid].params}
    fence_type = int(was["FENCE_TYPE"] or 0) | POLYGON_TYPE
    set_type = await _param(station, run, vid, "FENCE_TYPE", fence_type)
    set_action = await _param(station, run, vid, "FENCE_ACTION", settings.fence_action)
    enabled = await _param(station, run, vid, "FENCE_ENABLE", 1)
    station.event(
        run,
        "fence_set",
        vid,
        items=len(items),
        verified=True,
        fence_type=set_type,
        fence_action=set_action,
        fence_enable=enabled,
    )


async def take_down(station: Station, run: Run) -> None:
    """Each vehicle's fence list and parameters as they were before the run."""

    async def one(vid: int, saved: SavedFence) -> None:
        try:
            await mission_transfer.upload(station.fleet, vid, saved.items)
        except mission_transfer.TransferFailed as exc:
            station.event(run, "fence_failed", vid, reason=f"restoring: {exc}")
            return
        enable = saved.params.get("FENCE_ENABLE")
        await _param(station, run, vid, "FENCE_ENABLE", 0 if enable is None else enable)
        for name in FENCE_PARAMS[1:]:
            value = saved.params.get(name)
            if value is not None:
                await _param(station, run, vid, name, value)
        station.event(run, "fence_restored", vid, items=len(saved.items))

    saved = dict(run.fences_before)
    run.fences_before.clear()
    await asyncio.gather(*(_guarded(station, run, vid, one(vid, s)) for vid, s in saved.items()))

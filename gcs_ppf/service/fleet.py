"""The vehicles the service talks to: MAVLink links, discovery by heartbeat, liveness.

Owns the links (``gcs_ppf.service.links``) and what is known of each vehicle; sends our heartbeat
on every link, asks new vehicles for their telemetry streams (SET_MESSAGE_INTERVAL only) and
their airframe parameters (``gcs_ppf.guidance.airframe``), and marks silent ones lost
(the timeout in the vehicle's own seconds, ``gcs_ppf.guidance.vehicle_clock``).  The service's runs
read ``by_id`` and call ``send``; ``telemetry_event`` wakes them when positions arrive.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import statistics
import time
from collections import deque
from collections.abc import Callable, Coroutine, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gcs_ppf.geodesy import geodetic_to_enu
from gcs_ppf.guidance import lag
from gcs_ppf.guidance.airframe import Airframe
from gcs_ppf.guidance.online import VehicleState, state_from_velocity
from gcs_ppf.guidance.vehicle_clock import VehicleClock
from gcs_ppf.mavlink import commands, radio_budget
from gcs_ppf.mavlink.ardupilot import mode_name
from gcs_ppf.mavlink.codec import signing_timestamp
from gcs_ppf.mavlink.telemetry import AIRFRAME_PARAMS, VehicleTelemetry, apply
from gcs_ppf.mission import Mission
from gcs_ppf.service import link_choice
from gcs_ppf.service.errors import Conflict, NotFound, ServiceError
from gcs_ppf.service.forwarding import Forwarding
from gcs_ppf.service.link_choice import Fix, LinkSeen
from gcs_ppf.service.links import LinkKind, MavlinkLink, parse_link_url
from gcs_ppf.service.settings import Settings

log = logging.getLogger("gcs_ppf.service.fleet")

MAX_PREDICTION_S = 2.0
"""A state is not carried on further than this (vehicle seconds): a silent vehicle is the
watchdog's business, not dead reckoning's, and a lag beyond the budget is an event."""
WATCHDOG_PERIOD_S = 0.2
"""Vehicle seconds between two checks for silent vehicles."""
STALL_S = 0.25
"""The watchdog woken this much later than it asked (our seconds): the event loop stalled."""
STALL_DRAIN_S = 0.05
"""After a stall, our seconds the links' readers get before anyone is declared lost."""
ALL_SILENT_FACTOR = 3.0
"""When every vehicle is silent at once, each is lost only after this many timeouts."""
BOOT_HISTORY_STEP_S = 0.05
BOOT_HISTORY_KEPT = 400  # 20 s of ours
ROUND_TRIPS_KEPT = 5
MAX_ROUND_TRIP_S = 30.0  # a TIMESYNC answer older than this is not ours

STREAMED = {  # message id → rate factor of settings.stream_rate_hz
    33: 1.0,  # GLOBAL_POSITION_INT
    30: 0.2,  # ATTITUDE (shown in GET /vehicles only: the tick plans from velocities)
    74: 0.5,  # VFR_HUD
    2: 0.2,  # SYSTEM_TIME
    1: 0.2,  # SYS_STATUS
}


PARAM_ASKS = 10
"""Airframe parameters a vehicle has not answered are asked for again with each of our
heartbeats, this many times (names an ArduPlane version does not have are never answered).
Asked twice only, on a link losing 20 % of its packets a vehicle of five flew without its
TECS limits (so by the planned vertical speed in param3, which ArduPlane barely climbs by)
and its wingman stayed 1–2 km below its slot in Table 2's climb."""
MISSION_REPLIES = frozenset(
    {"MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK", "MISSION_COUNT", "MISSION_ITEM_INT"}
)
"""A vehicle's side of the mission protocol, handed to a transfer in progress."""
TRAFFIC_SAMPLES = 6
"""Heartbeats over which a serial link's load is measured (5 of its seconds at 1 Hz)."""
RADIO_FULL = 0.9
"""A radio link carrying more than this fraction of its baud rate either way is told in the
log: beyond it, a radio's buffer fills and it drops what does not fit."""
IDENTITY_CHECK_S = 1.0
"""Our seconds between two looks at whether the links a vehicle is heard on carry one
vehicle or two (the positions compared: a few hundred each, at every message otherwise)."""
UNMEASURED_HEARTBEAT_HZ = 10.0
"""Our heartbeats per second of ours while a vehicle's clock rate is not yet measured."""
HEARTBEAT_POLL_S = 0.05
"""How often (ours) the heartbeats' period is looked at."""


@dataclass
class Vehicle:
    """A vehicle discovered by its heartbeat on a link."""

    system_id: int
    link_id: int
    telemetry: VehicleTelemetry
    last_heard_s: float
    lost: bool = False
    clock: VehicleClock = field(default_factory=VehicleClock)
    round_trips_s: deque[float] = field(default_factory=lambda: deque(maxlen=ROUND_TRIPS_KEPT))
    """The link's last round trips (our seconds), from TIMESYNC."""
    param_asks: int = 0
    """How many times its airframe parameters not answered yet were asked for again."""
    heard_on: dict[int, float] = field(default_factory=dict)
    """Link id → when (our monotonic seconds) it was last heard there."""
    duplicate_links: tuple[int, ...] = ()
    """The links one system id is heard on at once, when they carry two vehicles
    (``Fleet.duplicates``)."""
    redundant_links: tuple[int, ...] = ()
    """The links it is heard on at once, when they carry this one vehicle (a radio and a
    backup): it is commanded on the better (``link_choice``)."""
    links_seen: dict[int, LinkSeen] = field(default_factory=dict)
    """Link id → what the link carried of it lately (``link_choice``)."""
    link_change: tuple[int, int, str] | None = None
    """The last change of the link it is commanded on: (from, to, why)."""
    link_switched_s: float = -math.inf
    """When (ours) it last did."""
    identity_checked_s: float = -math.inf
    """When (ours) its links were last told one vehicle or two (``Fleet._check_duplicate``)."""
    stream_rate_hz: float | None = None
    """The position rate its streams were last asked for at (``Fleet.stream_rate_hz``)."""
    boot_history: deque[tuple[float, int]] = field(
        default_factory=lambda: deque(maxlen=BOOT_HISTORY_KEPT)
    )
    """(our seconds, its time_boot_ms) of its recent messages, one per ``BOOT_HISTORY_STEP_S``:
    how far its clock went while another vehicle was silent."""

    def clock_advance_s(self, since_s: float) -> float | None:
        """Its seconds from our ``since_s`` to its last message (its clock as its messages
        read; not carried on past the last, which a starved ground station reads late);
        None if its history does not reach back to ``since_s``."""
        h = self.boot_history
        if not h or h[0][0] > since_s:
            return None
        walls = [w for w, _ in h]
        boots = [b for _, b in h]
        then = float(np.interp(since_s, walls, boots)) / 1000.0
        return h[-1][1] / 1000.0 - then

    @property
    def round_trip_s(self) -> float | None:
        """The link's round trip now (our seconds): the median of the last few, or None."""
        return statistics.median(self.round_trips_s) if self.round_trips_s else None


@dataclass
class LinkEntry:
    id: int
    url: str
    link: MavlinkLink
    task: asyncio.Task[None] | None = None
    traffic: deque[tuple[float, int, int]] = field(
        default_factory=lambda: deque(maxlen=TRAFFIC_SAMPLES)
    )
    """(our monotonic s, bytes in, bytes out) at each of our heartbeats: the link's rate."""
    warned_full: bool = False

    def radio_load(self, clock_rate: float) -> tuple[float, float] | None:
        """A serial link's bytes a second down and up over its last samples, per vehicle
        second, as fractions of what its baud rate carries (8N1); None for other links or
        before two samples."""
        if self.link.url.kind is not LinkKind.SERIAL or len(self.traffic) < 2:
            return None
        (t0, in0, out0), (t1, in1, out1) = self.traffic[0], self.traffic[-1]
        seconds = (t1 - t0) * clock_rate
        if seconds <= 0.0:
            return None
        capacity = self.link.url.port / 10.0
        return (in1 - in0) / seconds / capacity, (out1 - out0) / seconds / capacity


class Fleet:
    """Links and vehicles; ``spawn`` runs a coroutine as a task of the service."""

    def __init__(
        self, settings: Settings, spawn: Callable[[Coroutine[Any, Any, Any]], asyncio.Task[Any]]
    ) -> None:
        self.settings = settings
        self._spawn = spawn
        self._links: dict[int, LinkEntry] = {}
        self._next_link_id = 1
        self._decoded_gone_s = 0.0  # ``decoding_s`` of the links removed
        self._inboxes: dict[int, asyncio.Queue[Any]] = {}  # ``mission_inbox``
        self.by_id: dict[int, Vehicle] = {}
        self.telemetry_event = asyncio.Event()
        self.telemetry_received_s = 0.0  # perf_counter of the latest position message
        self.forwarding: Forwarding | None = None
        """Other ground stations the vehicles' frames are relayed to (``service.forwarding``)."""

    def close(self) -> None:
        """Close every link (the service is stopping)."""
        for entry in list(self._links.values()):
            entry.link.close()
            if entry.task is not None:
                entry.task.cancel()

    # Links -------------------------------------------------------------------------------
    async def add_link(self, url: str, *, allow_unsigned: bool | None = None) -> dict[str, Any]:
        """Open a link to ``url``.  With a signing key (``Settings.signing_key``) it signs
        every frame it sends, as MAVLink link id ``id % 256``, and refuses unsigned or wrongly
        signed frames unless ``allow_unsigned`` (default: ``url`` is one of the settings'
        ``unsigned_links``)."""
        if allow_unsigned is None:
            allow_unsigned = url in self.settings.unsigned_links
        try:
            parse_link_url(url)
        except ValueError as exc:
            raise ServiceError(f"url: {exc}") from None
        if any(e.url == url for e in self._links.values()):
            raise Conflict(f"url: a link to {url} exists already")
        link_id = self._next_link_id
        self._next_link_id += 1
        tlog = None
        if self.settings.tlog_dir is not None:
            tlog = Path(self.settings.tlog_dir) / f"link{link_id}-{int(time.time())}.tlog"
            tlog.parent.mkdir(parents=True, exist_ok=True)

        def on_message(_link: MavlinkLink, msg: Any) -> None:
            self._on_message(link_id, msg)

        link = MavlinkLink(
            url,
            on_message,
            source_system=self.settings.system_id,
            tlog_path=tlog,
            signing_key=self.settings.signing_key_bytes,
            signing_link_id=link_id % 256,
            accept_unsigned=allow_unsigned,
        )
        entry = LinkEntry(link_id, url, link)
        entry.task = self._spawn(link.run())
        self._links[link_id] = entry
        signing = "unsigned" if not link.codec.signing else "signed"
        if link.codec.accept_unsigned:
            signing += ", unsigned frames accepted"
        log.info("link %d: %s (%s)", link_id, url, signing)
        return self._link_info(entry)

    def decoding_s(self) -> float:
        """Our seconds the links have spent decoding and handing on what they received
        (``MavlinkLink.receiving_s``), since the service started."""
        return sum(e.link.receiving_s for e in self._links.values()) + self._decoded_gone_s

    def links(self) -> list[dict[str, Any]]:
        return [self._link_info(e) for e in self._links.values()]

    async def remove_link(self, link_id: int) -> None:
        entry = self._links.pop(link_id, None)
        if entry is None:
            raise NotFound(f"link {link_id} does not exist")
        self._decoded_gone_s += entry.link.receiving_s
        entry.link.close()
        if entry.task is not None:
            entry.task.cancel()

    def _link_info(self, entry: LinkEntry) -> dict[str, Any]:
        vehicles = sorted(v.system_id for v in self.by_id.values() if v.link_id == entry.id)
        stats = entry.link.stats
        load = entry.radio_load(self.clock_rate())
        return {
            "id": entry.id,
            "url": entry.url,
            "connected": entry.link.connected,
            "vehicles": vehicles,
            "signing": entry.link.codec.signing,
            "allow_unsigned": entry.link.codec.accept_unsigned,
            "refused_unsigned": stats.refused_unsigned,
            "refused_bad_signature": stats.refused_bad_signature,
            "reconnects": stats.reconnects,
            "bytes_in": stats.bytes_in,
            "bytes_out": stats.bytes_out,
            "radio_load": None
            if load is None
            else {"down": round(load[0], 3), "up": round(load[1], 3)},
        }

    # Vehicles ----------------------------------------------------------------------------
    def relay(self, target_system: int | None, frame: bytes) -> None:
        """A frame from another ground station, unchanged, to the link of the vehicle it
        addresses (the one it is commanded on), or to every link when it addresses none
        of ours."""
        vehicle = None if target_system is None else self.by_id.get(target_system)
        entry = None if vehicle is None else self._links.get(vehicle.link_id)
        for e in [entry] if entry is not None else list(self._links.values()):
            e.link.forward_frame(frame, target_system)

    def _forward(self, link_id: int, sysid: int, msg: Any) -> None:
        """Relay what a link heard to the other ground stations: once per vehicle (from the
        link it is commanded on), never our own frames."""
        if self.forwarding is None or sysid == self.settings.system_id:
            return
        vehicle = self.by_id.get(sysid)
        if vehicle is None or vehicle.link_id == link_id:
            self.forwarding.from_vehicles(bytes(msg.get_msgbuf()))

    def _on_message(self, link_id: int, msg: Any) -> None:
        sysid = int(msg.get_srcSystem())
        if sysid == self.settings.system_id or msg.get_srcComponent() != 1:
            self._forward(link_id, sysid, msg)
            return  # our own echo, or a component that is not the autopilot
        now = time.monotonic()
        kind = msg.get_type()
        vehicle = self.by_id.get(sysid)
        if vehicle is None:
            if kind != "HEARTBEAT" or msg.type == 6:  # MAV_TYPE_GCS
                return  # vehicles are discovered by their heartbeats
            vehicle = Vehicle(sysid, link_id, apply(None, msg, now), now)
            self.by_id[sysid] = vehicle
            log.info("vehicle %d discovered on link %d", sysid, link_id)
            self._spawn(self._fit_streams(link_id))
        else:
            vehicle.telemetry = apply(vehicle.telemetry, msg, now)
        vehicle.heard_on[link_id] = now
        if kind == "GLOBAL_POSITION_INT":
            seen = vehicle.links_seen.setdefault(link_id, LinkSeen())
            seen.fixes.append(Fix(int(msg.time_boot_ms), msg.lat / 1e7, msg.lon / 1e7))
        several = self._check_duplicate(vehicle, now)
        if vehicle.redundant_links:  # one vehicle on several links: the better one
            self._choose_link(vehicle, now)
        elif not several:
            vehicle.link_id = link_id  # a vehicle that moved links is followed...
        # ...but not one id heard from two vehicles (or not known yet to be one): commands
        # stay on the link first heard.
        vehicle.last_heard_s = now
        self._forward(link_id, sysid, msg)
        boot_ms = getattr(msg, "time_boot_ms", None)
        if isinstance(boot_ms, int):
            vehicle.clock.observe(now, boot_ms)
            h = vehicle.boot_history
            if h and boot_ms < h[-1][1]:
                h.clear()  # rebooted
            if not h or now - h[-1][0] >= BOOT_HISTORY_STEP_S:
                h.append((now, boot_ms))
        if vehicle.lost and kind == "HEARTBEAT":
            vehicle.lost = False
            log.info("vehicle %d is back", sysid)
        if kind == "TIMESYNC" and msg.tc1 != 0:  # an answer to ours
            rtt = (time.monotonic_ns() - int(msg.ts1)) / 1e9
            if 0.0 <= rtt <= MAX_ROUND_TRIP_S:
                vehicle.round_trips_s.append(rtt)
        if kind == "GLOBAL_POSITION_INT":
            self.telemetry_received_s = time.perf_counter()
            self.telemetry_event.set()
        inbox = self._inboxes.get(sysid)
        if inbox is not None and kind in MISSION_REPLIES:
            inbox.put_nowait(msg)

    @contextlib.contextmanager
    def mission_inbox(self, system_id: int) -> Iterator[asyncio.Queue[Any]]:
        """The vehicle's mission-protocol messages (``MISSION_REPLIES``) while the block
        runs: one transfer with a vehicle at a time (``service.mission_transfer``)."""
        if system_id in self._inboxes:
            raise Conflict(f"vehicle {system_id}: a mission transfer is in progress")
        inbox: asyncio.Queue[Any] = asyncio.Queue()
        self._inboxes[system_id] = inbox
        try:
            yield inbox
        finally:
            del self._inboxes[system_id]

    def _live_links(self, vehicle: Vehicle, now: float) -> tuple[int, ...]:
        """The links the vehicle was heard on within the lost-vehicle timeout (its seconds)."""
        timeout = self.settings.vehicle_timeout_s
        return tuple(
            sorted(
                lid
                for lid, t in vehicle.heard_on.items()
                if lid in self._links and vehicle.clock.vehicle_seconds(now - t) <= timeout
            )
        )

    def _check_duplicate(self, vehicle: Vehicle, now: float) -> bool:
        """Note (and log, when it starts and ends) a system id heard on more than one link
        within the lost-vehicle timeout (in the vehicle's seconds): two vehicles with one
        id (``duplicate_links``: a run does not start with it, ``duplicates``), or one
        vehicle on two links (``redundant_links``: commanded on the better,
        ``link_choice``), told apart by the positions each link carries at the same
        ``time_boot_ms`` (``link_choice.same_vehicle``); undecided until they have.  True
        while it is heard on several."""
        if len(vehicle.heard_on) < 2 and not (vehicle.duplicate_links or vehicle.redundant_links):
            return False  # heard on one link only (every message comes here)
        live = self._live_links(vehicle, now)
        known = vehicle.duplicate_links or vehicle.redundant_links
        if live == known and now - vehicle.identity_checked_s < IDENTITY_CHECK_S:
            return True  # decided for these links lately (every message comes here)
        duplicate: tuple[int, ...] = ()
        redundant: tuple[int, ...] = ()
        if len(live) > 1:
            vehicle.identity_checked_s = now
            same = link_choice.same_vehicle(
                [vehicle.links_seen.get(lid, LinkSeen()) for lid in live]
            )
            if same is None:
                return True  # not known yet
            if same:
                redundant = live
            else:
                duplicate = live
        if (duplicate, redundant) == (vehicle.duplicate_links, vehicle.redundant_links):
            return len(live) > 1
        if duplicate:
            log.warning(
                "system id %d heard on links %s at once, at different positions: two "
                "vehicles with one id; commands stay on link %d, and no run starts with it",
                vehicle.system_id,
                ", ".join(map(str, duplicate)),
                vehicle.link_id,
            )
        elif redundant:
            log.info(
                "vehicle %d heard on links %s at once: one vehicle, commanded on the better",
                vehicle.system_id,
                ", ".join(map(str, redundant)),
            )
        else:
            log.info("system id %d now heard on one link only", vehicle.system_id)
        vehicle.duplicate_links, vehicle.redundant_links = duplicate, redundant
        return len(live) > 1

    def _choose_link(self, vehicle: Vehicle, now: float) -> None:
        """Command a vehicle heard on several links on the better one (``link_choice``)."""
        chosen, why = link_choice.better_link(
            vehicle.link_id,
            vehicle.links_seen,
            vehicle.redundant_links,
            vehicle.clock.rate,
            now - vehicle.link_switched_s,
        )
        if why is None or chosen == vehicle.link_id:
            return
        log.info(
            "vehicle %d commanded on link %d instead of %d (%s)",
            vehicle.system_id,
            chosen,
            vehicle.link_id,
            why,
        )
        vehicle.link_change = (vehicle.link_id, chosen, why)
        vehicle.link_id = chosen
        vehicle.link_switched_s = now

    def duplicates(self, system_ids: list[int] | None = None) -> dict[int, tuple[int, ...]]:
        """System id → the links it is heard on at once, for those heard on several (of
        ``system_ids``, or all) that are not known to be one vehicle on each
        (``redundant_links``)."""
        now = time.monotonic()
        out = {}
        for v in self.by_id.values():
            if system_ids is None or v.system_id in system_ids:
                several = self._check_duplicate(v, now)
                if v.duplicate_links:
                    out[v.system_id] = v.duplicate_links
                elif several and not v.redundant_links:  # not known yet to be one vehicle
                    out[v.system_id] = self._live_links(v, now)
        return out

    def stream_rate_hz(self, system_id: int) -> float:
        """The position rate a vehicle's streams are asked for: ``settings.stream_rate_hz``,
        or on a radio (a serial link) what fits it with every vehicle it carries
        (``radio_budget.fitted_rate_hz``)."""
        wanted = self.settings.stream_rate_hz
        vehicle = self.by_id.get(system_id)
        entry = None if vehicle is None else self._links.get(vehicle.link_id)
        if entry is None or entry.link.url.kind is not LinkKind.SERIAL:
            return wanted
        carried = sum(1 for v in self.by_id.values() if v.link_id == entry.id and not v.lost)
        return radio_budget.fitted_rate_hz(entry.link.url.port, carried, wanted)

    async def _fit_streams(self, link_id: int) -> None:
        """Every vehicle on the link asked for its streams at ``stream_rate_hz`` where that
        is not what it was asked for (a new one; the others on a radio when one more shares
        it), and a new one for its airframe parameters.  The link's load is measured anew
        from then (``LinkEntry.traffic``): what it carried at the rates before (the vehicles'
        own until the first fit) is not what it carries now."""
        refit = False
        for vehicle in [v for v in self.by_id.values() if v.link_id == link_id]:
            rate = self.stream_rate_hz(vehicle.system_id)
            if vehicle.stream_rate_hz == rate:
                continue
            refit = True
            new = vehicle.stream_rate_hz is None
            vehicle.stream_rate_hz = rate
            await self._request_streams(vehicle, rate)
            if new:
                await self.request_airframe_params(vehicle.system_id)
        entry = self._links.get(link_id)
        if refit and entry is not None:
            entry.traffic.clear()

    async def _request_streams(self, vehicle: Vehicle, rate_hz: float) -> None:
        """Ask a vehicle for the telemetry the planner needs, positions at ``rate_hz``, by
        SET_MESSAGE_INTERVAL only (a REQUEST_DATA_STREAM after it would set the whole
        stream group's rate and override these intervals on ArduPilot)."""
        for msg_id, factor in STREAMED.items():
            interval_us = int(1e6 / (rate_hz * factor))
            await self.send(
                vehicle.system_id,
                commands.set_message_interval(vehicle.system_id, msg_id, interval_us),
            )

    async def request_airframe_params(self, system_id: int, *, missing_only: bool = False) -> None:
        """Ask for the parameters of the airframe's envelope (``gcs_ppf.guidance.airframe``; the
        planner and the separation guard keep within them): every one of ``AIRFRAME_PARAMS``
        or, ``missing_only``, those not answered yet.  ArduPlane answers for the names it
        has (those of 4.5 on or of the versions before) and ignores the others."""
        vehicle = self.by_id.get(system_id)
        for name in AIRFRAME_PARAMS:
            if missing_only and vehicle is not None and vehicle.telemetry.param(name) is not None:
                continue
            await self.send(system_id, commands.param_request_read(system_id, name))

    async def setup_signing(self, system_id: int) -> dict[str, Any]:
        """Install the service's signing key on vehicle ``system_id`` by SETUP_SIGNING, on
        the link it was last heard on: only ever at the operator's explicit request (the
        frame carries the key).  Raises Conflict without a key or a connected link,
        NotFound for a vehicle never heard."""
        key = self.settings.signing_key_bytes
        if key is None:
            raise Conflict(
                "signing: the service has no signing key (set GCS_PPF_SIGNING_KEY or "
                "signing_key_file)"
            )
        vehicle = self.by_id.get(system_id)
        if vehicle is None:
            raise NotFound(f"vehicle {system_id} has not been heard")
        entry = self._links.get(vehicle.link_id)
        msg = commands.setup_signing(system_id, key, signing_timestamp(time.time()))
        if entry is None or not await entry.link.send(msg):
            raise Conflict(f"vehicle {system_id}: its link {vehicle.link_id} is not connected")
        log.warning(
            "vehicle %d: signing key sent by SETUP_SIGNING on link %d",
            system_id,
            vehicle.link_id,
        )
        return {"system_id": system_id, "link_id": vehicle.link_id, "sent": True}

    def telemetry(self, system_id: int) -> VehicleTelemetry | None:
        """What is known of vehicle ``system_id``, if it has been heard."""
        vehicle = self.by_id.get(system_id)
        return None if vehicle is None else vehicle.telemetry

    async def send(self, system_id: int, msg: Any) -> None:
        """Send ``msg`` on the link the vehicle was last heard on (if any)."""
        vehicle = self.by_id.get(system_id)
        if vehicle is None:
            return
        entry = self._links.get(vehicle.link_id)
        if entry is not None:
            await entry.link.send(msg)

    async def heartbeats(self) -> None:
        """Our HEARTBEAT on every link, for ever, at ``heartbeat_hz`` of the vehicles' time
        (CONVENTIONS §5: a SITL at ×10 hears 1 Hz of its seconds, and its GCS failsafe,
        FS_LONG_TIMEOUT of them, does not take our silence for a dead GCS), each with a
        TIMESYNC request that measures the link's round trip; and each vehicle's airframe
        parameters not answered yet asked for again (``PARAM_ASKS``), at ``heartbeat_hz``
        of ours (a round trip over a slow radio is ours, not the vehicle's)."""
        asked = beat = -math.inf
        while True:
            # the period looked at often: a vehicle first heard shortens it at once
            await asyncio.sleep(min(HEARTBEAT_POLL_S, self._heartbeat_period_s()))
            if time.monotonic() - beat < self._heartbeat_period_s():
                continue
            beat = time.monotonic()
            for entry in list(self._links.values()):
                await entry.link.send(commands.gcs_heartbeat())
                await entry.link.send(commands.timesync_request(time.monotonic_ns()))
                self._sample_traffic(entry)
            if time.monotonic() - asked >= 1.0 / self.settings.heartbeat_hz:
                asked = time.monotonic()
                for vehicle in list(self.by_id.values()):
                    if vehicle.param_asks < PARAM_ASKS and not vehicle.lost:
                        vehicle.param_asks += 1
                        await self.request_airframe_params(vehicle.system_id, missing_only=True)

    def _sample_traffic(self, entry: LinkEntry) -> None:
        """The link's byte counts now; a radio over ``RADIO_FULL`` of its rate is logged (once
        until it is under again)."""
        stats = entry.link.stats
        on_it = [v for v in self.by_id.values() if v.link_id == entry.id and not v.lost]
        if not on_it or not all(v.clock.measured for v in on_it):
            entry.traffic.clear()  # per vehicle second: only once their clocks are known
            return
        entry.traffic.append((time.monotonic(), stats.bytes_in, stats.bytes_out))
        load = entry.radio_load(self.clock_rate())
        if load is None:
            return
        full = max(load) > RADIO_FULL
        if full and not entry.warned_full:
            vehicles = len(on_it)
            log.warning(
                "link %d (%s): %.0f %% of its %d baud down, %.0f %% up, %d vehicles: a radio "
                "this full drops what does not fit (fewer vehicles on it, a faster radio, or "
                "GCS_PPF_STREAM_RATE_HZ / GCS_PPF_TICK_HZ lower)",
                entry.id,
                entry.url,
                100 * load[0],
                entry.link.url.port,
                100 * load[1],
                vehicles,
            )
        entry.warned_full = full

    def _heartbeat_period_s(self) -> float:
        """``heartbeat_hz`` of the fastest vehicle clock; while a vehicle heard is not yet
        measured, at least ``UNMEASURED_HEARTBEAT_HZ`` of ours (its first second: at ×10,
        1 Hz of ours left 10 s of its time between our first two heartbeats, and its GCS
        failsafe took the vehicle out of GUIDED)."""
        hz = self.settings.heartbeat_hz * self.clock_rate()
        if any(not v.clock.measured for v in self.by_id.values() if not v.lost):
            hz = max(hz, UNMEASURED_HEARTBEAT_HZ)
        return 1.0 / hz

    async def watchdog(self) -> None:
        """Mark vehicles lost after the timeout of silence, in their own seconds
        (``silent_vehicles``), checked every ``WATCHDOG_PERIOD_S`` of vehicle time.  After a
        stall of the event loop (the watchdog itself woken ``STALL_S`` late) the links'
        readers first get ``STALL_DRAIN_S`` to read what queued meanwhile: otherwise the
        vehicle read last looks silent (measured: four of five vehicles declared lost at
        once after a 2.5 s stall, while the observer heard all of them)."""
        expected = time.monotonic()
        while True:
            late = time.monotonic() - expected
            if late > STALL_S:
                log.warning("event loop stalled %.2f s: reading the links first", late)
                await asyncio.sleep(STALL_DRAIN_S)
            now = time.monotonic()
            for v in silent_vehicles(
                list(self.by_id.values()), now, self.settings.vehicle_timeout_s
            ):
                v.lost = True
                ours = now - v.last_heard_s
                log.warning(
                    "vehicle %d lost (silent %.1f s of its time, %.2f s of ours)",
                    v.system_id,
                    v.clock.vehicle_seconds(ours),
                    ours,
                )
            period = max(0.01, WATCHDOG_PERIOD_S / self.clock_rate())
            expected = time.monotonic() + period
            await asyncio.sleep(period)

    def on_radio(self, vehicle_ids: Iterable[int]) -> bool:
        """Whether any of these vehicles is commanded over a radio (a serial link)."""
        links = {v.link_id for vid in vehicle_ids if (v := self.by_id.get(vid)) is not None}
        return any(
            (entry := self._links.get(lid)) is not None and entry.link.url.kind is LinkKind.SERIAL
            for lid in links
        )

    def clock_rate(self) -> float:
        """The fastest vehicle clock's seconds per ours (a SITL's speed-up; 1 if none)."""
        return max((v.clock.rate for v in self.by_id.values()), default=1.0)

    def vehicles(self) -> list[dict[str, Any]]:
        now = time.monotonic()
        out = []
        for v in sorted(self.by_id.values(), key=lambda v: v.system_id):
            t = v.telemetry
            out.append(
                {
                    "system_id": v.system_id,
                    "link_id": v.link_id,
                    "mode": mode_name(t.custom_mode) if t.custom_mode is not None else None,
                    "armed": t.armed,
                    "lost": v.lost,
                    "duplicate_links": list(v.duplicate_links),
                    "redundant_links": list(v.redundant_links),
                    "seconds_since_heard": round(now - v.last_heard_s, 3),
                    "round_trip_s": None if v.round_trip_s is None else round(v.round_trip_s, 3),
                    "position": {
                        "lat_deg": t.lat_deg,
                        "lon_deg": t.lon_deg,
                        "alt_amsl_m": t.alt_amsl_m,
                    },
                    "attitude": {
                        "roll_rad": t.roll_rad,
                        "pitch_rad": t.pitch_rad,
                        "yaw_rad": t.yaw_rad,
                    },
                    "airspeed_m_s": t.airspeed_m_s,
                    "groundspeed_m_s": t.groundspeed_m_s,
                    "pitch_limits_deg": {"max": t.pitch_max_deg, "min": t.pitch_min_deg},
                    "airframe": Airframe.from_telemetry(t).as_dict(),
                    "prearm": {  # null: not reported (SYS_STATUS, GPS_RAW_INT)
                        "ok": t.prearm_ok,
                        "gps_fix_type": t.gps_fix_type,
                        "reasons": [r.text for r in t.arming_reasons],
                    },
                }
            )
        return out

    @staticmethod
    def vehicle_enu(vehicle: Vehicle, mission: Mission) -> tuple[float, float, float] | None:
        t = vehicle.telemetry
        if t.lat_deg is None or t.lon_deg is None or t.alt_amsl_m is None:
            return None
        return geodetic_to_enu(t.lat_deg, t.lon_deg, t.alt_amsl_m, mission.origin)


def planning_states(
    located: list[tuple[Vehicle, tuple[float, float, float]]], tick_work_s: float = 0.0
) -> tuple[dict[int, VehicleState], set[int], dict[int, lag.Lag]]:
    """Each located vehicle's state carried on to the moment a command sent now acts on
    it (its lag, ``gcs_ppf.guidance.lag``: since its GLOBAL_POSITION_INT arrived, the link's
    round trip, ``tick_work_s`` of ours; at most ``MAX_PREDICTION_S``), and its lag."""
    states: dict[int, VehicleState] = {}
    active: set[int] = set()
    lags: dict[int, lag.Lag] = {}
    now = time.monotonic()
    for vehicle, pos in located:
        t = vehicle.telemetry
        if t.vn_m_s is None or t.ve_m_s is None or t.vd_m_s is None:
            continue
        since = 0.0 if t.position_received_s is None else max(0.0, now - t.position_received_s)
        lags[vehicle.system_id] = lag.vehicle_lag(
            since, vehicle.round_trip_s, tick_work_s, vehicle.clock.rate
        )
        ahead = min(lags[vehicle.system_id].total_s, MAX_PREDICTION_S)
        turn = -t.course_rate_rad_s  # clockwise from north → ICS yaw rate
        states[vehicle.system_id] = state_from_velocity(
            pos, t.vn_m_s, t.ve_m_s, t.vd_m_s, ahead, turn, t.vd_mean_m_s
        )
        if not vehicle.lost:
            active.add(vehicle.system_id)
    return states, active, lags


def silent_vehicles(vehicles: list[Vehicle], now_s: float, timeout_s: float) -> list[Vehicle]:
    """The vehicles not lost yet that have been silent for ``timeout_s`` of vehicle time
    *while another vehicle was heard*, that silence counted on the clock of the vehicle heard
    last (its time_boot_ms since the silent one was last heard: exact for vehicles whose
    clocks run alike — real time, or one SITL's speed-up — whatever our own clock's hiccups
    and however well the rates are estimated).  A ground station starved of CPU reads every
    link late at once (measured: three of five vehicles declared lost together under load,
    while an independent observer heard all five without a gap over 0.12 s), so when every
    vehicle is silent together, each is lost only after ``ALL_SILENT_FACTOR`` timeouts of its
    own rate's seconds (a single vehicle: after the timeout)."""
    alive = [v for v in vehicles if not v.lost]
    out = []
    for v in alive:
        others = [o for o in alive if o is not v and o.last_heard_s > v.last_heard_s]
        own = v.clock.vehicle_seconds(now_s - v.last_heard_s)
        if others:
            ref = max(others, key=lambda o: o.last_heard_s)
            advance = ref.clock_advance_s(v.last_heard_s)
            if advance is not None:
                if advance > timeout_s or own > ALL_SILENT_FACTOR * timeout_s:
                    out.append(v)
                continue
        factor = 1.0 if len(alive) == 1 else ALL_SILENT_FACTOR
        if own > factor * timeout_s:
            out.append(v)
    return out

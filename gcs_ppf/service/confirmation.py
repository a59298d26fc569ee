"""Commands that are confirmed: sent until the vehicle's COMMAND_ACK and then what it reports
(its HEARTBEAT) show them done, sent again when an answer is lost, a refusal never unnoticed.

As the established ground stations do it: MAVSDK and QGroundControl send an unanswered
COMMAND_LONG again a few times before they report failure; ArduPilot answers every command
with a COMMAND_ACK (``GCS_MAVLINK::handle_command_long``/``_int``) and reports modes and the
armed flag in the next HEARTBEAT.  Used by ``gcs_ppf.service.launch`` (arm, modes) and by the
service for the commands that end a run (the holds, ``gcs_ppf.guidance.holding``).
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from gcs_ppf.mavlink.enums import MAV_RESULT_ACCEPTED, MAV_RESULT_IN_PROGRESS
from gcs_ppf.mavlink.telemetry import VehicleTelemetry
from gcs_ppf.service.errors import ServiceError

MAV_RESULT_NAMES = {
    0: "ACCEPTED",
    1: "TEMPORARILY_REJECTED",
    2: "DENIED",
    3: "UNSUPPORTED",
    4: "FAILED",
    5: "IN_PROGRESS",
    6: "CANCELLED",
}


@dataclass(frozen=True)
class Retry:
    """How commands are confirmed (our seconds)."""

    attempts: int = 5
    """Sends of one command before giving up (MAVSDK: 3).  Five: on a radio losing 20 %
    each way, three sends lose a command outright 0.8 % of the time, and a launch confirms
    about four commands per vehicle (measured: a 5-vehicle launch failed on a TAKEOFF mode
    change sent three times and never received)."""
    ack_timeout_s: float = 1.5
    """Wait for the COMMAND_ACK (or PARAM_VALUE) of one send."""
    state_timeout_s: float = 3.0
    """After an ACCEPTED, wait for a HEARTBEAT showing the result (heartbeats come at 1 Hz)."""
    climb_timeout_s: float = 120.0
    """Wait for a vehicle taking off to reach its takeoff altitude."""
    poll_s: float = 0.02
    copies: int = 1
    """Sends of each attempt, ``poll_s`` apart: for an idempotent command that must act
    soon, the loss of one copy on a lossy radio costs nothing (with 20 % loss, three copies
    all lost 0.8 % of the time instead of 20 %)."""


DEFAULT_RETRY = Retry()


class CommandFailed(ServiceError):
    """A vehicle did not do what it was asked; ``detail`` says what and how."""

    def __init__(self, vehicle_id: int, what: str, **detail: Any) -> None:
        reason = ", ".join(f"{k} {v}" for k, v in detail.items())
        super().__init__(f"vehicle {vehicle_id}: {what} failed ({reason})", detail)
        self.vehicle_id = vehicle_id
        self.what = what


class Vehicles(Protocol):
    """What confirming a command needs of the fleet."""

    def telemetry(self, system_id: int) -> VehicleTelemetry | None: ...

    async def send(self, system_id: int, msg: Any) -> None: ...


EventSink = Callable[..., None]
"""``event(kind, vehicle_id, **detail)``: records a run event."""


async def wait_until(condition: Callable[[], bool], timeout_s: float, poll_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while True:
        if condition():
            return True
        if time.monotonic() >= deadline:
            return False
        await asyncio.sleep(poll_s)


def shown_since(
    fleet: Vehicles, vehicle_id: int, since: float, reached: Callable[[VehicleTelemetry], bool]
) -> bool:
    """A HEARTBEAT received after ``since`` shows the command done."""
    t = fleet.telemetry(vehicle_id)
    return (
        t is not None
        and t.last_heartbeat_s is not None
        and t.last_heartbeat_s >= since
        and (reached(t))
    )


async def confirmed_command(
    fleet: Vehicles,
    vehicle_id: int,
    make: Callable[[], Any],
    command: int,
    reached: Callable[[VehicleTelemetry], bool] | None,
    what: str,
    event: EventSink,
    retry: Retry = DEFAULT_RETRY,
) -> int:
    """Send ``make()`` until its COMMAND_ACK (for ``command``) and then a HEARTBEAT show it
    done (``reached``); returns the number of sends.  A lost ACK, or an ACCEPTED the
    heartbeat does not show, is sent again, up to ``retry.attempts`` sends; a refusal is
    final.  An ACK lost while a later HEARTBEAT shows the command done confirms it (flown
    with 20 % loss each way, a mode change that got no ACK in three sends failed the run;
    a lost ACK is as likely as a lost command).  Raises ``CommandFailed`` (after a
    ``command_failed`` event).  With ``reached`` None (a command no HEARTBEAT shows, such
    as a guided point) the ACCEPTED alone confirms it."""
    first_sent: float | None = None
    last_result: str = "no COMMAND_ACK"
    for attempt in range(1, retry.attempts + 1):
        sent = time.monotonic()
        first_sent = sent if first_sent is None else first_sent
        if attempt > 1:
            event("command_resent", vehicle_id, command=what, attempt=attempt, after=last_result)
        for copy in range(retry.copies):
            if copy:
                await asyncio.sleep(retry.poll_s)
            await fleet.send(vehicle_id, make())
        since = first_sent

        def acked(since: float = since) -> bool:
            t = fleet.telemetry(vehicle_id)
            a = None if t is None else t.ack(command)
            return a is not None and a.received_s >= since and a.result != MAV_RESULT_IN_PROGRESS

        if not await wait_until(acked, retry.ack_timeout_s, retry.poll_s):
            if reached is not None and shown_since(
                fleet, vehicle_id, first_sent, reached
            ):  # the ACK alone was lost
                event("command_ack_lost", vehicle_id, command=what, confirmed_by="HEARTBEAT")
                return attempt
            last_result = "no COMMAND_ACK"
            continue
        t = fleet.telemetry(vehicle_id)
        ack = None if t is None else t.ack(command)
        assert ack is not None
        if ack.result != MAV_RESULT_ACCEPTED:
            name = MAV_RESULT_NAMES.get(ack.result, str(ack.result))
            event("command_failed", vehicle_id, command=what, result=name, attempts=attempt)
            raise CommandFailed(vehicle_id, what, result=name, attempts=attempt)
        if reached is None:
            return attempt
        acked_at = ack.received_s

        def shown(
            acked_at: float = acked_at, reached: Callable[[VehicleTelemetry], bool] = reached
        ) -> bool:
            return shown_since(fleet, vehicle_id, acked_at, reached)

        if await wait_until(shown, retry.state_timeout_s, retry.poll_s):
            return attempt
        last_result = "ACCEPTED but not shown by the HEARTBEAT"
    event("command_failed", vehicle_id, command=what, result=last_result, attempts=retry.attempts)
    raise CommandFailed(vehicle_id, what, result=last_result, attempts=retry.attempts)


@dataclass(frozen=True, slots=True)
class Order:
    """One command for one vehicle, to be confirmed (``confirmed_command``'s arguments)."""

    vehicle_id: int
    make: Callable[[], Any]
    command: int
    what: str
    reached: Callable[[VehicleTelemetry], bool] | None = None


async def confirm_all(
    fleet: Vehicles, orders: list[Order], event: EventSink, retry: Retry = DEFAULT_RETRY
) -> set[int]:
    """Every order confirmed, all vehicles at once, each vehicle's orders in turn; returns
    the ids of the vehicles whose order failed (each after its ``command_failed`` event):
    a failure here is reported, not raised, so one vehicle never keeps the others waiting."""
    failed: set[int] = set()
    by_vehicle: dict[int, list[Order]] = {}
    for order in orders:
        by_vehicle.setdefault(order.vehicle_id, []).append(order)

    async def one_vehicle(vid: int, mine: list[Order]) -> None:
        for o in mine:
            try:
                await confirmed_command(
                    fleet, vid, o.make, o.command, o.reached, o.what, event, retry
                )
            except CommandFailed:
                failed.add(vid)
                return

    await asyncio.gather(*(one_vehicle(vid, mine) for vid, mine in by_vehicle.items()))
    return failed

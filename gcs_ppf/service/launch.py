"""Launching a formation on ArduPlane: take off the vehicles on the ground, arm, switch every
vehicle to GUIDED, each command confirmed by its COMMAND_ACK and then by the HEARTBEAT.

What it relies on (ArduPlane 4.7; measured on its SITL, ``../shared/arduplane-traces``):

- A fixed-wing ArduPlane does not take off in GUIDED: TAKEOFF mode (13) does, once armed,
  climbing to ``TKOFF_ALT`` above home and loitering there.  Real ArduPlane lifts off 3.8 s
  after arming and is at 95 m 20.4 s after (TKOFF_ALT 100); the takeoff roll passes 5 m/s
  1.3 s after arming, so a vehicle is "on the ground" by its height alone, and it is
  switched to GUIDED only once at ``TAKEOFF_DONE_FRACTION`` of its TKOFF_ALT (the value
  read back from the vehicle).
- ArduPilot answers every COMMAND_LONG with a COMMAND_ACK (``GCS_MAVLINK::handle_command_long``)
  and reports the result in the next HEARTBEAT (``base_mode`` armed flag, ``custom_mode``).
  A command whose ACK is lost is sent again a few times, as MAVSDK and QGroundControl do;
  a refusal (DENIED, FAILED, UNSUPPORTED, TEMPORARILY_REJECTED) is final.
- PARAM_SET is answered with the PARAM_VALUE of the parameter (``GCS_MAVLINK::handle_param_set``).
- Real ArduPlane refuses to arm (COMMAND_ACK FAILED) until its pre-arm checks pass: some
  seconds after boot while the EKF settles and the GPS gets its fix.  It reports them in
  SYS_STATUS (``MAV_SYS_STATUS_PREARM_CHECK`` healthy), says why not in ``PreArm:``
  STATUSTEXTs (every 30 s, and at each refused arm), and GPS_RAW_INT gives the fix.  So a
  vehicle is armed only once ready (``wait_ready``, within the start's bound), and an arm
  refused FAILED or TEMPORARILY_REJECTED is tried again every ``ARM_RETRY_S`` within it
  (``arm_when_ready``); the failure names the vehicle's own reasons.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from collections.abc import Awaitable, Callable
from dataclasses import replace

from gcs_ppf.geodesy import enu_to_geodetic
from gcs_ppf.mavlink import commands
from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.mavlink.telemetry import VehicleTelemetry, recent_reasons
from gcs_ppf.mission import Origin
from gcs_ppf.service.confirmation import (
    DEFAULT_RETRY,
    CommandFailed,
    EventSink,
    Retry,
    Vehicles,
    confirmed_command,
    wait_until,
)

__all__ = ["CommandFailed", "EventSink", "Retry", "arm_when_ready", "launch", "take_off"]

log = logging.getLogger("gcs_ppf.service.launch")

ON_GROUND_ALT_M = 5.0
"""Below this height above home a vehicle is on the ground (whatever its speed)."""
HEIGHT_WAIT_S = 10.0
"""How long (our seconds) the launch waits for a vehicle's first height above home before
it decides whether the vehicle is on the ground (``launch``)."""
TAKEOFF_DONE_FRACTION = 0.9
"""A vehicle taking off is switched to GUIDED once at this fraction of its TKOFF_ALT."""
LOST_POLL_S = 0.1
"""How often (our seconds) a vehicle being launched is looked at for the watchdog's verdict."""
ARM_RETRY_S = 2.0
"""Our seconds between arms refused for a reason that may clear."""
RETRYABLE_ARM = frozenset({"FAILED", "TEMPORARILY_REJECTED"})
"""Refusals of an arm that pre-arm checks still settling give (ArduPilot: FAILED)."""
STRAIGHT_ON_COPIES = 3
"""Copies of each send that switches a vehicle up from its takeoff to GUIDED
(``straight_on``): the same point again is harmless, and one lost leaves the vehicle in
TAKEOFF, which at its altitude turns back to loiter over where it started, across the
climb-out of any vehicle beside it (14.8 m from a wingman once, its switch lost twice at
300 ms latency and 20 % loss)."""
STRAIGHT_ON_M = 5000.0
"""How far ahead on its course the point lies that switches a vehicle that took off to
GUIDED (``straight_on``)."""
REASONS_RECENT_S = 35.0
"""ArduPilot repeats its PreArm reasons every 30 s: the ones this recent still hold."""
GPS_3D_FIX = 3


ClearAhead = Callable[[int, VehicleTelemetry], tuple[float, float] | None]
"""Where a vehicle that climbed out (its id, its telemetry) is sent instead of
``STRAIGHT_ON_M`` on along its course: (east, north) metres from it; None: straight on."""


def straight_ahead(vehicle_id: int, t: VehicleTelemetry) -> tuple[float, float] | None:
    return None


def never_lost(vehicle_id: int) -> bool:
    return False


def ignore_lost(vehicle_id: int) -> None:
    return None


def on_ground(t: VehicleTelemetry) -> bool:
    """Lower than ``ON_GROUND_ALT_M`` above home (not also slow: ArduPlane's takeoff roll
    passes 5 m/s 1.3 s after arming)."""
    return t.relative_alt_m is not None and t.relative_alt_m < ON_GROUND_ALT_M


def ready(t: VehicleTelemetry) -> bool:
    """Pre-arm checks passing (or not reported) and a 3D GPS fix (or no GPS_RAW_INT)."""
    return t.prearm_ok is not False and (t.gps_fix_type is None or t.gps_fix_type >= GPS_3D_FIX)


def not_ready_reasons(t: VehicleTelemetry | None, now_s: float) -> list[str]:
    """Why the vehicle is not ready: its own recent reasons, else what its status says."""
    if t is None:
        return ["no telemetry"]
    reasons = recent_reasons(t, now_s - REASONS_RECENT_S)
    if reasons:
        return reasons
    out = []
    if t.prearm_ok is False:
        out.append("pre-arm checks failing (SYS_STATUS), no reason given")
    if t.gps_fix_type is not None and t.gps_fix_type < GPS_3D_FIX:
        out.append(f"no 3D GPS fix (GPS_RAW_INT fix_type {t.gps_fix_type})")
    return out


async def wait_ready(
    fleet: Vehicles, vehicle_id: int, event: EventSink, timeout_s: float, poll_s: float
) -> None:
    """Until the vehicle is ``ready``, at most ``timeout_s``: ``prearm_waiting`` with its
    reasons, then ``prearm_passed``; or ``prearm_failed`` and ``CommandFailed`` naming
    them."""

    def is_ready() -> bool:
        t = fleet.telemetry(vehicle_id)
        return t is not None and ready(t)

    if is_ready():
        return
    started = time.monotonic()
    event(
        "prearm_waiting",
        vehicle_id,
        reasons=not_ready_reasons(fleet.telemetry(vehicle_id), started),
    )
    if timeout_s > 0 and await wait_until(is_ready, timeout_s, poll_s):
        event("prearm_passed", vehicle_id, waited_s=round(time.monotonic() - started, 1))
        return
    reasons = not_ready_reasons(fleet.telemetry(vehicle_id), time.monotonic())
    event("prearm_failed", vehicle_id, waited_s=round(timeout_s, 1), reasons=reasons)
    raise CommandFailed(vehicle_id, "pre-arm checks", reasons="; ".join(reasons) or "none given")


async def arm_when_ready(
    fleet: Vehicles,
    vehicle_id: int,
    event: EventSink,
    retry: Retry = DEFAULT_RETRY,
    ready_timeout_s: float = 0.0,
) -> None:
    """Armed (``arm``) once ``ready`` (``wait_ready``), within ``ready_timeout_s`` in all;
    an arm refused FAILED or TEMPORARILY_REJECTED (``arm_refused``, with the vehicle's
    reasons) is tried again every ``ARM_RETRY_S`` within it.  ``CommandFailed`` names the
    last refusal and the vehicle's reasons."""
    deadline = time.monotonic() + ready_timeout_s
    while True:
        await wait_ready(
            fleet, vehicle_id, event, max(0.0, deadline - time.monotonic()), retry.poll_s
        )
        asked = time.monotonic()
        try:
            await arm(fleet, vehicle_id, event, retry)
            return
        except CommandFailed as exc:
            result = exc.detail.get("result")
            # the reasons come as STATUSTEXT just before the ACK; wait a moment for them
            await asyncio.sleep(min(0.2, 4 * retry.poll_s))
            t = fleet.telemetry(vehicle_id)
            reasons = [] if t is None else recent_reasons(t, asked - 1.0)
            if result not in RETRYABLE_ARM or time.monotonic() + ARM_RETRY_S > deadline:
                raise CommandFailed(
                    vehicle_id, "arm", result=result, reasons="; ".join(reasons) or "none given"
                ) from None
            event("arm_refused", vehicle_id, result=result, reasons=reasons, retry_in_s=ARM_RETRY_S)
            await asyncio.sleep(ARM_RETRY_S)


async def set_mode(
    fleet: Vehicles,
    vehicle_id: int,
    mode: PlaneMode,
    event: EventSink,
    retry: Retry = DEFAULT_RETRY,
) -> int:
    """``mode``, confirmed (ACK, then HEARTBEAT.custom_mode)."""
    return await confirmed_command(
        fleet,
        vehicle_id,
        lambda: commands.set_mode(vehicle_id, mode),
        commands.MAV_CMD_DO_SET_MODE,
        lambda t: t.custom_mode == int(mode),
        f"mode {mode.name}",
        event,
        retry,
    )


async def straight_on(
    fleet: Vehicles,
    vehicle_id: int,
    event: EventSink,
    retry: Retry = DEFAULT_RETRY,
    clear_ahead: ClearAhead = straight_ahead,
) -> None:
    """A vehicle switched to GUIDED by the point ``STRAIGHT_ON_M`` ahead on its course at
    its altitude (DO_REPOSITION with its change-mode flag, ``STRAIGHT_ON_COPIES`` copies of
    each send; confirmed by the HEARTBEAT's mode), so that it flies on as it climbed out
    until the run commands it; ``clear_ahead`` may give another point (east, north metres
    from it) where that way is not clear, which ArduPlane circles once there.
    Switched by DO_SET_MODE, ArduPlane circles the point where it entered GUIDED
    (WP_LOITER_RAD) until a target comes, and at 300 ms latency and 20 % loss that target
    came seconds late; sent 5 km on regardless, at ×10 on that link a wingman of the
    three-vehicle line abreast flew 1.5 km straight on while the last took off and the run
    began with it 9.6 m from the sphere on its way.  Without a position and a course,
    DO_SET_MODE."""
    retry = replace(retry, copies=STRAIGHT_ON_COPIES)
    t = fleet.telemetry(vehicle_id)
    if (
        t is None
        or t.lat_deg is None
        or t.lon_deg is None
        or t.alt_amsl_m is None
        or t.vn_m_s is None
        or t.ve_m_s is None
    ):
        await set_mode(fleet, vehicle_id, PlaneMode.GUIDED, event, retry)
        return
    course = math.atan2(t.ve_m_s, t.vn_m_s)  # from north, clockwise
    here = Origin(lat=t.lat_deg, lon=t.lon_deg, alt=t.alt_amsl_m)
    point = clear_ahead(vehicle_id, t)
    east, north = STRAIGHT_ON_M * math.sin(course), STRAIGHT_ON_M * math.cos(course)
    if point is not None:
        east, north = point
    lat, lon, alt = enu_to_geodetic(east, north, 0.0, here)
    await confirmed_command(
        fleet,
        vehicle_id,
        lambda: commands.reposition(vehicle_id, lat, lon, alt, change_mode=True),
        commands.MAV_CMD_DO_REPOSITION,
        lambda t: t.custom_mode == int(PlaneMode.GUIDED),
        "straight on in GUIDED",
        event,
        retry,
    )


async def arm(
    fleet: Vehicles, vehicle_id: int, event: EventSink, retry: Retry = DEFAULT_RETRY
) -> int:
    """Armed, confirmed (ACK, then the HEARTBEAT's armed flag)."""
    return await confirmed_command(
        fleet,
        vehicle_id,
        lambda: commands.arm(vehicle_id, True),
        commands.MAV_CMD_COMPONENT_ARM_DISARM,
        lambda t: t.armed,
        "arm",
        event,
        retry,
    )


async def set_param(
    fleet: Vehicles,
    vehicle_id: int,
    name: str,
    value: float,
    event: EventSink,
    retry: Retry = DEFAULT_RETRY,
) -> float | None:
    """PARAM_SET ``name``, read back from the PARAM_VALUE it answers (asked for again by
    PARAM_REQUEST_READ when it does not come); the value the vehicle reports, or None if it
    never answered (then the vehicle may not have the parameter).  A read-back of another
    value is sent again, up to ``retry.attempts`` sends: it may answer a read of the value
    before, the PARAM_SET lost (at 20 % loss TKOFF_DIST stayed 200 m on every vehicle of a
    run, and each circled 200 m ahead while the others took off)."""
    read: float | None = None
    for attempt in range(1, retry.attempts + 1):
        sent = time.monotonic()
        await fleet.send(vehicle_id, commands.set_param(vehicle_id, name, value))
        if attempt > 1:
            await fleet.send(vehicle_id, commands.param_request_read(vehicle_id, name))

        def answered(since: float = sent) -> bool:
            t = fleet.telemetry(vehicle_id)
            p = None if t is None else t.param(name)
            return p is not None and p.received_s >= since

        if await wait_until(answered, retry.ack_timeout_s, retry.poll_s):
            t = fleet.telemetry(vehicle_id)
            p = None if t is None else t.param(name)
            assert p is not None
            read = p.value
            if abs(read - value) <= 1e-3 * max(1.0, abs(value)):
                return read
    if read is None:
        event("parameter_unanswered", vehicle_id, name=name, sent=value)
        return None
    event("parameter_not_set", vehicle_id, name=name, sent=value, read=read)
    return read


async def take_off(
    fleet: Vehicles,
    vehicle_id: int,
    takeoff_alt_m: float,
    event: EventSink,
    retry: Retry = DEFAULT_RETRY,
    takeoff_dist_m: float | None = None,
    ready_timeout_s: float = 0.0,
) -> float:
    """A vehicle on the ground up to its takeoff altitude: TKOFF_ALT set and read back,
    TAKEOFF mode, armed once ready (``arm_when_ready``, within ``ready_timeout_s``; each
    confirmed), then until it is at ``TAKEOFF_DONE_FRACTION`` of the TKOFF_ALT it reported
    (of ``takeoff_alt_m`` if it did not answer).  Returns that TKOFF_ALT."""
    read = await set_param(fleet, vehicle_id, "TKOFF_ALT", takeoff_alt_m, event, retry)
    alt = takeoff_alt_m if read is None or read <= 0.0 else read
    if takeoff_dist_m is not None:  # ArduPlane ≥ 4.5: climb out straight, not in circles
        await set_param(fleet, vehicle_id, "TKOFF_DIST", takeoff_dist_m, event, retry)
    await set_mode(fleet, vehicle_id, PlaneMode.TAKEOFF, event, retry)
    await arm_when_ready(fleet, vehicle_id, event, retry, ready_timeout_s)
    event("takeoff", vehicle_id, takeoff_alt_m=alt)

    def high_enough() -> bool:
        t = fleet.telemetry(vehicle_id)
        h = None if t is None else t.relative_alt_m
        return h is not None and h >= TAKEOFF_DONE_FRACTION * alt

    if not await wait_until(high_enough, retry.climb_timeout_s, 0.1):
        t = fleet.telemetry(vehicle_id)
        h = None if t is None else t.relative_alt_m
        event("takeoff_failed", vehicle_id, takeoff_alt_m=alt, height_m=h)
        raise CommandFailed(vehicle_id, "takeoff", takeoff_alt_m=alt, height_m=h)
    return alt


async def launch(
    fleet: Vehicles,
    vehicle_ids: list[int],
    takeoff_alt_m: float,
    event: EventSink,
    retry: Retry = DEFAULT_RETRY,
    takeoff_dist_m: float | None = None,
    is_lost: Callable[[int], bool] = never_lost,
    on_lost: Callable[[int], None] = ignore_lost,
    ready_timeout_s: float = 0.0,
    clear_ahead: ClearAhead = straight_ahead,
) -> None:
    """Every vehicle flying in GUIDED: those on the ground taken off (``take_off``), each
    switched to GUIDED as soon as it is up and sent straight on (``straight_on``, as far as
    ``clear_ahead`` allows); the others
    armed if they are not, and switched once every vehicle is up.  Up at its TKOFF_ALT,
    ArduPlane in TAKEOFF turns back to loiter TKOFF_DIST from where it started: waiting
    there for the last to take off, the first up flew back into the climb-out of the one
    beside it (3.0 and 36.8 m apart at 300 ms latency and 20 % loss, 2 runs of 10).
    The first failure cancels the rest and is raised (``CommandFailed``).  A vehicle the
    watchdog finds lost meanwhile (``is_lost``) is left out at once, its commands stopped,
    and ``on_lost`` told: whether the run goes on without it is the run's to decide (a
    wingman dying during a launch slowed by a busy machine failed the whole run after five
    sends of GUIDED to it, 15 s, under two CPU burners)."""
    left_out: set[int] = set()

    async def unless_lost(step: Callable[[int], Awaitable[None]], vid: int) -> None:
        if vid in left_out:
            return
        task = asyncio.ensure_future(step(vid))
        try:
            while not task.done() and not is_lost(vid):
                await asyncio.wait({task}, timeout=LOST_POLL_S)
            if task.done():
                try:
                    task.result()  # done: its failure, if it failed
                    return
                except CommandFailed:
                    if not is_lost(vid):
                        raise
        finally:
            if not task.done():
                task.cancel()
                with contextlib.suppress(asyncio.CancelledError, CommandFailed):
                    await task
        left_out.add(vid)
        on_lost(vid)

    took_off: set[int] = set()

    def height_known(vid: int) -> bool:
        t = fleet.telemetry(vid)
        return t is not None and t.relative_alt_m is not None

    async def airborne(vid: int) -> None:
        # Where a vehicle is must be known before it is judged on the ground or flying: on a
        # link losing 20 % of its messages a wingman had reported no position yet, was taken
        # for one flying, armed in GUIDED on the runway and left there (2 runs of 20).
        if not await wait_until(lambda: height_known(vid), HEIGHT_WAIT_S, LOST_POLL_S):
            raise CommandFailed(vid, "launch", reason="no height above home reported")
        t = fleet.telemetry(vid)
        if t is None:
            raise CommandFailed(vid, "launch", reason="no telemetry")
        if on_ground(t):
            await take_off(fleet, vid, takeoff_alt_m, event, retry, takeoff_dist_m, ready_timeout_s)
            took_off.add(vid)
        elif not t.armed:
            await arm_when_ready(fleet, vid, event, retry, ready_timeout_s)

    async def climbed_out(vid: int) -> None:
        await airborne(vid)
        if vid in took_off:  # GUIDED at once, flying straight on (``straight_on``)
            await straight_on(fleet, vid, event, retry, clear_ahead)

    async def guided(vid: int) -> None:
        if vid not in took_off:  # those flying hold meanwhile (``hold_during_launch``)
            await set_mode(fleet, vid, PlaneMode.GUIDED, event, retry)

    for step in (climbed_out, guided):
        try:
            async with asyncio.TaskGroup() as tg:
                for vid in vehicle_ids:
                    tg.create_task(unless_lost(step, vid))
        except* CommandFailed as group:
            raise group.exceptions[0] from None

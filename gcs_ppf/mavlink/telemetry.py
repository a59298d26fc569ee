"""Pure decoding of an ArduPlane's telemetry into one immutable sample per vehicle.

``apply(tel, msg, now_s)`` folds one received message into a new ``VehicleTelemetry``.  Units
are in the field names; angles and velocities are in MAVLink's NED convention (yaw and heading
from north, clockwise; velocities north/east/down) — conversion to the paper's ENU frame is the
job of ``gcs_ppf.frames``.  ``now_s`` is whatever clock the caller keeps (monotonic seconds in
the service); nothing here reads a clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

from gcs_ppf.mavlink.ardupilot import PlaneMode, is_armed, mode_name, plane_mode
from gcs_ppf.mavlink.codec import MAVLinkMessage

UINT16_UNKNOWN = 0xFFFF
"""GLOBAL_POSITION_INT.hdg when the heading is unknown."""
COURSE_RATE_SMOOTHING = 0.5
"""Weight of the newest measurement in the course rate (an exponential average)."""
SPEED_RATIO_SMOOTHING_S = 10.0
"""Time constant (vehicle seconds) of the averaged airspeed / ground speed ratio that
turns a planned ground speed into the airspeed to command (``gcs_ppf.guidance.slew``).  The
ratio is the air's density at the vehicle's height, which changes slowly; VFR_HUD's
instantaneous one swung 0.915–0.98 with TECS's ±3 m/s vertical oscillation on real
ArduPlane, ±0.9 m/s of commanded airspeed at 27 m/s, each swing a throttle step (22 ↔ 97 %)
that fed the oscillation."""
SPEED_RATIO_MIN_GROUNDSPEED_M_S = 5.0
"""Below this ground speed a VFR_HUD is left out of the ratio (on the runway)."""
FLIGHT_PATH_SMOOTHING_S = 2.0
"""Time constant (vehicle seconds) of the averaged vertical speed the flight path is planned
from.  ArduPlane's TECS holds a height with a ±2–4 m/s oscillation of the vertical speed
(a 6–8 s period, measured on real ArduPlane SITL in formation): planned from the
instantaneous flight path, each tick's altitude demand a few seconds ahead swung with it
(±3 m) and fed the oscillation, and the slots 200 m behind the leader (Eq. 6 turns them
with its pitch) swung ±15 m.  At the paper's scale it steadies the flown loop too: Table 2
at ×5 with a CPU burner per core (5 runs each) was in formation for a median 66 % of the
flight after forming with 2 s, 19 % with 0.4 s (the leader's flight path swinging ±8°)."""


NULL_ISLAND_DEG = 0.01
"""A position within this of 0°, 0° (1.1 km) is none: what an autopilot reports before it
has one.  No mission flies in the Gulf of Guinea's null island square."""
NULL_ISLAND_E7 = round(NULL_ISLAND_DEG * 1e7)

FIXES_KEPT = 32
"""How many positions ``recent_fixes`` keeps: 3.2 s at the 10 Hz stream the service asks for,
more than a tick late under load."""


@dataclass(frozen=True, slots=True)
class Fix:
    """One GLOBAL_POSITION_INT's position, on the vehicle's clock."""

    boot_ms: int
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float


@dataclass(frozen=True, slots=True)
class CommandAck:
    """The last COMMAND_ACK received for one command."""

    command: int
    """``MAV_CMD`` number acknowledged."""
    result: int
    """``MAV_RESULT`` (0 ACCEPTED, 1 TEMPORARILY_REJECTED, 2 DENIED, 3 UNSUPPORTED, 4 FAILED,
    5 IN_PROGRESS, ...)."""
    received_s: float
    """Caller's clock when it arrived."""


@dataclass(frozen=True, slots=True)
class ParamValue:
    """The last PARAM_VALUE received for one of ``AIRFRAME_PARAMS``."""

    name: str
    """The parameter's name as the vehicle spells it (``"TECS_CLMB_MAX"``)."""
    value: float
    """``param_value`` as sent (ArduPilot sends every type as a float)."""
    received_s: float
    """Caller's clock when it arrived."""


@dataclass(frozen=True)
class VehicleTelemetry:
    """What is known of one vehicle (system id, component id); None: not received yet.

    Not slotted: every message of every vehicle makes a new one (``apply``), and a
    ``__dict__`` copies in one C call where 43 slots took 43 Python ones."""

    system_id: int
    component_id: int
    mav_type: int | None = None
    """HEARTBEAT.type (``MAV_TYPE``; 1 = fixed wing)."""
    autopilot: int | None = None
    """HEARTBEAT.autopilot (``MAV_AUTOPILOT``; 3 = ArduPilot)."""
    custom_mode: int | None = None
    """HEARTBEAT.custom_mode as received."""
    mode: PlaneMode | None = None
    """``custom_mode`` as an ArduPlane mode; None if not one (or no heartbeat yet)."""
    armed: bool = False
    system_status: int | None = None
    """HEARTBEAT.system_status (``MAV_STATE``)."""
    last_heartbeat_s: float | None = None
    """Caller's clock at the last HEARTBEAT."""
    last_update_s: float | None = None
    """Caller's clock at the last message that changed this record."""
    lat_deg: float | None = None
    lon_deg: float | None = None
    alt_amsl_m: float | None = None
    relative_alt_m: float | None = None
    """Altitude above home (GLOBAL_POSITION_INT.relative_alt)."""
    vn_m_s: float | None = None
    ve_m_s: float | None = None
    vd_m_s: float | None = None
    heading_deg: float | None = None
    """GLOBAL_POSITION_INT.hdg: [0, 360) from north, clockwise; None if unknown."""
    position_received_s: float | None = None
    """Caller's clock when the last GLOBAL_POSITION_INT arrived."""
    position_boot_ms: int | None = None
    """GLOBAL_POSITION_INT.time_boot_ms of the last one."""
    recent_fixes: tuple[Fix, ...] = ()
    """The last ``FIXES_KEPT`` GLOBAL_POSITION_INTs, oldest first: the path flown between
    two of the caller's looks, which a look at the latest alone would cut short."""
    course_rate_rad_s: float = 0.0
    """How fast the course over the ground turns (rad/s, from north, +: clockwise, as the
    heading), from successive
    GLOBAL_POSITION_INT velocities in vehicle time, smoothed (``COURSE_RATE_SMOOTHING``)."""
    vd_mean_m_s: float | None = None
    """GLOBAL_POSITION_INT.vz averaged over ``FLIGHT_PATH_SMOOTHING_S`` of vehicle time."""
    roll_rad: float | None = None
    pitch_rad: float | None = None
    yaw_rad: float | None = None
    """ATTITUDE.yaw: from north, clockwise, (−π, π]."""
    airspeed_m_s: float | None = None
    groundspeed_m_s: float | None = None
    climb_m_s: float | None = None
    """VFR_HUD.climb (positive up)."""
    speed_ratio_mean: float | None = None
    """VFR_HUD.airspeed / .groundspeed averaged over ``SPEED_RATIO_SMOOTHING_S`` (samples
    flying faster than ``SPEED_RATIO_MIN_GROUNDSPEED_M_S`` over the ground, ratio 0.5–2)."""
    hud_boot_ms: int | None = None
    """Vehicle time of the latest VFR_HUD (the latest ``time_boot_ms`` when it came)."""
    time_boot_ms: int | None = None
    """Vehicle time: ``time_boot_ms`` of the most recent message carrying one."""
    system_time_boot_ms: int | None = None
    """SYSTEM_TIME.time_boot_ms."""
    unix_time_us: int | None = None
    """SYSTEM_TIME.time_unix_usec; None while the vehicle has no GPS time (it sends 0)."""
    command_acks: tuple[CommandAck, ...] = ()
    """The last COMMAND_ACK per command, ordered by command number."""
    pitch_max_deg: float | None = None
    """The airframe's pitch limits (PARAM_VALUE of ``PITCH_LIMIT_PARAMS``), degrees."""
    pitch_min_deg: float | None = None
    params: tuple[ParamValue, ...] = ()
    """The last PARAM_VALUE of each of ``KEPT_PARAMS`` received, ordered by name."""
    prearm_ok: bool | None = None
    """SYS_STATUS: ArduPilot's pre-arm checks pass (``MAV_SYS_STATUS_PREARM_CHECK`` healthy);
    None when the vehicle does not report the bit (or no SYS_STATUS yet)."""
    gps_fix_type: int | None = None
    """GPS_RAW_INT.fix_type (``GPS_FIX_TYPE``: 3 = 3D fix)."""
    arming_reasons: tuple[ArmingReason, ...] = ()
    """The vehicle's own reasons not to arm: its latest ``PreArm:`` / ``Arm:`` STATUSTEXTs,
    one per text (the newest of each), newest last, at most ``ARMING_REASONS_KEPT``."""
    home_lat_deg: float | None = None
    """HOME_POSITION: where RTL flies to (where the vehicle armed), when it has said."""
    home_lon_deg: float | None = None
    home_alt_amsl_m: float | None = None

    @property
    def mode_name(self) -> str | None:
        """ArduPlane's name of the current mode (``"GUIDED"``), None before the first heartbeat."""
        return None if self.custom_mode is None else mode_name(self.custom_mode)

    def ack(self, command: int) -> CommandAck | None:
        """The last COMMAND_ACK received for ``command``, if any."""
        for a in self.command_acks:
            if a.command == command:
                return a
        return None

    def param(self, name: str) -> ParamValue | None:
        """The last PARAM_VALUE received for ``name`` (of ``KEPT_PARAMS``), if any."""
        for p in self.params:
            if p.name == name:
                return p
        return None


@dataclass(frozen=True, slots=True)
class ArmingReason:
    """One STATUSTEXT saying why the vehicle will not arm, as received."""

    text: str
    received_s: float
    """Caller's clock when it came."""


MAV_SYS_STATUS_PREARM_CHECK = 1 << 28
ARMING_PREFIXES = ("PreArm:", "Arm:")
ARMING_REASONS_KEPT = 8


def recent_reasons(t: VehicleTelemetry, since_s: float) -> list[str]:
    """The texts of ``t``'s arming reasons received at or after ``since_s`` (caller's clock)."""
    return [r.text for r in t.arming_reasons if r.received_s >= since_s]


_FIELD_NAMES = frozenset(f.name for f in fields(VehicleTelemetry))


def apply(tel: VehicleTelemetry | None, msg: MAVLinkMessage, now_s: float) -> VehicleTelemetry:
    """``tel`` updated with ``msg`` (received at caller time ``now_s``), as a new object.

    ``tel`` None starts a record for the message's sender.  Messages from another system or
    component than ``tel``'s, and message types not decoded here, return ``tel`` unchanged.
    Decoded: HEARTBEAT, GLOBAL_POSITION_INT, ATTITUDE, VFR_HUD, SYSTEM_TIME, COMMAND_ACK,
    PARAM_VALUE of ``AIRFRAME_PARAMS`` (and the pitch limits among them as their own fields),
    SYS_STATUS's pre-arm bit, GPS_RAW_INT's fix, the arming reasons of STATUSTEXT,
    HOME_POSITION;
    the ``time_boot_ms`` of any message carrying one.
    """
    src = (int(msg.get_srcSystem()), int(msg.get_srcComponent()))
    if tel is None:
        tel = VehicleTelemetry(system_id=src[0], component_id=src[1])
    elif src != (tel.system_id, tel.component_id):
        return tel
    decode = _DECODERS.get(msg.get_type())
    changes: dict[str, Any] = decode(tel, msg, now_s) if decode is not None else {}
    boot_ms = getattr(msg, "time_boot_ms", None)
    if isinstance(boot_ms, int):
        changes["time_boot_ms"] = boot_ms
    if not changes:
        return tel
    changes["last_update_s"] = now_s
    return _replaced(tel, changes)


def _replaced(tel: VehicleTelemetry, changes: dict[str, Any]) -> VehicleTelemetry:
    """``dataclasses.replace(tel, **changes)`` at a fraction of its cost: every message of
    every vehicle comes through here (at 100 vehicles, 4,500 messages a second).  The
    instance's ``__dict__`` is filled directly, which the frozen class allows (it forbids
    only ``setattr``)."""
    assert changes.keys() <= _FIELD_NAMES, sorted(changes.keys() - _FIELD_NAMES)
    new = object.__new__(VehicleTelemetry)
    values = new.__dict__
    values.update(tel.__dict__)
    values.update(changes)
    return new


def _heartbeat(tel: VehicleTelemetry, msg: MAVLinkMessage, now_s: float) -> dict[str, Any]:
    custom = int(msg.custom_mode)
    return {
        "mav_type": int(msg.type),
        "autopilot": int(msg.autopilot),
        "custom_mode": custom,
        "mode": plane_mode(custom),
        "armed": is_armed(msg.base_mode),
        "system_status": int(msg.system_status),
        "last_heartbeat_s": now_s,
    }


def _course_rate(tel: VehicleTelemetry, vn: float, ve: float, boot_ms: int) -> float:
    """The course's rate of turn from the previous velocity to this one (0 when either is
    too slow to have a course, or the two are not 0–1 s of vehicle time apart)."""
    if tel.vn_m_s is None or tel.ve_m_s is None or tel.position_boot_ms is None:
        return 0.0
    dt = (boot_ms - tel.position_boot_ms) / 1000.0
    if not 0.0 < dt <= 1.0 or math.hypot(vn, ve) < 1.0 or math.hypot(tel.vn_m_s, tel.ve_m_s) < 1.0:
        return tel.course_rate_rad_s if dt == 0.0 else 0.0
    turned = math.remainder(math.atan2(ve, vn) - math.atan2(tel.ve_m_s, tel.vn_m_s), math.tau)
    a = COURSE_RATE_SMOOTHING
    return a * turned / dt + (1.0 - a) * tel.course_rate_rad_s


def _vd_mean(tel: VehicleTelemetry, vd: float, boot_ms: int) -> float:
    """The vertical speed averaged over ``FLIGHT_PATH_SMOOTHING_S`` (the first one as it is,
    and again after a gap of more than a second of vehicle time)."""
    if tel.vd_mean_m_s is None or tel.position_boot_ms is None:
        return vd
    dt = (boot_ms - tel.position_boot_ms) / 1000.0
    if not 0.0 <= dt <= 1.0:
        return vd
    a = 1.0 - math.exp(-dt / FLIGHT_PATH_SMOOTHING_S)
    return a * vd + (1.0 - a) * tel.vd_mean_m_s


def _global_position_int(
    tel: VehicleTelemetry, msg: MAVLinkMessage, now_s: float
) -> dict[str, Any]:
    """A position, unless it is none: ArduPlane 4.7 streams GLOBAL_POSITION_INT about 0°, 0°
    before its EKF has a global position (lat 3003, lon −696 in 1e-7°; read as one, three
    vehicles waiting for their GPS were 11,761 km from their starts and on top of each
    other, and a start was refused): ``NULL_ISLAND_DEG``.  Its height above home is kept:
    the barometer's, by which a vehicle on the runway is known to be on the ground."""
    if abs(msg.lat) < NULL_ISLAND_E7 and abs(msg.lon) < NULL_ISLAND_E7:
        return {"relative_alt_m": msg.relative_alt * 1e-3}
    hdg = int(msg.hdg)
    vn, ve = msg.vx * 1e-2, msg.vy * 1e-2
    fix = Fix(int(msg.time_boot_ms), msg.lat * 1e-7, msg.lon * 1e-7, msg.alt * 1e-3)
    return {
        "recent_fixes": (*tel.recent_fixes[-(FIXES_KEPT - 1) :], fix),
        "position_boot_ms": int(msg.time_boot_ms),
        "course_rate_rad_s": _course_rate(tel, vn, ve, int(msg.time_boot_ms)),
        "vd_mean_m_s": _vd_mean(tel, msg.vz * 1e-2, int(msg.time_boot_ms)),
        "lat_deg": msg.lat * 1e-7,
        "lon_deg": msg.lon * 1e-7,
        "alt_amsl_m": msg.alt * 1e-3,
        "relative_alt_m": msg.relative_alt * 1e-3,
        "vn_m_s": msg.vx * 1e-2,
        "ve_m_s": msg.vy * 1e-2,
        "vd_m_s": msg.vz * 1e-2,
        "heading_deg": None if hdg == UINT16_UNKNOWN else hdg * 1e-2,
        "position_received_s": now_s,
    }


def _attitude(tel: VehicleTelemetry, msg: MAVLinkMessage, now_s: float) -> dict[str, Any]:
    return {"roll_rad": float(msg.roll), "pitch_rad": float(msg.pitch), "yaw_rad": float(msg.yaw)}


def _speed_ratio_mean(
    tel: VehicleTelemetry, airspeed: float, groundspeed: float, climb: float
) -> float | None:
    """The airspeed / speed over the ground ratio averaged over ``SPEED_RATIO_SMOOTHING_S``
    of vehicle time (VFR_HUD carries no time of its own: the vehicle's latest; restarted
    after a gap of more than 2 s); a sample on the ground or implausible is left out.

    The speed over the ground is along the flight path, √(groundspeed² + climb²), as the
    airspeed and the plan's speed are: VFR_HUD's groundspeed is horizontal, and over it a
    vehicle climbing at 58° showed a ratio of 1.9, its planned 100 m/s was commanded as
    190 and it sped up to 300 m/s."""
    groundspeed = math.hypot(groundspeed, climb)
    if groundspeed <= SPEED_RATIO_MIN_GROUNDSPEED_M_S or not 0.5 <= airspeed / groundspeed <= 2.0:
        return tel.speed_ratio_mean
    ratio = airspeed / groundspeed
    previous = tel.speed_ratio_mean
    if previous is None or tel.hud_boot_ms is None or tel.time_boot_ms is None:
        return ratio
    dt = (tel.time_boot_ms - tel.hud_boot_ms) / 1000.0
    if not 0.0 <= dt <= 2.0:
        return ratio
    a = 1.0 - math.exp(-dt / SPEED_RATIO_SMOOTHING_S)
    return a * ratio + (1.0 - a) * previous


def _vfr_hud(tel: VehicleTelemetry, msg: MAVLinkMessage, now_s: float) -> dict[str, Any]:
    airspeed, groundspeed, climb = float(msg.airspeed), float(msg.groundspeed), float(msg.climb)
    return {
        "airspeed_m_s": airspeed,
        "groundspeed_m_s": groundspeed,
        "climb_m_s": climb,
        "speed_ratio_mean": _speed_ratio_mean(tel, airspeed, groundspeed, climb),
        "hud_boot_ms": tel.time_boot_ms,
    }


def _system_time(tel: VehicleTelemetry, msg: MAVLinkMessage, now_s: float) -> dict[str, Any]:
    unix_us = int(msg.time_unix_usec)
    return {
        "system_time_boot_ms": int(msg.time_boot_ms),
        "unix_time_us": unix_us if unix_us > 0 else None,
    }


def _command_ack(tel: VehicleTelemetry, msg: MAVLinkMessage, now_s: float) -> dict[str, Any]:
    ack = CommandAck(command=int(msg.command), result=int(msg.result), received_s=now_s)
    others = [a for a in tel.command_acks if a.command != ack.command]
    return {"command_acks": tuple(sorted([*others, ack], key=lambda a: a.command))}


PITCH_LIMIT_PARAMS: dict[str, tuple[str, float]] = {
    "PTCH_LIM_MAX_DEG": ("pitch_max_deg", 1.0),  # ArduPlane 4.5 on, degrees
    "PTCH_LIM_MIN_DEG": ("pitch_min_deg", 1.0),
    "LIM_PITCH_MAX": ("pitch_max_deg", 0.01),  # before, centidegrees
    "LIM_PITCH_MIN": ("pitch_min_deg", 0.01),
}
"""ArduPlane's pitch-limit parameters: the field of ``VehicleTelemetry`` and the scale."""


AIRFRAME_PARAMS: tuple[str, ...] = (
    "TECS_CLMB_MAX",  # m/s: TECS's steepest climb rate
    "TECS_SINK_MAX",  # m/s: TECS's steepest sink rate
    "AIRSPEED_MIN",  # m/s (ArduPlane 4.5 on; ARSPD_FBW_MIN before)
    "AIRSPEED_CRUISE",  # m/s (TRIM_ARSPD_CM, cm/s, before)
    "AIRSPEED_MAX",  # m/s (ARSPD_FBW_MAX before)
    "ARSPD_FBW_MIN",
    "TRIM_ARSPD_CM",
    "ARSPD_FBW_MAX",
    "ROLL_LIMIT_DEG",  # degrees (LIM_ROLL_CD, centidegrees, before 4.5)
    "LIM_ROLL_CD",
    "GUIDED_P",  # GUIDED heading controller: centidegrees of bank per radian of error
    "TKOFF_ALT",  # m above home that TAKEOFF mode climbs to
    "TKOFF_DIST",  # m ahead of the takeoff point where TAKEOFF mode then loiters (4.5 on)
    "RLL2SRV_TCONST",  # s: the roll loop's time constant
    "TECS_TIME_CONST",  # s: TECS's height loop's time constant
    *PITCH_LIMIT_PARAMS,
)
"""The ArduPlane parameters the service reads from every vehicle (PARAM_REQUEST_READ) and
keeps, under the names of ArduPlane 4.5 on and of the versions before; see
``gcs_ppf.guidance.airframe`` for what each one limits."""

SET_PARAMS: tuple[str, ...] = ("RTL_ALTITUDE", "FENCE_ENABLE", "FENCE_TYPE", "FENCE_ACTION")
"""Parameters the service sets on a vehicle at a launch (the failsafe's RTL altitude, the
fence): their PARAM_VALUE is kept too, so that the value set reads back."""
KEPT_PARAMS = frozenset(AIRFRAME_PARAMS) | frozenset(SET_PARAMS)


def _param_value(tel: VehicleTelemetry, msg: MAVLinkMessage, now_s: float) -> dict[str, Any]:
    name = msg.param_id
    if isinstance(name, bytes):
        name = name.decode("ascii", "replace")
    name = str(name).rstrip("\x00")
    value = float(msg.param_value)
    if name not in KEPT_PARAMS or not math.isfinite(value):
        return {}
    kept = [p for p in tel.params if p.name != name]
    out: dict[str, Any] = {
        "params": tuple(sorted([*kept, ParamValue(name, value, now_s)], key=lambda p: p.name))
    }
    known = PITCH_LIMIT_PARAMS.get(name)
    if known is not None:
        field_name, scale = known
        out[field_name] = value * scale
    return out


def _sys_status(tel: VehicleTelemetry, msg: MAVLinkMessage, now_s: float) -> dict[str, Any]:
    present = int(msg.onboard_control_sensors_present)
    if not present & MAV_SYS_STATUS_PREARM_CHECK:
        return {"prearm_ok": None}
    return {
        "prearm_ok": bool(int(msg.onboard_control_sensors_health) & MAV_SYS_STATUS_PREARM_CHECK)
    }


def _gps_raw_int(tel: VehicleTelemetry, msg: MAVLinkMessage, now_s: float) -> dict[str, Any]:
    return {"gps_fix_type": int(msg.fix_type)}


def _statustext(tel: VehicleTelemetry, msg: MAVLinkMessage, now_s: float) -> dict[str, Any]:
    text = msg.text
    if isinstance(text, bytes):
        text = text.decode("ascii", "replace")
    text = str(text).rstrip("\x00").strip()
    if not text.startswith(ARMING_PREFIXES):
        return {}
    kept = [r for r in tel.arming_reasons if r.text != text]
    kept.append(ArmingReason(text, now_s))
    return {"arming_reasons": tuple(kept[-ARMING_REASONS_KEPT:])}


def _home_position(tel: VehicleTelemetry, msg: MAVLinkMessage, now_s: float) -> dict[str, Any]:
    if abs(msg.latitude) < NULL_ISLAND_E7 and abs(msg.longitude) < NULL_ISLAND_E7:
        return {}  # no home yet
    return {
        "home_lat_deg": msg.latitude * 1e-7,
        "home_lon_deg": msg.longitude * 1e-7,
        "home_alt_amsl_m": msg.altitude * 1e-3,
    }


_DECODERS = {
    "HEARTBEAT": _heartbeat,
    "GLOBAL_POSITION_INT": _global_position_int,
    "ATTITUDE": _attitude,
    "VFR_HUD": _vfr_hud,
    "SYSTEM_TIME": _system_time,
    "COMMAND_ACK": _command_ack,
    "PARAM_VALUE": _param_value,
    "SYS_STATUS": _sys_status,
    "GPS_RAW_INT": _gps_raw_int,
    "STATUSTEXT": _statustext,
    "HOME_POSITION": _home_position,
}

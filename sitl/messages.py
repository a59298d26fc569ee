"""Pure builders: vehicle state in, pymavlink message objects out.

No clock and no I/O: every timestamp is an argument. A message object is packed per peer by
the shell (``msg.pack(mav)``), which adds sequence number, system id and signature. Units at
this boundary are MAVLink's (degE7, mm, cm/s, cdeg); everything before it is SI (CONVENTIONS §1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, TypeAlias

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.mavlink.enums import (
    GPS_FIX_TYPE_3D_FIX,
    MAV_AUTOPILOT_ARDUPILOTMEGA,
    MAV_LANDED_STATE_IN_AIR,
    MAV_LANDED_STATE_ON_GROUND,
    MAV_TYPE_FIXED_WING,
    MAV_VTOL_STATE_UNDEFINED,
)
from sitl.modes import base_mode

Message: TypeAlias = Any  # a pymavlink MAVLink_*_message (pymavlink is untyped)


#: ArduPlane version we present: 4.5.7 official.
FLIGHT_SW_VERSION = (4 << 24) | (5 << 16) | (7 << 8) | 255
#: Capabilities this SITL honours (no FTP, no rally, no terrain; fences by the mission
#: protocol, which has no capability bit): MISSION_INT,
#: COMMAND_INT, SET_POSITION_TARGET_GLOBAL_INT (altitude only, as ArduPlane), MAVLINK2 and
#: PARAM_ENCODE_C_CAST (integer parameters travel as float-cast values, as on ArduPilot).
CAPABILITIES = (
    mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    | mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | mavlink.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
    | mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    | mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST
)
#: SYS_STATUS sensor bits: 3D gyro, 3D accel, 3D mag, abs pressure, diff pressure, GPS,
#: angular rate control, attitude stabilisation, yaw position, z/altitude control,
#: x/y position control, motor outputs, AHRS.
_SENSORS = 0x1 | 0x2 | 0x4 | 0x8 | 0x10 | 0x20 | 0x400 | 0x800 | 0x1000 | 0x2000 | 0x4000
_SENSORS |= 0x8000 | 0x200000


@dataclass(frozen=True, slots=True)
class Telemetry:
    """What the telemetry builders need of one vehicle at one instant (SI units, NED angles)."""

    time_boot_ms: int
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    alt_rel_home_m: float
    vel_ned_m_s: tuple[float, float, float]
    roll_rad: float
    pitch_rad: float
    heading_rad: float
    roll_rate_rad_s: float
    pitch_rate_rad_s: float
    yaw_rate_ned_rad_s: float
    airspeed_m_s: float
    throttle_pct: int
    landed: bool


def _i32(value: float) -> int:
    return max(-(2**31), min(2**31 - 1, round(value)))


def _i16(value: float) -> int:
    return max(-(2**15), min(2**15 - 1, round(value)))


def _u16(value: float) -> int:
    return max(0, min(2**16 - 1, round(value)))


def _wrap_pi(angle: float) -> float:
    return math.remainder(angle, math.tau)


def heartbeat(mode: PlaneMode, armed: bool, system_status: int) -> Message:
    return mavlink.MAVLink_heartbeat_message(
        MAV_TYPE_FIXED_WING,
        MAV_AUTOPILOT_ARDUPILOTMEGA,
        base_mode(mode, armed),
        int(mode),
        system_status,
        3,
    )


GEOFENCE = 0x100000
"""MAV_SYS_STATUS_GEOFENCE."""


def sys_status(
    drop_rate_comm_cpct: int = 0,
    fence_present: bool = False,
    fence_enabled: bool = False,
    fence_breached: bool = False,
) -> Message:
    """SYS_STATUS; the geofence bits as ArduPilot's AC_Fence sets them: present with fence
    items, enabled with FENCE_ENABLE, and healthy unless breached (healthy with no fence at
    all: MAVProxy calls a healthy bit that drops a breach)."""
    present = _SENSORS | (GEOFENCE if fence_present else 0)
    enabled = _SENSORS | (GEOFENCE if fence_enabled else 0)
    health = _SENSORS | (0 if fence_breached else GEOFENCE)
    return mavlink.MAVLink_sys_status_message(
        present, enabled, health, 200, 12600, 1000, 90, _u16(drop_rate_comm_cpct), 0, 0, 0, 0, 0
    )


def fence_status(breached: bool, count: int, breach_time_ms: int, breach_type: int) -> Message:
    return mavlink.MAVLink_fence_status_message(
        int(breached), _u16(count), breach_type, breach_time_ms & 0xFFFFFFFF, 0
    )


def gps_raw_int(t: Telemetry, time_usec: int) -> Message:
    vn, ve, _ = t.vel_ned_m_s
    ground_speed = math.hypot(vn, ve)
    cog = (math.degrees(math.atan2(ve, vn)) % 360.0) * 100.0
    return mavlink.MAVLink_gps_raw_int_message(
        time_usec,
        GPS_FIX_TYPE_3D_FIX,
        _i32(t.lat_deg * 1e7),
        _i32(t.lon_deg * 1e7),
        _i32(t.alt_amsl_m * 1000),
        80,
        120,
        _u16(ground_speed * 100),
        _u16(cog) % 36000,
        16,
    )


def global_position_int(t: Telemetry) -> Message:
    vn, ve, vd = t.vel_ned_m_s
    hdg = (math.degrees(t.heading_rad) % 360.0) * 100.0
    return mavlink.MAVLink_global_position_int_message(
        t.time_boot_ms,
        _i32(t.lat_deg * 1e7),
        _i32(t.lon_deg * 1e7),
        _i32(t.alt_amsl_m * 1000),
        _i32(t.alt_rel_home_m * 1000),
        _i16(vn * 100),
        _i16(ve * 100),
        _i16(vd * 100),
        _u16(hdg) % 36000,
    )


def attitude(t: Telemetry) -> Message:
    return mavlink.MAVLink_attitude_message(
        t.time_boot_ms,
        t.roll_rad,
        t.pitch_rad,
        _wrap_pi(t.heading_rad),
        t.roll_rate_rad_s,
        t.pitch_rate_rad_s,
        t.yaw_rate_ned_rad_s,
    )


def vfr_hud(t: Telemetry) -> Message:
    vn, ve, vd = t.vel_ned_m_s
    heading = round(math.degrees(t.heading_rad)) % 360
    return mavlink.MAVLink_vfr_hud_message(
        t.airspeed_m_s, math.hypot(vn, ve), heading, t.throttle_pct, t.alt_amsl_m, -vd
    )


def system_time(time_unix_usec: int, time_boot_ms: int) -> Message:
    return mavlink.MAVLink_system_time_message(time_unix_usec, time_boot_ms)


def extended_sys_state(landed: bool) -> Message:
    state = MAV_LANDED_STATE_ON_GROUND if landed else MAV_LANDED_STATE_IN_AIR
    return mavlink.MAVLink_extended_sys_state_message(MAV_VTOL_STATE_UNDEFINED, state)


def home_position(lat_deg: float, lon_deg: float, alt_amsl_m: float, time_usec: int) -> Message:
    """HOME_POSITION; the local x/y/z of home is 0 (this SITL's EKF origin is home)."""
    return mavlink.MAVLink_home_position_message(
        _i32(lat_deg * 1e7),
        _i32(lon_deg * 1e7),
        _i32(alt_amsl_m * 1000),
        0.0,
        0.0,
        0.0,
        [1.0, 0.0, 0.0, 0.0],
        0.0,
        0.0,
        0.0,
        time_usec,
    )


def autopilot_version(sysid: int) -> Message:
    custom = list(b"ppfsitl\x00")
    return mavlink.MAVLink_autopilot_version_message(
        CAPABILITIES, FLIGHT_SW_VERSION, 0, 0, 0, custom, [0] * 8, [0] * 8, 0, 0, sysid
    )


def mission_current(seq: int, total: int, mission_state: int, mission_mode: int) -> Message:
    return mavlink.MAVLink_mission_current_message(seq, total, mission_state, mission_mode)


def mission_item_reached(seq: int) -> Message:
    return mavlink.MAVLink_mission_item_reached_message(seq)


def statustext(severity: int, text: str) -> Message:
    return mavlink.MAVLink_statustext_message(severity, text.encode("ascii", "replace")[:50])


def timesync(tc1_ns: int, ts1_ns: int) -> Message:
    return mavlink.MAVLink_timesync_message(tc1_ns, ts1_ns)


def command_ack(command: int, result: int, target_system: int, target_component: int) -> Message:
    return mavlink.MAVLink_command_ack_message(
        command, result, 0, 0, target_system, target_component
    )


def param_value(name: str, value: float, ptype: int, count: int, index: int) -> Message:
    return mavlink.MAVLink_param_value_message(name.encode("ascii"), value, ptype, count, index)


def message_interval(message_id: int, interval_us: int) -> Message:
    return mavlink.MAVLink_message_interval_message(message_id, interval_us)


def position_target_global_int(
    time_boot_ms: int, lat_deg: float, lon_deg: float, alt_amsl_m: float
) -> Message:
    """The active navigation target, as ArduPlane reports it (position only, MAV_FRAME_GLOBAL)."""
    type_mask = 0xFDF8  # ignore velocity, acceleration, yaw, yaw rate (+ ArduPlane's 0xF000)
    return mavlink.MAVLink_position_target_global_int_message(
        time_boot_ms,
        0,
        type_mask,
        _i32(lat_deg * 1e7),
        _i32(lon_deg * 1e7),
        alt_amsl_m,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
    )


# MAVLink FTP (https://mavlink.io/en/services/ftp.html): payload header fields.
FTP_OP_NAK = 129
FTP_ERR_FILE_NOT_FOUND = 10


def ftp_nak_file_not_found(
    request_payload: bytes, target_system: int, target_component: int
) -> Message:
    """Answer any MAVLink FTP request with NAK / FileNotFound (no file system here).

    Reply header: seq = request seq + 1, session, opcode NAK, size 1, req_opcode echoed,
    data[0] = error code.
    """
    req = bytes(request_payload[:12]).ljust(12, b"\x00")
    seq = (int.from_bytes(req[0:2], "little") + 1) & 0xFFFF
    session, req_opcode = req[2], req[3]
    payload = bytearray(251)
    payload[0:2] = seq.to_bytes(2, "little")
    payload[2] = session
    payload[3] = FTP_OP_NAK
    payload[4] = 1  # size
    payload[5] = req_opcode
    payload[12] = FTP_ERR_FILE_NOT_FOUND
    return mavlink.MAVLink_file_transfer_protocol_message(
        0, target_system, target_component, list(payload)
    )

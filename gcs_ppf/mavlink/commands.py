"""Pure builders of the messages a ground station sends an ArduPlane (no I/O, no clock).

Each returns pymavlink message objects; the link's ``Codec`` gives them source ids and sequence
numbers when it encodes them.  Each docstring names the ArduPlane code the message relies on
(``ArduPlane/GCS_Mavlink.cpp``, ``libraries/GCS_MAVLink/GCS_Common.cpp``).  Commands go to the
autopilot component (1) unless told otherwise; ArduPilot answers every ``COMMAND_LONG`` and
``COMMAND_INT`` with a ``COMMAND_ACK`` carrying the command number.
"""

from __future__ import annotations

import math

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_ppf.mavlink.ardupilot import AUTOPILOT_COMPONENT_ID, FORCE_ARM_DISARM_MAGIC, PlaneMode
from gcs_ppf.mavlink.codec import MAVLinkMessage
from gcs_ppf.mavlink.enums import (
    HEADING_TYPE_COURSE_OVER_GROUND,
    MAV_DATA_STREAM_ALL,
    MAV_DATA_STREAM_EXTENDED_STATUS,
    MAV_DATA_STREAM_EXTRA1,
    MAV_DATA_STREAM_EXTRA2,
    MAV_DATA_STREAM_EXTRA3,
    MAV_DATA_STREAM_POSITION,
    MAV_DO_REPOSITION_FLAGS_CHANGE_MODE,
    MAV_FRAME_GLOBAL,
    MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
    MAV_PARAM_TYPE_REAL32,
    SPEED_TYPE_AIRSPEED,
)
from gcs_ppf.mavlink.enums import (  # the command numbers are re-exported: callers name a
    # command by the module that builds it (``commands.MAV_CMD_DO_SET_MODE``)
    MAV_CMD_COMPONENT_ARM_DISARM as MAV_CMD_COMPONENT_ARM_DISARM,
)
from gcs_ppf.mavlink.enums import (
    MAV_CMD_DO_CHANGE_SPEED as MAV_CMD_DO_CHANGE_SPEED,
)
from gcs_ppf.mavlink.enums import (
    MAV_CMD_DO_REPOSITION as MAV_CMD_DO_REPOSITION,
)
from gcs_ppf.mavlink.enums import (
    MAV_CMD_DO_SET_MODE as MAV_CMD_DO_SET_MODE,
)
from gcs_ppf.mavlink.enums import (
    MAV_CMD_GUIDED_CHANGE_ALTITUDE as MAV_CMD_GUIDED_CHANGE_ALTITUDE,
)
from gcs_ppf.mavlink.enums import (
    MAV_CMD_GUIDED_CHANGE_HEADING as MAV_CMD_GUIDED_CHANGE_HEADING,
)
from gcs_ppf.mavlink.enums import (
    MAV_CMD_REQUEST_MESSAGE as MAV_CMD_REQUEST_MESSAGE,
)
from gcs_ppf.mavlink.enums import (
    MAV_CMD_SET_MESSAGE_INTERVAL as MAV_CMD_SET_MESSAGE_INTERVAL,
)
from gcs_ppf.mavlink.enums import (
    MAVLINK_MSG_ID_HOME_POSITION as MAVLINK_MSG_ID_HOME_POSITION,
)

TELEMETRY_STREAMS: tuple[int, ...] = (
    MAV_DATA_STREAM_EXTENDED_STATUS,
    MAV_DATA_STREAM_POSITION,
    MAV_DATA_STREAM_EXTRA1,
    MAV_DATA_STREAM_EXTRA2,
    MAV_DATA_STREAM_EXTRA3,
)
"""ArduPlane's stream groups carrying what ``telemetry.apply`` decodes (``SRx_*`` parameters):
EXTENDED_STATUS (SYS_STATUS, GPS_RAW_INT), POSITION (GLOBAL_POSITION_INT), EXTRA1 (ATTITUDE),
EXTRA2 (VFR_HUD), EXTRA3 (SYSTEM_TIME)."""


def _target(target_system: int, target_component: int) -> None:
    if not (1 <= target_system <= 255 and 0 <= target_component <= 255):
        raise ValueError(
            f"target must be system 1..255 and component 0..255, "
            f"got {target_system}/{target_component}"
        )


def _finite(name: str, value: float) -> float:
    if not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value}")
    return float(value)


def _command_long(
    target_system: int, target_component: int, command: int, *params: float
) -> MAVLinkMessage:
    _target(target_system, target_component)
    p = [float(x) for x in params] + [0.0] * (7 - len(params))
    return mavlink2.MAVLink_command_long_message(target_system, target_component, command, 0, *p)


def timesync_request(now_ns: int) -> MAVLinkMessage:
    """TIMESYNC with tc1 = 0 and ts1 = our clock (ns): ArduPilot answers with tc1 = its own
    clock and ts1 echoed (``GCS_MAVLINK::handle_timesync``), so our clock at the answer
    minus ts1 is the link's round trip (how MAVROS and MAVSDK measure it)."""
    return mavlink2.MAVLink_timesync_message(0, now_ns)


def gcs_heartbeat() -> MAVLinkMessage:
    """The ground station's 1 Hz HEARTBEAT: ``MAV_TYPE_GCS``, ``MAV_AUTOPILOT_INVALID``.

    ArduPilot uses GCS heartbeats for its GCS-failsafe (``FS_GCS_ENABL``) and to learn where to
    route messages; it ignores the mode fields of a GCS heartbeat.
    """
    return mavlink2.MAVLink_heartbeat_message(
        mavlink2.MAV_TYPE_GCS,
        mavlink2.MAV_AUTOPILOT_INVALID,
        0,
        0,
        mavlink2.MAV_STATE_ACTIVE,
        3,
    )


def setup_signing(
    target_system: int, key: bytes, initial_timestamp: int, target_component: int = 1
) -> MAVLinkMessage:
    """SETUP_SIGNING: install ``key`` (32 bytes; all zeros turns signing off) on a vehicle,
    with the signing timestamp it goes on from (10 µs units since 2015, ``codec.
    signing_timestamp``).  ArduPilot stores it and signs on every link at once; it sends
    no acknowledgement.  The frame carries the key in clear: send it on a link you trust."""
    _target(target_system, target_component)
    if len(key) != 32:
        raise ValueError(f"key must be 32 bytes, got {len(key)}")
    if not 0 <= initial_timestamp < 2**48:
        raise ValueError(f"initial_timestamp must be 0 … 2⁴⁸−1, got {initial_timestamp}")
    return mavlink2.MAVLink_setup_signing_message(
        target_system, target_component, list(key), initial_timestamp
    )


def set_mode(
    target_system: int, mode: PlaneMode, *, target_component: int = AUTOPILOT_COMPONENT_ID
) -> MAVLinkMessage:
    """COMMAND_LONG ``MAV_CMD_DO_SET_MODE``: param1 ``MAV_MODE_FLAG_CUSTOM_MODE_ENABLED``,
    param2 the ArduPlane mode number.

    ArduPilot (``_set_mode_common``) only honours custom modes; it acks ACCEPTED, or FAILED when
    the mode refuses to start (e.g. GUIDED or LOITER without a position estimate).
    """
    return _command_long(
        target_system,
        target_component,
        MAV_CMD_DO_SET_MODE,
        MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
        int(PlaneMode(mode)),
    )


def arm(
    target_system: int,
    armed: bool,
    *,
    force: bool = False,
    target_component: int = AUTOPILOT_COMPONENT_ID,
) -> MAVLinkMessage:
    """COMMAND_LONG ``MAV_CMD_COMPONENT_ARM_DISARM``: param1 1 to arm, 0 to disarm.

    ``force`` puts 21196 in param2, which makes ArduPilot skip its pre-arm checks, or disarm
    a plane that is flying (which it otherwise refuses with FAILED).
    """
    return _command_long(
        target_system,
        target_component,
        MAV_CMD_COMPONENT_ARM_DISARM,
        1.0 if armed else 0.0,
        float(FORCE_ARM_DISARM_MAGIC) if force else 0.0,
    )


def reposition(
    target_system: int,
    lat_deg: float,
    lon_deg: float,
    alt_amsl_m: float,
    loiter_radius_m: float = 0.0,
    change_mode: bool = True,
    *,
    target_component: int = AUTOPILOT_COMPONENT_ID,
) -> MAVLinkMessage:
    """COMMAND_INT ``MAV_CMD_DO_REPOSITION`` in ``MAV_FRAME_GLOBAL``: fly to a guided point.

    This is how ArduPlane moves sideways in GUIDED (``handle_command_int_do_reposition``; it
    accepts the command only as COMMAND_INT).  x/y are lat/lon in 1e-7 degrees, z the altitude in
    metres above mean sea level.  param1 −1: ground speed unchanged (ArduPlane ignores it; speed
    goes by ``change_speed``).  param2 ``MAV_DO_REPOSITION_FLAGS_CHANGE_MODE`` if
    ``change_mode``: switch to GUIDED first; without it ArduPlane answers FAILED unless already
    in GUIDED.  param3: loiter radius in metres once there, used only if > 0 (else
    ``WP_LOITER_RAD``).  param4 NaN: ArduPlane reads yaw as the loiter direction, NaN or 0 is
    clockwise.  ArduPlane answers DENIED for a point that is not a valid location.
    """
    _target(target_system, target_component)
    lat = _finite("lat_deg", lat_deg)
    lon = _finite("lon_deg", lon_deg)
    alt = _finite("alt_amsl_m", alt_amsl_m)
    radius = _finite("loiter_radius_m", loiter_radius_m)
    if not -90.0 <= lat <= 90.0:
        raise ValueError(f"lat_deg must be within [-90, 90], got {lat}")
    if not -180.0 <= lon <= 180.0:
        raise ValueError(f"lon_deg must be within [-180, 180], got {lon}")
    if radius < 0.0:
        raise ValueError(f"loiter_radius_m must be >= 0, got {radius}")
    return mavlink2.MAVLink_command_int_message(
        target_system,
        target_component,
        MAV_FRAME_GLOBAL,
        MAV_CMD_DO_REPOSITION,
        0,
        0,
        -1.0,
        float(MAV_DO_REPOSITION_FLAGS_CHANGE_MODE if change_mode else 0),
        radius,
        math.nan,
        round(lat * 1e7),
        round(lon * 1e7),
        alt,
    )


def change_speed(
    target_system: int, airspeed_m_s: float, *, target_component: int = AUTOPILOT_COMPONENT_ID
) -> MAVLinkMessage:
    """COMMAND_LONG ``MAV_CMD_DO_CHANGE_SPEED``: param1 0 (airspeed), param2 the airspeed in
    m/s, param3 −1 (throttle unchanged), param4 0 (absolute).

    ArduPlane (``handle_command_DO_CHANGE_SPEED``) accepts it only in GUIDED-like modes and AUTO,
    answering FAILED otherwise; the target airspeed is then held within its
    ``AIRSPEED_MIN``..``AIRSPEED_MAX`` envelope.
    """
    speed = _finite("airspeed_m_s", airspeed_m_s)
    if speed <= 0.0:
        raise ValueError(f"airspeed_m_s must be > 0, got {speed}")
    return _command_long(
        target_system,
        target_component,
        MAV_CMD_DO_CHANGE_SPEED,
        SPEED_TYPE_AIRSPEED,
        speed,
        -1.0,
        0.0,
    )


def guided_change_heading(
    target_system: int,
    course_deg: float,
    lateral_accel_m_s2: float,
    *,
    target_component: int = AUTOPILOT_COMPONENT_ID,
) -> MAVLinkMessage:
    """COMMAND_INT ``MAV_CMD_GUIDED_CHANGE_HEADING`` (ArduPilot dialect, 43002): hold a course.

    ArduPlane (``handle_command_int_guided_slew_commands``, GUIDED only, else FAILED) flies the
    course over ground param2 (degrees from north, clockwise, in [0, 360)) with param1
    ``HEADING_TYPE_COURSE_OVER_GROUND``, banking no more than param3, a lateral acceleration in
    m/s², allows; it holds the course until a mode change or a DO_REPOSITION.  Its controller
    (``ModeGuided::update``) is P only by default: bank (centidegrees) = GUIDED_P × heading
    error (radians), clipped to ±min(atan(param3/g), ROLL_LIMIT_DEG), so a course that keeps
    moving is flown behind (``gcs_ppf.guidance.slew`` leads it).
    """
    course = _finite("course_deg", course_deg) % 360.0
    if float(np.float32(course)) >= 360.0:  # the wire's float32 rounds 359.99999… up
        course = 0.0
    accel = _finite("lateral_accel_m_s2", lateral_accel_m_s2)
    if accel <= 0.0:
        raise ValueError(f"lateral_accel_m_s2 must be > 0, got {accel}")
    _target(target_system, target_component)
    return mavlink2.MAVLink_command_int_message(
        target_system,
        target_component,
        MAV_FRAME_GLOBAL,
        MAV_CMD_GUIDED_CHANGE_HEADING,
        0,
        0,
        float(HEADING_TYPE_COURSE_OVER_GROUND),
        course,
        accel,
        0.0,
        0,
        0,
        0.0,
    )


def guided_change_altitude(
    target_system: int,
    alt_amsl_m: float,
    rate_m_s: float,
    *,
    target_component: int = AUTOPILOT_COMPONENT_ID,
) -> MAVLinkMessage:
    """COMMAND_INT ``MAV_CMD_GUIDED_CHANGE_ALTITUDE`` (ArduPilot dialect, 43001): change altitude
    at a vertical speed.

    ArduPlane (GUIDED only, else FAILED) takes z (metres above mean sea level in
    ``MAV_FRAME_GLOBAL``) as its altitude target and holds it until a mode change; it refuses
    z = 0 and z = −1 (DENIED), so they are refused here.  param3 = 0 lets TECS climb or sink
    as fast as it can (up to TECS_CLMB_MAX / TECS_SINK_MAX); param3 > 0 is *not* a climb-rate
    cap: each update moves the demand from the current altitude by param3 × Δt, so TECS barely
    climbs (measured on ArduPlane 4.7 SITL: 3.6 m in 60 s asked at 2 m/s;
    ``gcs_ppf.guidance.slew``).
    """
    alt = _finite("alt_amsl_m", alt_amsl_m)
    rate = _finite("rate_m_s", rate_m_s)
    if alt in (0.0, -1.0):
        raise ValueError(f"alt_amsl_m {alt} is refused by ArduPlane (0 and -1 mean 'unset')")
    if rate < 0.0:
        raise ValueError(f"rate_m_s must be >= 0, got {rate}")
    _target(target_system, target_component)
    return mavlink2.MAVLink_command_int_message(
        target_system,
        target_component,
        MAV_FRAME_GLOBAL,
        MAV_CMD_GUIDED_CHANGE_ALTITUDE,
        0,
        0,
        0.0,
        0.0,
        rate,
        0.0,
        0,
        0,
        alt,
    )


def set_message_interval(
    target_system: int,
    message_id: int,
    interval_us: int,
    *,
    target_component: int = AUTOPILOT_COMPONENT_ID,
) -> MAVLinkMessage:
    """COMMAND_LONG ``MAV_CMD_SET_MESSAGE_INTERVAL``: param1 the message id, param2 the interval
    in µs (−1 stops the message, 0 restores the default rate), param7 0 (to this link).

    ArduPilot applies it per link and it overrides the ``REQUEST_DATA_STREAM`` rates for that
    message; DENIED if the vehicle cannot send that message.  A REQUEST_DATA_STREAM sent after
    it sets the rate of the whole stream group again and overrides the interval (measured on
    ArduPlane 4.7): a ground station that sets intervals sends no REQUEST_DATA_STREAM.
    """
    if not 0 <= message_id <= 0xFFFFFF:
        raise ValueError(f"message_id must be a MAVLink message id (0..16777215), got {message_id}")
    if interval_us < -1:
        raise ValueError(f"interval_us must be >= -1, got {interval_us}")
    return _command_long(
        target_system,
        target_component,
        MAV_CMD_SET_MESSAGE_INTERVAL,
        float(message_id),
        float(interval_us),
    )


def request_message(
    target_system: int, message_id: int, *, target_component: int = AUTOPILOT_COMPONENT_ID
) -> MAVLinkMessage:
    """COMMAND_LONG ``MAV_CMD_REQUEST_MESSAGE``: param1 the message id, sent once (as
    QGroundControl asks for HOME_POSITION, ``MAVLINK_MSG_ID_HOME_POSITION``)."""
    if not 0 <= message_id <= 0xFFFFFF:
        raise ValueError(f"message_id must be a MAVLink message id (0..16777215), got {message_id}")
    return _command_long(
        target_system, target_component, MAV_CMD_REQUEST_MESSAGE, float(message_id)
    )


def request_data_streams(
    target_system: int,
    rate_hz: int,
    stream_id: int = MAV_DATA_STREAM_ALL,
    *,
    target_component: int = AUTOPILOT_COMPONENT_ID,
) -> MAVLinkMessage:
    """REQUEST_DATA_STREAM: stream group ``stream_id`` at ``rate_hz`` (0 stops it).

    The legacy rate request every ArduPilot honours (``handle_request_data_stream``): it sets the
    ``SRx_*`` rate of the group, or of every group for ``MAV_DATA_STREAM_ALL``.  Use one message
    per group of ``TELEMETRY_STREAMS`` to ask for less than everything.
    """
    _target(target_system, target_component)
    if not 0 <= rate_hz <= 0xFFFF:
        raise ValueError(f"rate_hz must be 0..65535, got {rate_hz}")
    if not 0 <= stream_id <= 255:
        raise ValueError(f"stream_id must be 0..255, got {stream_id}")
    return mavlink2.MAVLink_request_data_stream_message(
        target_system, target_component, stream_id, rate_hz, 1 if rate_hz > 0 else 0
    )


def _param_id(name: str) -> bytes:
    raw = name.encode("ascii")
    if not 1 <= len(raw) <= 16:
        raise ValueError(f"parameter name must be 1..16 ASCII characters, got {name!r}")
    return raw


def set_param(
    target_system: int,
    name: str,
    value: float,
    *,
    target_component: int = AUTOPILOT_COMPONENT_ID,
) -> MAVLinkMessage:
    """PARAM_SET of a float parameter; ArduPilot answers with PARAM_VALUE (not COMMAND_ACK),
    and ignores parameters it does not have."""
    _target(target_system, target_component)
    raw = _param_id(name)
    return mavlink2.MAVLink_param_set_message(
        target_system,
        target_component,
        raw,
        _finite("value", value),
        MAV_PARAM_TYPE_REAL32,
    )


def param_request_read(
    target_system: int, name: str, *, target_component: int = AUTOPILOT_COMPONENT_ID
) -> MAVLinkMessage:
    """PARAM_REQUEST_READ by name (param_index −1); ArduPilot answers with PARAM_VALUE, or
    not at all for a name it does not have."""
    _target(target_system, target_component)
    return mavlink2.MAVLink_param_request_read_message(
        target_system, target_component, _param_id(name), -1
    )


def takeoff(
    target_system: int, alt_m: float, *, target_component: int = AUTOPILOT_COMPONENT_ID
) -> tuple[MAVLinkMessage, MAVLinkMessage, MAVLinkMessage]:
    """The fixed-wing takeoff ArduPlane accepts: (PARAM_SET ``TKOFF_ALT``, TAKEOFF mode, arm).

    Send in order.  A fixed-wing ArduPlane does not take ``MAV_CMD_NAV_TAKEOFF`` as a command:
    ``GCS_MAVLINK_Plane`` handles it only for QuadPlanes (``quadplane.do_user_takeoff``), and a
    NAV_TAKEOFF is otherwise a mission item for AUTO.  TAKEOFF mode (13) climbs at full throttle
    to ``TKOFF_ALT`` metres above home once armed, then loiters.
    """
    alt = _finite("alt_m", alt_m)
    if alt <= 0.0:
        raise ValueError(f"alt_m must be > 0, got {alt}")
    return (
        set_param(target_system, "TKOFF_ALT", alt, target_component=target_component),
        set_mode(target_system, PlaneMode.TAKEOFF, target_component=target_component),
        arm(target_system, True, target_component=target_component),
    )

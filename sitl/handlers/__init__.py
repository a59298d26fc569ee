"""Inbound MAVLink: a dispatch table from message type to handler, and the commands.

Each handler takes the autopilot, the decoded message, the sender (sysid, compid), the
vehicle's kinematics and the clocks, and fills an Outbox. What ArduPlane does with each
message is noted where this SITL has to choose (ArduPlane/GCS_Mavlink.cpp, GCS_Common.cpp).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from gcs_ppf import geodesy
from gcs_ppf.mavlink import enums
from gcs_ppf.mavlink.ardupilot import FORCE_ARM_DISARM_MAGIC, PlaneMode
from gcs_ppf.mavlink.enums import (
    HEADING_TYPE_COURSE_OVER_GROUND,
    HEADING_TYPE_HEADING,
    MAV_CMD_COMPONENT_ARM_DISARM,
    MAV_CMD_DO_CHANGE_SPEED,
    MAV_CMD_DO_REPOSITION,
    MAV_CMD_DO_SET_MISSION_CURRENT,
    MAV_CMD_DO_SET_MODE,
    MAV_CMD_GET_HOME_POSITION,
    MAV_CMD_GET_MESSAGE_INTERVAL,
    MAV_CMD_GUIDED_CHANGE_ALTITUDE,
    MAV_CMD_GUIDED_CHANGE_HEADING,
    MAV_CMD_GUIDED_CHANGE_SPEED,
    MAV_CMD_MISSION_START,
    MAV_CMD_NAV_LOITER_UNLIM,
    MAV_CMD_NAV_RETURN_TO_LAUNCH,
    MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN,
    MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES,
    MAV_CMD_REQUEST_MESSAGE,
    MAV_CMD_SET_MESSAGE_INTERVAL,
    MAV_DO_REPOSITION_FLAGS_CHANGE_MODE,
    MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
    MAV_RESULT_ACCEPTED,
    MAV_RESULT_DENIED,
    MAV_RESULT_FAILED,
    MAV_RESULT_UNSUPPORTED,
    MAV_SEVERITY_INFO,
    MAV_SEVERITY_WARNING,
    MAV_TYPE_GCS,
    MAVLINK_MSG_ID_SET_MODE,
    SPEED_TYPE_AIRSPEED,
)
from sitl import messages as mb
from sitl import mission_protocol as mp
from sitl import streams as st
from sitl.autopilot import Autopilot, Clock, GuidedAltitude, GuidedCourse, Kinematics, Outbox
from sitl.modes import mode_from_number
from sitl.params import decode_param_id

Src = tuple[int, int]
Handler = Callable[[Autopilot, Any, Src, Kinematics, Clock, Outbox], None]


GUIDED_SLEW_COMMANDS = (
    MAV_CMD_GUIDED_CHANGE_SPEED,
    MAV_CMD_GUIDED_CHANGE_ALTITUDE,
    MAV_CMD_GUIDED_CHANGE_HEADING,
)
HEADING_TYPE_DEFAULT = 4

#: What a vehicle stuck on its last command (``--fault ignore=T``, SIM_CMD_IGNORE; see
#: ``sitl.faults``) acknowledges as ACCEPTED and does not act on: every command that changes
#: how it flies.
IGNORED_COMMANDS = frozenset({
    MAV_CMD_DO_SET_MODE, MAV_CMD_MISSION_START, MAV_CMD_NAV_RETURN_TO_LAUNCH,
    MAV_CMD_NAV_LOITER_UNLIM, MAV_CMD_DO_REPOSITION, *GUIDED_SLEW_COMMANDS,
    MAV_CMD_DO_CHANGE_SPEED, MAV_CMD_DO_SET_MISSION_CURRENT, MAV_CMD_COMPONENT_ARM_DISARM,
})  # fmt: skip


def addressed_elsewhere(ap: Autopilot, msg: Any) -> bool:
    """True if ``msg`` targets another system, or another component of this one."""
    target = getattr(msg, "target_system", 0)
    if target not in (0, ap.sysid):
        return True
    comp = getattr(msg, "target_component", 0)
    return comp not in (0, 1)


def _finite(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)


# ---- parameters --------------------------------------------------------------------------
def _param_msg(ap: Autopilot, index: int) -> Any:
    entry = ap.params.at(index)
    assert entry is not None
    spec, value = entry
    return mb.param_value(spec.name, value, int(spec.ptype), len(ap.params), index)


def on_param_request_list(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    out.reply.extend(_param_msg(ap, k) for k in range(len(ap.params)))


def on_param_request_read(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    if msg.param_index >= 0:
        if ap.params.at(msg.param_index) is not None:
            out.reply.append(_param_msg(ap, msg.param_index))
        return
    name = decode_param_id(msg.param_id)
    if name in ap.params:
        out.reply.append(_param_msg(ap, ap.params.index_of(name)))


def on_param_set(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    name = decode_param_id(msg.param_id)
    if name not in ap.params:
        return  # ArduPilot ignores unknown parameters
    if ap.params.set(name, float(msg.param_value)):
        apply_param(ap, name, clock)
        out.broadcast.append(_param_msg(ap, ap.params.index_of(name)))
    else:
        out.reply.append(_param_msg(ap, ap.params.index_of(name)))


#: Parameters that change the flight model's envelope (``Autopilot.write_envelope``).
ENVELOPE_PARAMS = frozenset({
    "SIM_SPEED_MIN", "SIM_SPEED_MAX", "SIM_ACCEL_MAX", "SIM_DECEL_MAX", "SIM_YAW_RATE",
    "SIM_PTCH_RATE", "SIM_SPD_HGT", "SIM_EAS2TAS", "PTCH_LIM_MAX_DEG", "PTCH_LIM_MIN_DEG",
    "ROLL_LIMIT_DEG", "GUIDED_P", "TECS_CLMB_MAX", "TECS_SINK_MAX", "NAVL1_PERIOD",
    "NAVL1_DAMPING", "AIRSPEED_CRUISE", "RLL2SRV_TCONST", "TECS_TIME_CONST",
})  # fmt: skip


def apply_param(ap: Autopilot, name: str, clock: Clock) -> None:
    """Side effects of a parameter change."""
    value = ap.params[name]
    if name in ENVELOPE_PARAMS:
        ap.envelope_dirty = True
        ap.guidance_dirty = True  # the speed demand is scaled by SIM_EAS2TAS
    elif name.startswith("AIRSPEED") or name == "WP_LOITER_RAD":
        ap.guidance_dirty = True
    elif name == "SIM_GPS_NOISE":
        ap.faults.noise_m = value
    elif name == "SIM_LINK_LOSS":
        ap.faults.loss_pct = value
    elif name == "SIM_LINK_DELAY":
        ap.faults.latency_ms = value
    elif name == "SIM_LINK_CUT" and value > 0:
        ap.faults.add_cut(clock.sim_s, value)
    elif name == "SIM_KILL" and value >= 1:
        ap.faults.dead = True
        ap.guidance_dirty = True
    elif name == "SIM_CMD_IGNORE":
        ap.faults.ignore_from_s = clock.sim_s if value >= 1 else None


# ---- mission protocol --------------------------------------------------------------------
def _home_item(ap: Autopilot) -> mp.MissionItem:
    lat, lon, alt = ap.home_geo
    return mp.MissionItem(0, 16, 0, 1, 0.0, 0.0, 0.0, 0.0, round(lat * 1e7), round(lon * 1e7), alt)


def _mission_result(ap: Autopilot, res: mp.Result, out: Outbox) -> None:
    out.reply.extend(res.replies)
    if res.mission_changed:
        ap.mission_changed()
        out.text(
            MAV_SEVERITY_INFO, f"Flight plan received ({max(len(ap.mission.items) - 1, 0)} items)"
        )


def on_mission_count(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    _mission_result(ap, ap.mission.on_count(src, msg.count, msg.mission_type, clock.link_s), out)


def on_mission_item(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    """MISSION_ITEM_INT / MISSION_ITEM: current = 2 is a guided goto, 3 an altitude change."""
    try:
        item = mp.item_from_message(msg)
    except (ValueError, OverflowError):
        out.reply.append(mavlink_ack(src, enums.MAV_MISSION_ERROR, msg.mission_type))
        return
    if msg.current in (2, 3):
        ok = guided_item(ap, item, msg.current == 3, kin, clock, out)
        result = enums.MAV_MISSION_ACCEPTED if ok else enums.MAV_MISSION_ERROR
        out.reply.append(mavlink_ack(src, result, msg.mission_type))
        return
    _mission_result(ap, ap.mission.on_item(src, msg.seq, item, msg.mission_type, clock.link_s), out)


def mavlink_ack(src: Src, result: int, mission_type: int) -> Any:
    return mavlink.MAVLink_mission_ack_message(src[0], src[1], result, mission_type)


def guided_item(
    ap: Autopilot, item: mp.MissionItem, alt_only: bool, kin: Kinematics, clock: Clock, out: Outbox
) -> bool:
    """ArduPlane accepts a guided goto only in GUIDED; an altitude change in any mode."""
    if mp.validate_item(item) != enums.MAV_MISSION_ACCEPTED and not alt_only:
        return False
    target = ap.location_to_enu(item.frame, item.x, item.y, item.z)
    if target is None or not _finite(target[2]):
        return False
    if alt_only:
        x, y, _ = ap.nav.pos_enu_m
        ap.set_nav(type(ap.nav)(ap.nav.kind, (x, y, target[2]), ap.nav.radius_m, ap.nav.direction))
        return True
    if ap.mode != PlaneMode.GUIDED or not _finite(target[0], target[1]):
        return False
    ap.set_nav(ap.loiter(target, ap.guided_radius_m, ap.guided_ccw))
    return True


def on_mission_request_list(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    _mission_result(ap, ap.mission.on_request_list(src, msg.mission_type), out)


def on_mission_request(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    as_int = msg.get_type() == "MISSION_REQUEST_INT"
    res = ap.mission.on_request(src, msg.seq, msg.mission_type, _home_item(ap), as_int)
    _mission_result(ap, res, out)


def on_mission_clear_all(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    _mission_result(ap, ap.mission.on_clear_all(src, msg.mission_type), out)


def on_mission_set_current(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    if set_mission_current(ap, msg.seq, kin, clock, out):
        out.broadcast.append(ap.mission_current_msg())


def set_mission_current(
    ap: Autopilot, seq: float, kin: Kinematics, clock: Clock, out: Outbox
) -> bool:
    if not _finite(seq) or not ap.runner.set_current(int(seq)):
        return False
    if ap.mode == PlaneMode.AUTO:
        ap.set_mode(PlaneMode.AUTO, kin, clock, out)
    return True


# ---- other messages ----------------------------------------------------------------------
def on_heartbeat(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    if msg.type == MAV_TYPE_GCS and src[0] == int(ap.params["SYSID_MYGCS"]):
        ap.last_gcs_heartbeat_s = clock.sim_s


def on_set_mode(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    result = do_set_mode(ap, msg.base_mode, msg.custom_mode, kin, clock, out)
    out.reply.append(mb.command_ack(MAVLINK_MSG_ID_SET_MODE, result, src[0], src[1]))


def on_set_position_target_global_int(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    """ArduPlane uses only the altitude, and only in GUIDED."""
    if ap.mode != PlaneMode.GUIDED or msg.type_mask & 0x4 or not _finite(msg.alt):
        return
    frame = {0: 0, 5: 0, 3: 3, 6: 3, 10: 3, 11: 3}.get(msg.coordinate_frame)
    if frame is None:
        out.text(MAV_SEVERITY_WARNING, "Invalid coord frame in SET_POSTION_TARGET_GLOBAL_INT")
        return
    x, y, _ = ap.nav.pos_enu_m
    target = ap.location_to_enu(frame, 0, 0, msg.alt)
    if target is not None:
        ap.set_nav(type(ap.nav)(ap.nav.kind, (x, y, target[2]), ap.nav.radius_m, ap.nav.direction))


def on_request_data_stream(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    ap.streams.request_data_stream(
        msg.req_stream_id, float(msg.req_message_rate), bool(msg.start_stop), clock.sim_s
    )


def on_timesync(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    """As ArduPilot's ``handle_timesync``: a request (tc1 = 0) is answered with tc1 = our
    clock in ns and ts1 echoed; an answer is ignored."""
    if msg.tc1 == 0:
        out.reply.append(mb.timesync(int(clock.sim_s * 1e9), int(msg.ts1)))


def on_ftp(ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox) -> None:
    out.reply.append(mb.ftp_nak_file_not_found(bytes(msg.payload), src[0], src[1]))


def on_command(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    is_int = msg.get_type() == "COMMAND_INT"
    answer = Outbox()
    try:
        result = command(ap, msg, is_int, src, kin, clock, answer)
    except (ValueError, OverflowError):
        result = MAV_RESULT_DENIED
    # The ACK goes first: ArduPilot queues requested messages behind it.
    out.reply.append(mb.command_ack(msg.command, result, src[0], src[1]))
    out.reply.extend(answer.reply)
    out.broadcast.extend(answer.broadcast)


# ---- commands ----------------------------------------------------------------------------
def do_set_mode(
    ap: Autopilot, base: float, custom: float, kin: Kinematics, clock: Clock, out: Outbox
) -> int:
    if not _finite(base, custom) or not int(base) & MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
        return MAV_RESULT_UNSUPPORTED
    mode = mode_from_number(float(custom))
    if mode is None:
        return MAV_RESULT_FAILED
    ap.set_mode(mode, kin, clock, out)
    return MAV_RESULT_ACCEPTED


def do_reposition(ap: Autopilot, msg: Any, kin: Kinematics, clock: Clock, out: Outbox) -> int:
    """ArduPlane's handle_command_int_do_reposition."""
    if not (-900_000_000 <= msg.x <= 900_000_000 and -1_800_000_000 <= msg.y <= 1_800_000_000):
        return MAV_RESULT_DENIED
    z = msg.z if math.isfinite(msg.z) else None
    target = ap.location_to_enu(msg.frame, msg.x, msg.y, z if z is not None else 0.0)
    if target is None:
        return MAV_RESULT_DENIED
    if z is None:
        target = (target[0], target[1], kin.pos_enu_m[2])
    if not _finite(*target):
        target = (kin.pos_enu_m[0], kin.pos_enu_m[1], target[2])
    flags = int(msg.param2) if math.isfinite(msg.param2) else 0
    if not (flags & MAV_DO_REPOSITION_FLAGS_CHANGE_MODE or ap.mode == PlaneMode.GUIDED):
        return MAV_RESULT_FAILED
    if ap.mode != PlaneMode.GUIDED:
        ap.set_mode(PlaneMode.GUIDED, kin, clock, out)
    ccw = math.isfinite(msg.param4) and msg.param4 != 0
    if math.isfinite(msg.param3) and msg.param3 > 0:
        ap.guided_radius_m, ap.guided_ccw = float(msg.param3), ccw
    ap.guided_course = None  # ArduPlane: target_heading_type = GUIDED_HEADING_NONE
    ap.guidance_dirty = True
    ap.set_nav(ap.loiter(target, ap.guided_radius_m, ap.guided_ccw))
    return MAV_RESULT_ACCEPTED


def guided_slew(ap: Autopilot, msg: Any, kin: Kinematics) -> int:
    """ArduPlane's ``handle_command_int_guided_slew_commands`` (COMMAND_INT only, GUIDED only).

    CHANGE_HEADING: param1 the heading type (course over ground or heading, the same here:
    no wind; HEADING_TYPE_DEFAULT cancels), param2 degrees in [0, 360), param3 the lateral
    acceleration that limits the bank (at least 0.05 m/s²); held until a mode change, a
    DO_REPOSITION or a cancel.  CHANGE_ALTITUDE: z in ``frame`` (0 and −1 are refused as
    ArduPlane does), param3 the vertical speed (0: as fast as possible); held until a mode
    change.  CHANGE_SPEED: param1 airspeed (the only type), param2 within AIRSPEED_MIN..MAX;
    param3 (the acceleration of the change) is accepted, the airframe's SIM_ACCEL_MAX and
    SIM_DECEL_MAX limit it here.
    """
    if ap.mode != PlaneMode.GUIDED:
        return MAV_RESULT_FAILED
    p1, p2, p3 = msg.param1, msg.param2, msg.param3
    if msg.command == MAV_CMD_GUIDED_CHANGE_SPEED:
        if not _finite(p1, p2) or int(p1) != SPEED_TYPE_AIRSPEED:
            return MAV_RESULT_DENIED
        if not ap.params["AIRSPEED_MIN"] <= p2 <= ap.params["AIRSPEED_MAX"]:
            return MAV_RESULT_FAILED
        ap.new_airspeed_m_s = float(p2)
    elif msg.command == MAV_CMD_GUIDED_CHANGE_ALTITUDE:
        if not _finite(msg.z) or msg.z in (0.0, -1.0):
            return MAV_RESULT_DENIED
        lat, lon, _ = geodesy.enu_to_geodetic(*kin.pos_enu_m, ap.origin)  # the altitude here
        target = ap.location_to_enu(msg.frame, round(lat * 1e7), round(lon * 1e7), float(msg.z))
        if target is None:
            return MAV_RESULT_DENIED
        rate = abs(p3) if _finite(p3) and p3 != 0.0 else 1000.0
        ap.guided_altitude = GuidedAltitude(target[2], rate)
    else:
        if not _finite(p1, p2) or not 0.0 <= p2 < 360.0:
            return MAV_RESULT_DENIED
        kind = int(p1)
        if kind == HEADING_TYPE_DEFAULT:
            ap.guided_course = None
        elif kind in (HEADING_TYPE_COURSE_OVER_GROUND, HEADING_TYPE_HEADING):
            accel = max(float(p3), 0.05) if _finite(p3) else 0.05
            ap.guided_course = GuidedCourse(math.radians(90.0 - p2), accel)
        else:
            return MAV_RESULT_DENIED
    ap.guidance_dirty = True
    return MAV_RESULT_ACCEPTED


def command(
    ap: Autopilot, msg: Any, is_int: bool, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> int:
    cmd = msg.command
    p1, p2 = msg.param1, msg.param2
    if cmd == MAV_CMD_COMPONENT_ARM_DISARM:
        if p1 == 1:
            ap.armed = True
            ap.guidance_dirty = True
            return MAV_RESULT_ACCEPTED
        if p1 == 0:
            if not kin.landed and p2 != FORCE_ARM_DISARM_MAGIC:
                out.text(MAV_SEVERITY_WARNING, "Disarm refused: flying")
                return MAV_RESULT_FAILED
            ap.armed = False
            ap.guidance_dirty = True
            return MAV_RESULT_ACCEPTED
        return MAV_RESULT_UNSUPPORTED
    if cmd == MAV_CMD_DO_SET_MODE:
        return do_set_mode(ap, p1, p2, kin, clock, out)
    if cmd == MAV_CMD_DO_REPOSITION:
        # Sent as COMMAND_LONG, older ArduPlane does not know it; we insist on COMMAND_INT.
        return do_reposition(ap, msg, kin, clock, out) if is_int else MAV_RESULT_UNSUPPORTED
    if cmd in GUIDED_SLEW_COMMANDS:
        return guided_slew(ap, msg, kin) if is_int else MAV_RESULT_UNSUPPORTED
    if cmd == MAV_CMD_DO_CHANGE_SPEED:
        if ap.mode not in (PlaneMode.GUIDED, PlaneMode.AUTO) or not _finite(p1, p2):
            return MAV_RESULT_FAILED
        return MAV_RESULT_ACCEPTED if ap.change_speed(float(p2), out) else MAV_RESULT_FAILED
    if cmd == MAV_CMD_MISSION_START:
        ap.set_mode(PlaneMode.AUTO, kin, clock, out)
        return MAV_RESULT_ACCEPTED
    if cmd == MAV_CMD_NAV_RETURN_TO_LAUNCH:
        ap.set_mode(PlaneMode.RTL, kin, clock, out)
        return MAV_RESULT_ACCEPTED
    if cmd == MAV_CMD_NAV_LOITER_UNLIM:
        ap.set_mode(PlaneMode.LOITER, kin, clock, out)
        return MAV_RESULT_ACCEPTED
    if cmd == MAV_CMD_DO_SET_MISSION_CURRENT:
        ok = set_mission_current(ap, p1, kin, clock, out)
        if ok:
            out.broadcast.append(ap.mission_current_msg())
        return MAV_RESULT_ACCEPTED if ok else MAV_RESULT_FAILED
    if cmd == MAV_CMD_SET_MESSAGE_INTERVAL:
        if not _finite(p1) or not ap.streams.set_interval_us(int(p1), float(p2), clock.sim_s):
            return MAV_RESULT_FAILED
        return MAV_RESULT_ACCEPTED
    if cmd == MAV_CMD_GET_MESSAGE_INTERVAL:
        if not _finite(p1) or not ap.streams.supports(int(p1)):
            return MAV_RESULT_FAILED
        out.reply.append(mb.message_interval(int(p1), ap.streams.interval_us(int(p1))))
        return MAV_RESULT_ACCEPTED
    if cmd == MAV_CMD_REQUEST_MESSAGE:
        reply = requested_message(ap, int(p1) if _finite(p1) else -1, kin, clock)
        if reply is None:
            return MAV_RESULT_FAILED
        out.reply.append(reply)
        return MAV_RESULT_ACCEPTED
    if cmd == MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
        out.reply.append(mb.autopilot_version(ap.sysid))
        return MAV_RESULT_ACCEPTED
    if cmd == MAV_CMD_GET_HOME_POSITION:
        out.reply.append(ap.home_position(clock))
        return MAV_RESULT_ACCEPTED
    if cmd == MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN:
        if p1 != 1:
            return MAV_RESULT_UNSUPPORTED
        if ap.armed:
            return MAV_RESULT_FAILED
        ap.reboot_requested = True
        return MAV_RESULT_ACCEPTED
    return MAV_RESULT_UNSUPPORTED


def requested_message(ap: Autopilot, msg_id: int, kin: Kinematics, clock: Clock) -> Any | None:
    """MAV_CMD_REQUEST_MESSAGE: the one-off messages, and any streamed one."""
    if msg_id == st.AUTOPILOT_VERSION:
        return mb.autopilot_version(ap.sysid)
    if msg_id == st.HOME_POSITION:
        return ap.home_position(clock)
    if msg_id == st.HEARTBEAT:
        return ap.heartbeat()
    if msg_id == st.MISSION_CURRENT:
        return ap.mission_current_msg()
    if msg_id == st.EXTENDED_SYS_STATE:
        return mb.extended_sys_state(kin.landed)
    if msg_id == st.SYSTEM_TIME:
        return mb.system_time(clock.unix_us, clock.time_boot_ms)
    return None


HANDLERS: dict[str, Handler] = {
    "HEARTBEAT": on_heartbeat,
    "PARAM_REQUEST_LIST": on_param_request_list,
    "PARAM_REQUEST_READ": on_param_request_read,
    "PARAM_SET": on_param_set,
    "MISSION_COUNT": on_mission_count,
    "MISSION_ITEM_INT": on_mission_item,
    "MISSION_ITEM": on_mission_item,
    "MISSION_REQUEST_LIST": on_mission_request_list,
    "MISSION_REQUEST_INT": on_mission_request,
    "MISSION_REQUEST": on_mission_request,
    "MISSION_CLEAR_ALL": on_mission_clear_all,
    "MISSION_SET_CURRENT": on_mission_set_current,
    "COMMAND_LONG": on_command,
    "COMMAND_INT": on_command,
    "SET_MODE": on_set_mode,
    "TIMESYNC": on_timesync,
    "SET_POSITION_TARGET_GLOBAL_INT": on_set_position_target_global_int,
    "REQUEST_DATA_STREAM": on_request_data_stream,
    "FILE_TRANSFER_PROTOCOL": on_ftp,
}


def ignored(msg: Any, src: Src) -> Outbox | None:
    """What a vehicle stuck on its last command answers to ``msg`` instead of obeying it:
    ACCEPTED for a flight command (``IGNORED_COMMANDS``, SET_MODE, a guided
    MISSION_ITEM_INT), nothing for SET_POSITION_TARGET_GLOBAL_INT; None for any other
    message, which is handled as usual."""
    kind = msg.get_type()
    out = Outbox()
    if kind in ("COMMAND_LONG", "COMMAND_INT") and msg.command in IGNORED_COMMANDS:
        out.reply.append(mb.command_ack(msg.command, MAV_RESULT_ACCEPTED, src[0], src[1]))
    elif kind == "SET_MODE":
        out.reply.append(
            mb.command_ack(MAVLINK_MSG_ID_SET_MODE, MAV_RESULT_ACCEPTED, src[0], src[1])
        )
    elif kind in ("MISSION_ITEM_INT", "MISSION_ITEM") and msg.current in (2, 3):
        out.reply.append(mavlink_ack(src, enums.MAV_MISSION_ACCEPTED, msg.mission_type))
    elif kind not in ("SET_POSITION_TARGET_GLOBAL_INT", "MISSION_SET_CURRENT"):
        return None
    return out


def handle(ap: Autopilot, msg: Any, kin: Kinematics, clock: Clock) -> Outbox | None:
    """Dispatch one decoded message; None when it is not for this vehicle or not handled."""
    handler = HANDLERS.get(msg.get_type())
    if handler is None or ap.faults.dead or addressed_elsewhere(ap, msg):
        return None
    src = (msg.get_srcSystem(), msg.get_srcComponent())
    if ap.faults.ignoring_commands(clock.sim_s):
        stuck = ignored(msg, src)
        if stuck is not None:
            return stuck
    out = Outbox()
    handler(ap, msg, src, kin, clock, out)
    return out

"""COMMAND_LONG, COMMAND_INT and SET_MODE: each command's ACK result and what it does, as
ArduPlane's GCS_MAVLink_Plane.cpp and GCS_Common.cpp answer them."""

from __future__ import annotations

from typing import Any

from gcs_ppf.mavlink.ardupilot import FORCE_ARM_DISARM_MAGIC, PlaneMode
from gcs_ppf.mavlink.enums import (
    MAV_CMD_COMPONENT_ARM_DISARM,
    MAV_CMD_DO_CHANGE_SPEED,
    MAV_CMD_DO_REPOSITION,
    MAV_CMD_DO_SET_MISSION_CURRENT,
    MAV_CMD_DO_SET_MODE,
    MAV_CMD_GET_HOME_POSITION,
    MAV_CMD_GET_MESSAGE_INTERVAL,
    MAV_CMD_MISSION_START,
    MAV_CMD_NAV_LOITER_UNLIM,
    MAV_CMD_NAV_RETURN_TO_LAUNCH,
    MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN,
    MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES,
    MAV_CMD_REQUEST_MESSAGE,
    MAV_CMD_SET_MESSAGE_INTERVAL,
    MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
    MAV_RESULT_ACCEPTED,
    MAV_RESULT_DENIED,
    MAV_RESULT_FAILED,
    MAV_RESULT_UNSUPPORTED,
    MAV_SEVERITY_WARNING,
    MAVLINK_MSG_ID_SET_MODE,
)
from sitl import messages as mb
from sitl.autopilot import Autopilot, Clock, Kinematics, Outbox
from sitl.handlers.base import Src, finite
from sitl.handlers.guided import GUIDED_SLEW_COMMANDS, do_reposition, guided_slew
from sitl.handlers.mission import set_mission_current
from sitl.handlers.telemetry import get_message_interval, request_message, set_message_interval
from sitl.modes import mode_from_number

#: Commands that switch the flight mode to the one named, whatever their parameters.
MODE_COMMANDS = {
    MAV_CMD_MISSION_START: PlaneMode.AUTO,
    MAV_CMD_NAV_RETURN_TO_LAUNCH: PlaneMode.RTL,
    MAV_CMD_NAV_LOITER_UNLIM: PlaneMode.LOITER,
}


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


def on_set_mode(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    result = do_set_mode(ap, msg.base_mode, msg.custom_mode, kin, clock, out)
    out.reply.append(mb.command_ack(MAVLINK_MSG_ID_SET_MODE, result, src[0], src[1]))


def do_set_mode(
    ap: Autopilot, base: float, custom: float, kin: Kinematics, clock: Clock, out: Outbox
) -> int:
    if not finite(base, custom) or not int(base) & MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
        return MAV_RESULT_UNSUPPORTED
    mode = mode_from_number(float(custom))
    if mode is None:
        return MAV_RESULT_FAILED
    # ArduPlane's Plane::set_mode: "don't switch modes if we are already in the correct
    # mode" (GUIDED asked again keeps its guided point, course and speed)
    if mode != ap.mode:
        ap.set_mode(mode, kin, clock, out)
    return MAV_RESULT_ACCEPTED


def arm_disarm(ap: Autopilot, p1: float, p2: float, kin: Kinematics, out: Outbox) -> int:
    """MAV_CMD_COMPONENT_ARM_DISARM: a flying vehicle disarms only when forced."""
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


def change_speed(ap: Autopilot, p1: float, p2: float, out: Outbox) -> int:
    """MAV_CMD_DO_CHANGE_SPEED, in GUIDED or AUTO only (ArduPlane's guard)."""
    if ap.mode not in (PlaneMode.GUIDED, PlaneMode.AUTO) or not finite(p1, p2):
        return MAV_RESULT_FAILED
    return MAV_RESULT_ACCEPTED if ap.change_speed(float(p2), out) else MAV_RESULT_FAILED


def reboot(ap: Autopilot, p1: float) -> int:
    """MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN: the autopilot reboots (param1 = 1), disarmed only."""
    if p1 != 1:
        return MAV_RESULT_UNSUPPORTED
    if ap.armed:
        return MAV_RESULT_FAILED
    ap.reboot_requested = True
    return MAV_RESULT_ACCEPTED


def command(
    ap: Autopilot, msg: Any, is_int: bool, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> int:
    """The result of one COMMAND_LONG / COMMAND_INT, its effects done and replies queued."""
    cmd = msg.command
    p1, p2 = msg.param1, msg.param2
    if cmd == MAV_CMD_COMPONENT_ARM_DISARM:
        return arm_disarm(ap, p1, p2, kin, out)
    if cmd == MAV_CMD_DO_SET_MODE:
        return do_set_mode(ap, p1, p2, kin, clock, out)
    if cmd == MAV_CMD_DO_REPOSITION:
        # Sent as COMMAND_LONG, older ArduPlane does not know it; we insist on COMMAND_INT.
        return do_reposition(ap, msg, kin, clock, out) if is_int else MAV_RESULT_UNSUPPORTED
    if cmd in GUIDED_SLEW_COMMANDS:
        return guided_slew(ap, msg, kin) if is_int else MAV_RESULT_UNSUPPORTED
    if cmd == MAV_CMD_DO_CHANGE_SPEED:
        return change_speed(ap, p1, p2, out)
    if cmd in MODE_COMMANDS:
        ap.set_mode(MODE_COMMANDS[cmd], kin, clock, out)
        return MAV_RESULT_ACCEPTED
    if cmd == MAV_CMD_DO_SET_MISSION_CURRENT:
        ok = set_mission_current(ap, p1, kin, clock, out)
        if ok:
            out.broadcast.append(ap.mission_current_msg())
        return MAV_RESULT_ACCEPTED if ok else MAV_RESULT_FAILED
    if cmd == MAV_CMD_SET_MESSAGE_INTERVAL:
        return set_message_interval(ap, p1, p2, clock)
    if cmd == MAV_CMD_GET_MESSAGE_INTERVAL:
        return get_message_interval(ap, p1, out)
    if cmd == MAV_CMD_REQUEST_MESSAGE:
        return request_message(ap, p1, kin, clock, out)
    if cmd == MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
        out.reply.append(mb.autopilot_version(ap.sysid))
        return MAV_RESULT_ACCEPTED
    if cmd == MAV_CMD_GET_HOME_POSITION:
        out.reply.append(ap.home_position(clock))
        return MAV_RESULT_ACCEPTED
    if cmd == MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN:
        return reboot(ap, p1)
    return MAV_RESULT_UNSUPPORTED

"""Inbound MAVLink to the SITL: the dispatch table from message type to handler.

Each handler (``sitl.handlers.base.Handler``) takes the autopilot, the decoded message, the
sender (sysid, compid), the vehicle's kinematics and the clocks, and fills an Outbox. The
handlers are grouped by what they talk about: ``commands`` (COMMAND_LONG/_INT, SET_MODE),
``guided`` (GUIDED targets), ``mission`` (the mission protocol), ``parameters``,
``telemetry`` (streams and requested messages) and ``link`` (heartbeat, timesync, FTP). What
ArduPlane does with each message is noted where this SITL has to choose
(ArduPlane/GCS_MAVLink_Plane.cpp, GCS_Common.cpp).
"""

from __future__ import annotations

from typing import Any

from gcs_ppf.mavlink import enums
from gcs_ppf.mavlink.enums import (
    MAV_CMD_COMPONENT_ARM_DISARM,
    MAV_CMD_DO_CHANGE_SPEED,
    MAV_CMD_DO_REPOSITION,
    MAV_CMD_DO_SET_MISSION_CURRENT,
    MAV_CMD_DO_SET_MODE,
    MAV_CMD_MISSION_START,
    MAV_CMD_NAV_LOITER_UNLIM,
    MAV_CMD_NAV_RETURN_TO_LAUNCH,
    MAV_RESULT_ACCEPTED,
    MAVLINK_MSG_ID_SET_MODE,
)
from sitl import messages as mb
from sitl.autopilot import Autopilot, Clock, Kinematics, Outbox
from sitl.handlers import commands, guided, link, mission, parameters, telemetry
from sitl.handlers.base import Handler, Src

#: What a vehicle stuck on its last command (``--fault ignore=T``, SIM_CMD_IGNORE; see
#: ``sitl.faults``) acknowledges as ACCEPTED and does not act on: every command that changes
#: how it flies.
IGNORED_COMMANDS = frozenset(
    {
        MAV_CMD_DO_SET_MODE,
        MAV_CMD_MISSION_START,
        MAV_CMD_NAV_RETURN_TO_LAUNCH,
        MAV_CMD_NAV_LOITER_UNLIM,
        MAV_CMD_DO_REPOSITION,
        *guided.GUIDED_SLEW_COMMANDS,
        MAV_CMD_DO_CHANGE_SPEED,
        MAV_CMD_DO_SET_MISSION_CURRENT,
        MAV_CMD_COMPONENT_ARM_DISARM,
    }
)


def addressed_elsewhere(ap: Autopilot, msg: Any) -> bool:
    """True if ``msg`` targets another system, or another component of this one."""
    target = getattr(msg, "target_system", 0)
    if target not in (0, ap.sysid):
        return True
    comp = getattr(msg, "target_component", 0)
    return comp not in (0, 1)


HANDLERS: dict[str, Handler] = {
    "HEARTBEAT": link.on_heartbeat,
    "PARAM_REQUEST_LIST": parameters.on_param_request_list,
    "PARAM_REQUEST_READ": parameters.on_param_request_read,
    "PARAM_SET": parameters.on_param_set,
    "MISSION_COUNT": mission.on_mission_count,
    "MISSION_ITEM_INT": mission.on_mission_item,
    "MISSION_ITEM": mission.on_mission_item,
    "MISSION_REQUEST_LIST": mission.on_mission_request_list,
    "MISSION_REQUEST_INT": mission.on_mission_request,
    "MISSION_REQUEST": mission.on_mission_request,
    "MISSION_CLEAR_ALL": mission.on_mission_clear_all,
    "MISSION_SET_CURRENT": mission.on_mission_set_current,
    "COMMAND_LONG": commands.on_command,
    "COMMAND_INT": commands.on_command,
    "SET_MODE": commands.on_set_mode,
    "TIMESYNC": link.on_timesync,
    "SET_POSITION_TARGET_GLOBAL_INT": guided.on_set_position_target_global_int,
    "REQUEST_DATA_STREAM": telemetry.on_request_data_stream,
    "FILE_TRANSFER_PROTOCOL": link.on_ftp,
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
        out.reply.append(mission.mavlink_ack(src, enums.MAV_MISSION_ACCEPTED, msg.mission_type))
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

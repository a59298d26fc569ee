"""The mission protocol's messages (MISSION_COUNT, _ITEM(_INT), _REQUEST(_LIST), _CLEAR_ALL,
_SET_CURRENT) handed to the sans-I/O ``sitl.mission_protocol``, and the current item."""

from __future__ import annotations

from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from gcs_ppf.mavlink import enums
from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.mavlink.enums import MAV_SEVERITY_INFO, MAV_SEVERITY_WARNING
from sitl import mission_protocol as mp
from sitl.autopilot import Autopilot, Clock, Kinematics, Outbox
from sitl.handlers.base import Src, finite
from sitl.handlers.guided import guided_item


def _home_item(ap: Autopilot) -> mp.MissionItem:
    lat, lon, alt = ap.home_geo
    return mp.MissionItem(0, 16, 0, 1, 0.0, 0.0, 0.0, 0.0, round(lat * 1e7), round(lon * 1e7), alt)


def _server(ap: Autopilot, mission_type: int) -> mp.MissionServer:
    """The list a message is about: the fence's, or the mission's (which answers the rest)."""
    return ap.fence if mission_type == mp.MISSION_TYPE_FENCE else ap.mission


def _mission_result(ap: Autopilot, res: mp.Result, out: Outbox, mission_type: int = 0) -> None:
    out.reply.extend(res.replies)
    if not res.mission_changed:
        return
    if mission_type == mp.MISSION_TYPE_FENCE:
        if ap.fence_changed():
            out.text(MAV_SEVERITY_INFO, f"Fence: {len(ap.fence_areas)} areas")
        else:
            out.text(MAV_SEVERITY_WARNING, "Fence: polygon vertex counts do not add up; cleared")
        return
    ap.mission_changed()
    out.text(MAV_SEVERITY_INFO, f"Flight plan received ({max(len(ap.mission.items) - 1, 0)} items)")


def mavlink_ack(src: Src, result: int, mission_type: int) -> Any:
    """A MISSION_ACK to ``src``."""
    return mavlink.MAVLink_mission_ack_message(src[0], src[1], result, mission_type)


def on_mission_count(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    server = _server(ap, msg.mission_type)
    res = server.on_count(src, msg.count, msg.mission_type, clock.link_s)
    _mission_result(ap, res, out, msg.mission_type)


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
    server = _server(ap, msg.mission_type)
    res = server.on_item(src, msg.seq, item, msg.mission_type, clock.link_s)
    _mission_result(ap, res, out, msg.mission_type)


def on_mission_request_list(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    res = _server(ap, msg.mission_type).on_request_list(src, msg.mission_type)
    _mission_result(ap, res, out, msg.mission_type)


def on_mission_request(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    as_int = msg.get_type() == "MISSION_REQUEST_INT"
    server = _server(ap, msg.mission_type)
    res = server.on_request(src, msg.seq, msg.mission_type, _home_item(ap), as_int)
    _mission_result(ap, res, out, msg.mission_type)


def on_mission_clear_all(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    if msg.mission_type == mp.MISSION_TYPE_ALL:  # every list, the fence's too
        _mission_result(ap, ap.fence.on_clear_all(src, msg.mission_type), Outbox(), 1)
    server = _server(ap, msg.mission_type)
    _mission_result(ap, server.on_clear_all(src, msg.mission_type), out, msg.mission_type)


def on_mission_set_current(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    if set_mission_current(ap, msg.seq, kin, clock, out):
        out.broadcast.append(ap.mission_current_msg())


def set_mission_current(
    ap: Autopilot, seq: float, kin: Kinematics, clock: Clock, out: Outbox
) -> bool:
    """Make ``seq`` the current item (restarting it in AUTO); False if there is none."""
    if not finite(seq) or not ap.runner.set_current(int(seq)):
        return False
    if ap.mode == PlaneMode.AUTO:
        ap.set_mode(PlaneMode.AUTO, kin, clock, out)
    return True

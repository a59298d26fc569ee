"""What the vehicle sends and how often, on request: REQUEST_DATA_STREAM, the message-interval
commands and MAV_CMD_REQUEST_MESSAGE (the schedule itself is ``sitl.streams``)."""

from __future__ import annotations

from typing import Any

from gcs_ppf.mavlink.enums import MAV_RESULT_ACCEPTED, MAV_RESULT_FAILED
from sitl import messages as mb
from sitl import streams as st
from sitl.autopilot import Autopilot, Clock, Kinematics, Outbox
from sitl.handlers.base import Src, finite


def on_request_data_stream(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    ap.streams.request_data_stream(
        msg.req_stream_id, float(msg.req_message_rate), bool(msg.start_stop), clock.sim_s
    )


def set_message_interval(ap: Autopilot, p1: float, p2: float, clock: Clock) -> int:
    """MAV_CMD_SET_MESSAGE_INTERVAL: message id ``p1`` every ``p2`` µs."""
    if not finite(p1) or not ap.streams.set_interval_us(int(p1), float(p2), clock.sim_s):
        return MAV_RESULT_FAILED
    return MAV_RESULT_ACCEPTED


def get_message_interval(ap: Autopilot, p1: float, out: Outbox) -> int:
    """MAV_CMD_GET_MESSAGE_INTERVAL: MESSAGE_INTERVAL of message id ``p1``."""
    if not finite(p1) or not ap.streams.supports(int(p1)):
        return MAV_RESULT_FAILED
    out.reply.append(mb.message_interval(int(p1), ap.streams.interval_us(int(p1))))
    return MAV_RESULT_ACCEPTED


def request_message(ap: Autopilot, p1: float, kin: Kinematics, clock: Clock, out: Outbox) -> int:
    """MAV_CMD_REQUEST_MESSAGE: message id ``p1`` once, now."""
    reply = requested_message(ap, int(p1) if finite(p1) else -1, kin, clock)
    if reply is None:
        return MAV_RESULT_FAILED
    out.reply.append(reply)
    return MAV_RESULT_ACCEPTED


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

"""Which messages from another ground station take a vehicle's flight out of our hands.

A GCS beside the service (QGroundControl, MAVProxy) may read anything — parameters, streams,
the mission — without touching the run; but a mode change, a course, a position or speed
target, a mission jump, an arm or disarm, manual control: the vehicle then flies what that
GCS told it, and the service must not fight it (``vehicle_taken_over``).  Pure: a message in,
the vehicle it takes over (or None) out.
"""

from __future__ import annotations

from gcs_ppf.mavlink import enums
from gcs_ppf.mavlink.codec import MAVLinkMessage

FLIGHT_COMMANDS = frozenset(
    {
        enums.MAV_CMD_DO_SET_MODE,
        enums.MAV_CMD_DO_REPOSITION,
        enums.MAV_CMD_DO_CHANGE_SPEED,
        enums.MAV_CMD_DO_SET_MISSION_CURRENT,
        enums.MAV_CMD_DO_JUMP,
        enums.MAV_CMD_GUIDED_CHANGE_ALTITUDE,
        enums.MAV_CMD_GUIDED_CHANGE_HEADING,
        enums.MAV_CMD_GUIDED_CHANGE_SPEED,
        enums.MAV_CMD_MISSION_START,
        enums.MAV_CMD_NAV_LAND,
        enums.MAV_CMD_NAV_LOITER_TIME,
        enums.MAV_CMD_NAV_LOITER_TURNS,
        enums.MAV_CMD_NAV_LOITER_UNLIM,
        enums.MAV_CMD_NAV_RETURN_TO_LAUNCH,
        enums.MAV_CMD_NAV_TAKEOFF,
        enums.MAV_CMD_NAV_WAYPOINT,
        enums.MAV_CMD_COMPONENT_ARM_DISARM,
        enums.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN,
    }
)
"""COMMAND_LONG / COMMAND_INT commands that change what the vehicle flies."""

FLIGHT_MESSAGES = frozenset(
    {
        "SET_MODE",
        "SET_POSITION_TARGET_GLOBAL_INT",
        "SET_POSITION_TARGET_LOCAL_NED",
        "SET_ATTITUDE_TARGET",
        "MISSION_SET_CURRENT",
        "MANUAL_CONTROL",
        "RC_CHANNELS_OVERRIDE",
    }
)
"""Messages that do so by themselves."""


def taken_over(msg: MAVLinkMessage) -> int | None:
    """The system id of the vehicle ``msg`` takes over, None if it takes over none (reads,
    parameter and stream requests, heartbeats, or a broadcast to system 0)."""
    kind = msg.get_type()
    if kind in ("COMMAND_LONG", "COMMAND_INT"):
        if int(msg.command) not in FLIGHT_COMMANDS:
            return None
    elif kind not in FLIGHT_MESSAGES:
        return None
    target = int(getattr(msg, "target_system", 0))
    return target or None

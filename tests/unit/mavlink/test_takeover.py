"""Which frames of another ground station take a vehicle's flight (``mavlink.takeover``)."""

from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_ppf.mavlink import commands
from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.mavlink.codec import MAVLinkMessage
from gcs_ppf.mavlink.takeover import taken_over


def command(cmd: int, target: int = 3) -> MAVLinkMessage:
    return mavlink2.MAVLink_command_long_message(target, 1, cmd, 0, 0, 0, 0, 0, 0, 0, 0)


@pytest.mark.parametrize(
    "msg",
    [
        commands.set_mode(3, PlaneMode.LOITER),
        command(mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH),
        command(mavlink2.MAV_CMD_GUIDED_CHANGE_HEADING),
        command(mavlink2.MAV_CMD_COMPONENT_ARM_DISARM),
        mavlink2.MAVLink_set_mode_message(3, 1, 10),
        mavlink2.MAVLink_mission_set_current_message(3, 1, 2),
        mavlink2.MAVLink_rc_channels_override_message(3, 1, *([1500] * 8)),
    ],
)
def test_commands_of_flight_take_the_vehicle(msg: MAVLinkMessage) -> None:
    assert taken_over(msg) == 3


@pytest.mark.parametrize(
    "msg",
    [
        command(mavlink2.MAV_CMD_REQUEST_MESSAGE),
        command(mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL),
        command(mavlink2.MAV_CMD_DO_SET_MODE, target=0),  # every vehicle: none in particular
        mavlink2.MAVLink_param_request_read_message(3, 1, b"TECS_CLMB_MAX", -1),
        mavlink2.MAVLink_param_request_list_message(3, 1),
        mavlink2.MAVLink_mission_request_list_message(3, 1, 0),
        mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3),
    ],
)
def test_reads_and_requests_take_nothing(msg: MAVLinkMessage) -> None:
    assert taken_over(msg) is None

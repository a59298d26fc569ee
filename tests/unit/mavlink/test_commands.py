"""Golden bytes of every command builder, and the fields a fresh pymavlink parser reads back.

The bytes were computed once (system 255, component 190, seq 7) and checked by decoding them
with pymavlink; they are locked here so that no refactoring changes what goes on the wire.
"""

from __future__ import annotations

import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_ppf.mavlink import commands, enums
from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.mavlink.codec import Codec, MAVLinkMessage

GOLDEN: list[tuple[str, MAVLinkMessage, str, dict[str, Any]]] = [
    (
        "gcs_heartbeat",
        commands.gcs_heartbeat(),
        "fd09000007ffbe0000000000000006080004037efa",
        {"type": 6, "autopilot": 8, "base_mode": 0, "custom_mode": 0, "system_status": 4},
    ),
    (
        "set_mode_guided",
        commands.set_mode(3, PlaneMode.GUIDED),
        "fd20000007ffbe4c00000000803f000070410000000000000000000000000000000000000000b0000301fe57",
        {"target_system": 3, "target_component": 1, "command": 176, "param1": 1.0, "param2": 15.0},
    ),
    (
        "arm",
        commands.arm(3, True),
        "fd20000007ffbe4c00000000803f00000000000000000000000000000000000000000000000090010301bd07",
        {"command": 400, "param1": 1.0, "param2": 0.0},
    ),
    (
        "disarm_force",
        commands.arm(3, False, force=True),
        "fd20000007ffbe4c0000000000000098a5460000000000000000000000000000000000000000900103019fa3",
        {"command": 400, "param1": 0.0, "param2": 21196.0},
    ),
    (
        "reposition",
        commands.reposition(3, 47.397742, 8.545594, 788.5, loiter_radius_m=80.0),
        "fd20000007ffbe4b0000000080bf0000803f0000a0420000c07f4c52401c44f4170500204544c0000301c42d",
        {
            "target_system": 3,
            "target_component": 1,
            "frame": 0,
            "command": 192,
            "current": 0,
            "autocontinue": 0,
            "param1": -1.0,
            "param2": 1.0,
            "param3": 80.0,
            "x": 473977420,
            "y": 85455940,
            "z": 788.5,
        },
    ),
    (
        "change_speed",
        commands.change_speed(3, 22.5),
        "fd20000007ffbe4c0000000000000000b441000080bf00000000000000000000000000000000b20003013ea5",
        {"command": 178, "param1": 0.0, "param2": 22.5, "param3": -1.0, "param4": 0.0},
    ),
    (
        "guided_change_heading",
        commands.guided_change_heading(3, 271.5, 52.0),
        "fd20000007ffbe4b00000000000000c087430000504200000000000000000000000000000000faa70301c1f4",
        {"command": 43002, "frame": 0, "param1": 0.0, "param2": 271.5, "param3": 52.0},
    ),
    (
        "guided_change_altitude",
        commands.guided_change_altitude(3, 1288.25, 7.5),
        "fd20000007ffbe4b000000000000000000000000f0400000000000000000000000000008a144f9a70301afe2",
        {"command": 43001, "frame": 0, "param3": 7.5, "z": 1288.25},
    ),
    (
        "set_message_interval",
        commands.set_message_interval(3, 33, 100_000),
        "fd20000007ffbe4c0000000004420050c3470000000000000000000000000000000000000000ff010301b226",
        {"command": 511, "param1": 33.0, "param2": 100_000.0, "param7": 0.0},
    ),
    (
        "request_data_streams",
        commands.request_data_streams(3, 10),
        "fd06000007ffbe4200000a00030100019359",
        {
            "target_system": 3,
            "target_component": 1,
            "req_stream_id": 0,
            "req_message_rate": 10,
            "start_stop": 1,
        },
    ),
    (
        "set_param",
        commands.set_param(3, "TKOFF_ALT", 60.0),
        "fd17000007ffbe170000000070420301544b4f46465f414c5400000000000000094c61",
        {"param_id": "TKOFF_ALT", "param_value": 60.0, "param_type": 9},
    ),
]


def _decode(frame: bytes) -> Any:
    parser = mavlink2.MAVLink(None)
    msgs = parser.parse_buffer(frame)
    assert msgs is not None
    assert len(msgs) == 1
    return msgs[0]


@pytest.mark.parametrize(
    ("msg", "golden", "fields"), [g[1:] for g in GOLDEN], ids=[g[0] for g in GOLDEN]
)
def test_golden_bytes_and_fields(msg: MAVLinkMessage, golden: str, fields: dict[str, Any]) -> None:
    codec = Codec(255, 190)
    codec.seq = 7
    frame = codec.encode(msg)
    decoded = _decode(frame)
    assert decoded.get_srcSystem() == 255
    assert decoded.get_srcComponent() == 190
    assert decoded.get_seq() == 7
    for name, value in fields.items():
        assert getattr(decoded, name) == value, name
    assert frame.hex() == golden


def test_reposition_yaw_is_nan_and_flags_follow_change_mode() -> None:
    decoded = _decode(Codec().encode(commands.reposition(1, 0.0, 0.0, 100.0)))
    assert math.isnan(decoded.param4)
    assert decoded.param2 == 1.0
    assert decoded.param3 == 0.0
    no_change = _decode(Codec().encode(commands.reposition(1, 0.0, 0.0, 100.0, change_mode=False)))
    assert no_change.param2 == 0.0


def test_reposition_rounds_to_the_nearest_1e7_degree() -> None:
    decoded = _decode(Codec().encode(commands.reposition(1, -33.86785, 151.20732, 10.0)))
    assert decoded.x == -338678500
    assert decoded.y == 1512073200


def test_guided_change_heading_wraps_the_course_into_0_360() -> None:
    for course, sent in ((-90.0, 270.0), (360.0, 0.0), (725.0, 5.0), (-1e-9, 0.0)):
        decoded = _decode(Codec().encode(commands.guided_change_heading(1, course, 10.0)))
        assert 0.0 <= decoded.param2 < 360.0
        assert decoded.param2 == pytest.approx(sent, abs=1e-6)


def test_request_data_streams_zero_rate_stops_the_stream() -> None:
    msg = commands.request_data_streams(2, 0, enums.MAV_DATA_STREAM_POSITION)
    assert (msg.req_stream_id, msg.req_message_rate, msg.start_stop) == (6, 0, 0)


def test_takeoff_is_param_mode_then_arm() -> None:
    param, mode, arm = commands.takeoff(4, 75.0)
    assert param.get_type() == "PARAM_SET"
    assert param.param_id == "TKOFF_ALT"
    assert param.param_value == 75.0
    assert (mode.command, mode.param2) == (176, 13.0)
    assert (arm.command, arm.param1) == (400, 1.0)
    assert {m.target_system for m in (param, mode, arm)} == {4}


@pytest.mark.parametrize(
    "build",
    [
        lambda: commands.reposition(1, 91.0, 0.0, 100.0),
        lambda: commands.reposition(1, 0.0, 181.0, 100.0),
        lambda: commands.reposition(1, 0.0, 0.0, math.nan),
        lambda: commands.reposition(1, 0.0, 0.0, 100.0, loiter_radius_m=-1.0),
        lambda: commands.reposition(0, 0.0, 0.0, 100.0),
        lambda: commands.change_speed(1, 0.0),
        lambda: commands.guided_change_heading(1, math.nan, 10.0),
        lambda: commands.guided_change_heading(1, 90.0, 0.0),
        lambda: commands.guided_change_altitude(1, 0.0, 5.0),
        lambda: commands.guided_change_altitude(1, -1.0, 5.0),
        lambda: commands.guided_change_altitude(1, 500.0, -5.0),
        lambda: commands.change_speed(1, math.inf),
        lambda: commands.set_message_interval(1, 33, -2),
        lambda: commands.request_data_streams(1, 70_000),
        lambda: commands.set_param(1, "A_NAME_LONGER_THAN_16", 1.0),
        lambda: commands.takeoff(1, 0.0),
        lambda: commands.set_mode(256, PlaneMode.GUIDED),
    ],
)
def test_bad_arguments_raise_value_error(build: Any) -> None:
    with pytest.raises(ValueError, match=r"\w"):
        build()


def test_builders_are_pure() -> None:
    a = Codec().encode(commands.reposition(5, 1.0, 2.0, 3.0))
    b = Codec().encode(commands.reposition(5, 1.0, 2.0, 3.0))
    assert a == b

"""Unit tests of the pure SITL modules: mission protocol, parameters, streams, modes,
message builders (golden bytes), faults."""

from __future__ import annotations

import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from gcs_ppf.mavlink import enums
from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.mission import Limits
from sitl import messages as mb
from sitl import mission_protocol as mp
from sitl.faults import FaultState, parse_fault
from sitl.modes import base_mode, mode_from_number
from sitl.params import ParamTable, ParamType, vehicle_param_specs
from sitl.streams import GLOBAL_POSITION_INT, HEARTBEAT, StreamSchedule

GCS = (255, 190)
HOME = mp.MissionItem(0, 16, 0, 1, 0, 0, 0, 0, 473977420, 85455940, 488.0)


def wp(
    lat_e7: int = 474000000, lon_e7: int = 85500000, z: float = 300.0, cmd: int = 16
) -> mp.MissionItem:
    return mp.MissionItem(3, cmd, 0, 1, 0.0, 0.0, 0.0, 0.0, lat_e7, lon_e7, z)


def upload(server: mp.MissionServer, items: list[mp.MissionItem]) -> list[Any]:
    res = server.on_count(GCS, len(items), 0, 0.0)
    assert res.replies[0].get_type() == "MISSION_REQUEST_INT"
    for seq, item in enumerate(items):
        res = server.on_item(GCS, seq, item, 0, 0.1)
    return res.replies


# ---- mission protocol -----------------------------------------------------------------------
def test_upload_then_download_round_trip() -> None:
    server = mp.MissionServer()
    items = [HOME, wp(), wp(474100000, 85600000, 250.0), wp(cmd=20)]
    replies = upload(server, items)
    assert replies[-1].get_type() == "MISSION_ACK"
    assert replies[-1].type == enums.MAV_MISSION_ACCEPTED
    assert server.on_request_list(GCS, 0).replies[0].count == 4
    for seq in range(1, 4):
        got = server.on_request(GCS, seq, 0, HOME, as_int=True).replies[0]
        assert (got.seq, got.command, got.x, got.y, got.z) == (
            seq, items[seq].command, items[seq].x, items[seq].y, items[seq].z,
        )  # fmt: skip
    home = server.on_request(GCS, 0, 0, HOME, as_int=True).replies[0]
    assert (home.x, home.y) == (HOME.x, HOME.y)


def test_requests_each_item_in_order_and_rejects_out_of_sequence() -> None:
    server = mp.MissionServer()
    res = server.on_count(GCS, 3, 0, 0.0)
    assert res.replies[0].seq == 0
    res = server.on_item(GCS, 0, HOME, 0, 0.0)
    assert res.replies[0].seq == 1
    res = server.on_item(GCS, 999, wp(), 0, 0.0)  # sequence 999: error, upload goes on
    assert res.replies[0].type == enums.MAV_MISSION_INVALID_SEQUENCE
    assert server.state == mp.Transfer.RECEIVING
    res = server.on_item((7, 1), 1, wp(), 0, 0.0)  # another GCS
    assert res.replies[0].type == enums.MAV_MISSION_DENIED


@pytest.mark.parametrize(
    ("item", "result"),
    [
        (wp(lat_e7=10_000_000_000 // 10), enums.MAV_MISSION_INVALID_PARAM5_X),  # latitude 100°
        (wp(lon_e7=1_900_000_000), enums.MAV_MISSION_INVALID_PARAM6_Y),
        (wp(cmd=31000), enums.MAV_MISSION_UNSUPPORTED),
        (mp.MissionItem(1, 16, 0, 1, 0, 0, 0, 0, 0, 0, 100.0), enums.MAV_MISSION_UNSUPPORTED_FRAME),
        (
            mp.MissionItem(3, 17, 0, 1, math.nan, 0, 0, 0, 0, 0, 100.0),
            enums.MAV_MISSION_INVALID_PARAM1,
        ),
        (wp(z=math.inf), enums.MAV_MISSION_INVALID_PARAM7),
    ],
)
def test_bad_item_ends_upload_with_its_error(item: mp.MissionItem, result: int) -> None:
    server = mp.MissionServer()
    upload(server, [HOME, wp()])
    server.on_count(GCS, 2, 0, 1.0)
    server.on_item(GCS, 0, HOME, 0, 1.0)
    res = server.on_item(GCS, 1, item, 0, 1.0)
    assert res.replies[0].type == result
    assert server.state == mp.Transfer.IDLE
    assert len(server.items) == 2  # the old mission is kept


def test_waypoint_yaw_may_be_nan() -> None:
    item = mp.MissionItem(3, 16, 0, 1, 0, 0, 0, math.nan, 474000000, 85500000, 100.0)
    assert mp.validate_item(item) == enums.MAV_MISSION_ACCEPTED


def test_too_many_items_no_space_and_clear_and_empty_count() -> None:
    server = mp.MissionServer()
    assert (
        server.on_count(GCS, mp.MAX_ITEMS + 1, 0, 0.0).replies[0].type == enums.MAV_MISSION_NO_SPACE
    )
    upload(server, [HOME, wp()])
    res = server.on_clear_all(GCS, 0)
    assert res.mission_changed
    assert server.items == []
    assert server.on_request_list(GCS, 0).replies[0].count == 1  # home only
    res = server.on_count(GCS, 0, 0, 0.0)
    assert res.replies[0].type == enums.MAV_MISSION_ACCEPTED


def test_download_out_of_range_and_fence_rally() -> None:
    server = mp.MissionServer()
    res = server.on_request(GCS, 5, 0, HOME, as_int=True)
    assert [m.get_type() for m in res.replies] == ["MISSION_COUNT", "MISSION_ACK"]
    assert res.replies[1].type == enums.MAV_MISSION_INVALID_SEQUENCE
    assert server.on_request_list(GCS, 1).replies[0].count == 0
    assert server.on_count(GCS, 3, 2, 0.0).replies[0].type == enums.MAV_MISSION_UNSUPPORTED


def test_resend_then_timeout() -> None:
    server = mp.MissionServer()
    server.on_count(GCS, 3, 0, 0.0)
    assert server.tick(0.5).replies == []
    again = server.tick(1.2).replies
    assert again[0].get_type() == "MISSION_REQUEST_INT"
    assert again[0].seq == 0
    cancelled = server.tick(9.0).replies
    assert cancelled[0].type == enums.MAV_MISSION_OPERATION_CANCELLED
    assert server.state == mp.Transfer.IDLE


def test_download_denied_during_upload() -> None:
    server = mp.MissionServer()
    server.on_count(GCS, 3, 0, 0.0)
    assert server.on_request_list(GCS, 0).replies[0].type == enums.MAV_MISSION_DENIED


# ---- parameters -----------------------------------------------------------------------------
def table() -> ParamTable:
    return ParamTable(vehicle_param_specs(3, Limits(), 100.0))


def test_params_defaults_and_types() -> None:
    t = table()
    assert t["SYSID_THISMAV"] == 3
    assert t.spec("SYSID_THISMAV").ptype == ParamType.INT16
    assert t["AIRSPEED_MIN"] == 100.0
    assert t["AIRSPEED_MAX"] == 300.0
    assert t["SIM_YAW_RATE"] == pytest.approx(30.0)
    assert all(len(n) <= 16 for n in t.names())


def test_params_accept_integral_floats_and_refuse_bad_values() -> None:
    t = table()
    assert t.set("FS_GCS_ENABL", 1.0)
    assert t["FS_GCS_ENABL"] == 1
    assert not t.set("FS_GCS_ENABL", 1.5)
    assert not t.set("FS_GCS_ENABL", 7)
    assert not t.set("AIRSPEED_CRUISE", math.nan)
    assert not t.set("NO_SUCH_PARAM", 1)
    assert t["FS_GCS_ENABL"] == 1


# ---- streams, modes, faults ------------------------------------------------------------------
def test_stream_schedule_rates_and_interval_command() -> None:
    s = StreamSchedule.default()
    count = sum(GLOBAL_POSITION_INT in s.due(k * 0.02) for k in range(100))  # 2 s
    assert count == 20  # 10 Hz
    assert s.set_interval_us(GLOBAL_POSITION_INT, 500_000, 2.0)
    count = sum(GLOBAL_POSITION_INT in s.due(2.0 + k * 0.02) for k in range(100))
    assert count == 4  # 2 Hz
    assert s.set_interval_us(GLOBAL_POSITION_INT, -1, 4.0)
    assert s.interval_us(GLOBAL_POSITION_INT) == -1
    assert not s.set_interval_us(12345, 1000, 4.0)
    s.request_data_stream(6, 5, True, 4.0)
    assert s.interval_us(GLOBAL_POSITION_INT) == 200_000
    assert HEARTBEAT in s.due(10.0)


def test_base_mode_like_arduplane() -> None:
    assert base_mode(PlaneMode.MANUAL, False) == 1 | 64
    assert base_mode(PlaneMode.GUIDED, True) == 1 | 8 | 16 | 128
    assert base_mode(PlaneMode.AUTO, True) & 4 == 0  # ArduPlane never sets AUTO_ENABLED
    assert mode_from_number(15.0) == PlaneMode.GUIDED
    assert mode_from_number(99) is None
    assert mode_from_number(PlaneMode.STABILIZE) is None  # ArduPlane's, not flown here
    assert mode_from_number(math.nan) is None
    assert mode_from_number(15.5) is None


def test_fault_spec_parsing() -> None:
    spec = parse_fault("2:loss=10,latency=200,noise=5,cut=30+10,die=120")
    state = FaultState()
    spec.apply(state)
    assert spec.vehicle_id == 2
    assert (state.loss_pct, state.latency_ms, state.noise_m, state.die_at_s) == (10, 200, 5, 120)
    assert state.link_cut(35.0)
    assert not state.link_cut(40.0)
    assert parse_fault("loss=5").vehicle_id is None
    for bad in ["loss=101", "x=1", "2:", "cut=5", "loss=abc"]:
        with pytest.raises(ValueError, match="--fault"):
            parse_fault(bad)


# ---- message builders: golden bytes ------------------------------------------------------------
def test_heartbeat_golden_bytes() -> None:
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    data = mb.heartbeat(PlaneMode.GUIDED, True, 4).pack(mav)
    assert data.hex() == "fd0900000001010000000f00000001039904034761"
    msg = mavlink.MAVLink(None).parse_char(data)
    assert (msg.type, msg.autopilot, msg.custom_mode, msg.base_mode) == (1, 3, 15, 0x99)


def test_global_position_int_golden_bytes_and_units() -> None:
    t = mb.Telemetry(
        123456, 47.397742, 8.545594, 788.0, 300.0, (10.0, -5.0, 1.0), 0.1, 0.05, 1.5,
        0.0, 0.0, 0.0, 100.0, 50, False,
    )  # fmt: skip
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    data = mb.global_position_int(t).pack(mav)
    assert data.hex() == (
        "fd1c000000010121000040e201004c52401c44f4170520060c00e0930400e8030cfe64009221a2d1"
    )
    msg = mavlink.MAVLink(None).parse_char(data)
    assert (msg.lat, msg.lon, msg.alt, msg.relative_alt) == (473977420, 85455940, 788000, 300000)
    assert (msg.vx, msg.vy, msg.vz, msg.hdg) == (1000, -500, 100, round(math.degrees(1.5) * 100))


def test_autopilot_version_has_mission_int_capability() -> None:
    msg = mb.autopilot_version(1)
    assert msg.capabilities & mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    assert msg.capabilities & mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    assert not msg.capabilities & mavlink.MAV_PROTOCOL_CAPABILITY_FTP


def test_ftp_nak_echoes_sequence_and_opcode() -> None:
    req = bytes([7, 0, 3, 15]) + bytes(247)  # seq 7, session 3, opcode 15 (OpenFileRO)
    nak = mb.ftp_nak_file_not_found(req, 255, 190)
    p = bytes(nak.payload)
    assert int.from_bytes(p[0:2], "little") == 8
    assert (p[2], p[3], p[4], p[5], p[12]) == (3, mb.FTP_OP_NAK, 1, 15, mb.FTP_ERR_FILE_NOT_FOUND)

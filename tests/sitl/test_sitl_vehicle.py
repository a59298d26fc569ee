"""In-process tests of a simulated ArduPlane: messages in, behaviour and answers out."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from gcs_ppf.geodesy import enu_to_geodetic
from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.mavlink.enums import HEADING_TYPE_DEFAULT
from gcs_ppf.mission import Mission, load_mission_file
from sitl.__main__ import build_parser
from sitl.autopilot import Outbox
from sitl.engine import ParamOverride, Simulation
from sitl.faults import parse_fault
from tests.conftest import EXAMPLES
from tests.sitl.sitl_helpers import PAPER, SLOW, TWO

GCS = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
ACCEPTED, DENIED, UNSUPPORTED, FAILED = 0, 2, 3, 4


def deliver(sim: Simulation, i: int, msg: Any) -> Outbox:
    """Pack ``msg`` as the GCS would, parse it as the vehicle would, and hand it over."""
    parsed = mavlink.MAVLink(None).parse_char(msg.pack(GCS))
    out = sim.handle(i, parsed, link_s=0.0)
    return out if out is not None else Outbox()


def all_msgs(out: Outbox) -> list[Any]:
    return out.reply + out.broadcast


def ack(out: Outbox, command: int) -> int:
    acks = [m for m in out.reply if m.get_type() == "COMMAND_ACK" and m.command == command]
    assert len(acks) == 1
    return int(acks[0].result)


def cmd_long(sim: Simulation, command: int, *p: float, i: int = 0, target: int = 1) -> int:
    params = [*p, *([0.0] * (7 - len(p)))]
    return ack(
        deliver(sim, i, mavlink.MAVLink_command_long_message(target, 1, command, 0, *params)),
        command,
    )


def reposition(
    sim: Simulation, east: float, north: float, up: float, flags: float = 1, radius: float = 0
) -> int:
    lat, lon, _ = enu_to_geodetic(east, north, 0.0, sim.origin)
    msg = mavlink.MAVLink_command_int_message(
        1, 1, 6, 192, 0, 0, -1, flags, radius, 0, round(lat * 1e7), round(lon * 1e7), up
    )
    return ack(deliver(sim, 0, msg), 192)


def run(sim: Simulation, seconds: float) -> list[Any]:
    msgs: list[Any] = []
    for _ in range(round(seconds / 0.02)):
        for _i, out in sim.step(0.0):
            msgs.extend(all_msgs(out))
    return msgs


def sim_of(path: Any = TWO, **kw: Any) -> Simulation:
    return Simulation(load_mission_file(path), **kw)


def test_spawns_armed_in_manual_at_mission_start_state() -> None:
    sim = sim_of()
    ap = sim.autopilots[0]
    assert ap.mode == PlaneMode.MANUAL
    assert ap.armed
    assert tuple(sim.state.pos_enu_m[0]) == (1500.0, 2000.0, 300.0)
    run(sim, 1.0)
    assert sim.state.pos_enu_m[0, 0] == pytest.approx(1600.0)  # straight on at 100 m/s


def test_an_arduplane_starting_on_the_ground_sits_there_as_arduplane_does() -> None:
    """ArduPlane-scale vehicles whose start lies on the ground start landed, disarmed, at
    rest (ArduPlane never boots flying); one starting higher, and the paper's airframe at
    any height, start flying as the paper's initial state; the flags choose for all."""
    mission = load_mission_file(EXAMPLES / "arduplane_3.json")
    sim = Simulation(mission)
    assert sim.state.landed.all()
    assert not any(ap.armed for ap in sim.autopilots)
    run(sim, 2.0)
    assert np.allclose(sim.state.pos_enu_m, [v.position for v in mission.vehicles])
    doc = json.loads((EXAMPLES / "arduplane_3.json").read_text())
    doc["vehicles"][1]["position"][2] = 120.0
    mixed = Simulation(Mission.model_validate(doc))
    assert mixed.state.landed.tolist() == [True, False, True]
    assert mixed.autopilots[1].armed
    assert not Simulation(mission, ground_start=False).state.landed.any()
    paper = load_mission_file(EXAMPLES / "paper_table3.json")
    assert 0.0 in [v.position[2] for v in paper.vehicles]
    assert not Simulation(paper).state.landed.any()
    assert Simulation(paper, ground_start=True).state.landed.all()
    parser = build_parser()
    assert parser.parse_args(["m.json"]).ground_start is None
    assert parser.parse_args(["m.json", "--ground-start"]).ground_start is True
    assert parser.parse_args(["m.json", "--air-start"]).ground_start is False
    with pytest.raises(SystemExit):
        parser.parse_args(["m.json", "--air-start", "--ground-start"])


def test_reposition_needs_command_int_and_change_mode_flag() -> None:
    sim = sim_of()
    assert reposition(sim, 5000, 2000, 300, flags=0) == FAILED  # MANUAL, no flag
    lat, lon, _ = enu_to_geodetic(5000, 2000, 0, sim.origin)
    assert cmd_long(sim, 192, -1, 1, 0, 0, lat, lon, 300) == UNSUPPORTED
    bad = mavlink.MAVLink_command_int_message(
        1, 1, 6, 192, 0, 0, -1, 1, 0, 0, 1_000 * 10**7 // 10, 0, 300
    )
    assert ack(deliver(sim, 0, bad), 192) == DENIED  # latitude 100°
    assert reposition(sim, 5000, 2000, 400, flags=1, radius=250) == ACCEPTED
    ap = sim.autopilots[0]
    assert ap.mode == PlaneMode.GUIDED
    assert ap.nav.radius_m == 250
    run(sim, 90.0)  # straight for the point 3 km away (ArduPlane L1 loiter), then the circle
    d = math.dist(sim.state.pos_enu_m[0, :2], (5000, 2000))
    assert 200 < d < 320  # circling the point at ≈ 250 m
    assert sim.state.pos_enu_m[0, 2] == pytest.approx(400, abs=5)


def test_guided_goto_by_mission_item_current_2_only_in_guided() -> None:
    sim = sim_of()
    lat, lon, _ = enu_to_geodetic(4000, 4000, 0, sim.origin)
    item = mavlink.MAVLink_mission_item_int_message(
        1, 1, 0, 6, 16, 2, 0, 0, 0, 0, 0, round(lat * 1e7), round(lon * 1e7), 300, 0
    )
    out = deliver(sim, 0, item)
    assert out.reply[0].get_type() == "MISSION_ACK"
    assert out.reply[0].type == 1
    assert cmd_long(sim, 176, 1, 15) == ACCEPTED
    out = deliver(sim, 0, item)
    assert out.reply[0].type == 0
    assert sim.autopilots[0].nav.pos_enu_m[0] == pytest.approx(4000, abs=0.5)


def test_set_position_target_changes_only_altitude() -> None:
    sim = sim_of()
    cmd_long(sim, 176, 1, 15)
    before = sim.autopilots[0].nav.pos_enu_m
    msg = mavlink.MAVLink_set_position_target_global_int_message(
        0, 1, 1, 6, 0, 470000000, 80000000, 450.0, 0, 0, 0, 0, 0, 0, 0, 0
    )
    deliver(sim, 0, msg)
    after = sim.autopilots[0].nav.pos_enu_m
    assert after[:2] == before[:2]
    assert after[2] == pytest.approx(450.0, abs=1.0)


def test_change_speed_rules() -> None:
    sim = sim_of()
    assert cmd_long(sim, 178, 0, 150) == FAILED  # MANUAL
    cmd_long(sim, 176, 1, 15)
    assert cmd_long(sim, 178, 0, -5) == FAILED
    assert cmd_long(sim, 178, 0, 999) == FAILED  # above AIRSPEED_MAX
    assert cmd_long(sim, 178, 0, 150) == ACCEPTED
    run(sim, 8.0)
    assert sim.state.speed_m_s[0] == pytest.approx(150, abs=1.0)


def slew(sim: Simulation, command: int, *p: float, z: float = 0.0, frame: int = 0) -> int:
    """A MAV_CMD_GUIDED_CHANGE_* command as COMMAND_INT (param1..3, z) to vehicle 0."""
    params = [*p, *([0.0] * (4 - len(p)))]
    msg = mavlink.MAVLink_command_int_message(1, 1, frame, command, 0, 0, *params, 0, 0, z)
    return ack(deliver(sim, 0, msg), command)


HEADING, ALTITUDE, SPEED = 43002, 43001, 43000


def test_guided_change_heading_holds_a_course_until_cancelled() -> None:
    sim = sim_of()  # vehicle 0 flies east at 100 m/s
    ap = sim.autopilots[0]
    assert slew(sim, HEADING, 0, 0.0, 50.0) == FAILED  # MANUAL
    cmd_long(sim, 176, 1, 15)
    assert cmd_long(sim, HEADING, 0, 0.0, 50.0) == UNSUPPORTED  # COMMAND_INT only
    assert slew(sim, HEADING, 0, 360.0, 50.0) == DENIED
    assert slew(sim, HEADING, 3, 0.0, 50.0) == DENIED  # no such heading type
    assert slew(sim, HEADING, 0, 0.0, 5.0) == ACCEPTED  # north, 5 m/s² of lateral acceleration
    yaw0 = float(sim.state.yaw_rad[0])
    run(sim, 2.0)
    assert abs(float(sim.state.yaw_rad[0]) - yaw0) <= 0.05 * 2.0 + 1e-6  # a/v = 0.05 rad/s
    assert slew(sim, HEADING, 0, 0.0, 100.0) == ACCEPTED
    run(sim, 30.0)
    assert float(sim.state.yaw_rad[0]) == pytest.approx(math.pi / 2, abs=0.01)  # held
    assert slew(sim, HEADING, HEADING_TYPE_DEFAULT, 0.0, 0.0) == ACCEPTED  # cancel
    assert ap.guided_course is None
    assert slew(sim, HEADING, 1, 270.0, 100.0) == ACCEPTED  # west
    run(sim, 10.0)
    assert abs(math.remainder(float(sim.state.yaw_rad[0]) - math.pi, math.tau)) < 0.01
    assert reposition(sim, 5000, 2000, 300) == ACCEPTED  # a guided point replaces the course
    assert ap.guided_course is None
    assert slew(sim, HEADING, 0, 90.0, 100.0) == ACCEPTED
    assert cmd_long(sim, 176, 1, 12) == ACCEPTED  # LOITER
    assert ap.guided_course is None


def test_guided_asked_again_keeps_its_guided_point_and_speed_as_arduplane_does() -> None:
    """``Plane::set_mode``: "don't switch modes if we are already in the correct mode". A
    vehicle sent to a loiter point (DO_REPOSITION switches to GUIDED) and then told GUIDED
    again keeps the point and the speed, rather than loitering where it is."""
    sim = sim_of()
    ap = sim.autopilots[0]
    assert reposition(sim, 5000, 2000, 300) == ACCEPTED
    assert cmd_long(sim, 178, 0, 120.0, -1) == ACCEPTED  # DO_CHANGE_SPEED
    nav, speed = ap.nav, ap.new_airspeed_m_s
    assert ap.mode == PlaneMode.GUIDED
    assert speed is not None
    assert cmd_long(sim, 176, 1, 15) == ACCEPTED  # GUIDED again
    assert ap.nav == nav
    assert ap.new_airspeed_m_s == speed
    assert cmd_long(sim, 176, 1, 11) == ACCEPTED  # RTL: a new mode is entered
    assert ap.nav != nav


def test_heading_type_default_cancels_the_course_and_4_is_no_heading_type() -> None:
    """ArduPlane's ``handle_command_int_guided_slew_commands`` switches on MAVLink's
    HEADING_TYPE: HEADING_TYPE_DEFAULT (2 in the dialect) cancels the course
    (GUIDED_HEADING_NONE); a type the enum does not have, 4 among them, is DENIED."""
    assert HEADING_TYPE_DEFAULT == mavlink.HEADING_TYPE_DEFAULT == 2
    sim = sim_of()
    ap = sim.autopilots[0]
    cmd_long(sim, 176, 1, 15)  # GUIDED
    assert slew(sim, HEADING, 0, 0.0, 50.0) == ACCEPTED
    held = ap.guided_course
    assert held is not None
    assert slew(sim, HEADING, 4, 0.0, 0.0) == DENIED
    assert ap.guided_course == held  # a refused command changes nothing
    assert slew(sim, HEADING, HEADING_TYPE_DEFAULT, 0.0, 0.0) == ACCEPTED
    assert ap.guided_course is None


def test_guided_change_altitude_slews_from_here_or_climbs_as_fast_as_it_can() -> None:
    """ArduPlane's param3: > 0 keeps the demand within param3 × 0.1 s of the current
    altitude (it barely climbs: trace 06), 0 climbs as TECS can (trace 04)."""
    sim = sim_of()  # vehicle 0 at 300 m ICS; origin altitude 488 m AMSL
    ap = sim.autopilots[0]
    assert slew(sim, ALTITUDE, 0, 0, 5.0, z=800.0) == FAILED  # MANUAL
    cmd_long(sim, 176, 1, 15)
    assert slew(sim, ALTITUDE, 0, 0, 5.0, z=0.0) == DENIED  # 0 and −1 are refused
    assert slew(sim, ALTITUDE, 0, 0, 5.0, z=-1.0) == DENIED
    assert slew(sim, ALTITUDE, 0, 0, 5.0, z=800.0, frame=1) == DENIED  # MAV_FRAME_LOCAL_NED
    assert slew(sim, ALTITUDE, 0, 0, 5.0, z=488.0 + 500.0) == ACCEPTED  # 500 m ICS, AMSL
    run(sim, 10.0)
    # far less than the 5 m/s × 10 s asked (the paper airframe's height loop is 5× faster
    # than ArduPlane's, so more than ArduPlane's ~0.07 m/s)
    assert 300.2 <= sim.state.pos_enu_m[0, 2] <= 300.0 + 0.2 * 5.0 * 10.0
    assert slew(sim, ALTITUDE, 0, 0, 0.0, z=488.0 + 500.0) == ACCEPTED
    run(sim, 4.0)
    assert sim.state.pos_enu_m[0, 2] > 310.0
    assert reposition(sim, 5000, 2000, 300) == ACCEPTED  # the altitude target stays
    run(sim, 80.0)
    assert sim.state.pos_enu_m[0, 2] == pytest.approx(500.0, abs=3.0)
    assert slew(sim, ALTITUDE, 0, 0, 0.0, z=400.0, frame=3) == ACCEPTED  # above home
    assert ap.guided_altitude is not None  # (ICS z is below the altitude by the curvature)
    assert ap.guided_altitude.z_m == pytest.approx(400.0 + ap.home_enu_m[2], abs=2.0)
    assert ap.guided_altitude.rate_m_s == 1000.0  # 0: as fast as it can


def test_guided_change_speed_rules() -> None:
    sim = sim_of()
    assert slew(sim, SPEED, 0, 150.0) == FAILED  # MANUAL
    cmd_long(sim, 176, 1, 15)
    assert slew(sim, SPEED, 1, 150.0) == DENIED  # ground speed: not supported
    assert slew(sim, SPEED, 0, 999.0) == FAILED  # above AIRSPEED_MAX
    assert slew(sim, SPEED, 0, 150.0, 2.0) == ACCEPTED
    run(sim, 8.0)
    assert sim.state.speed_m_s[0] == pytest.approx(150, abs=1.0)


def test_modes_arming_and_unknown_commands() -> None:
    sim = sim_of()
    assert cmd_long(sim, 176, 1, 99) == FAILED
    assert cmd_long(sim, 176, 0, 15) == UNSUPPORTED  # no custom-mode flag
    assert cmd_long(sim, 400, 0) == FAILED  # no disarm in flight
    assert cmd_long(sim, 400, 0, 21196) == ACCEPTED  # forced
    assert not sim.autopilots[0].armed
    assert cmd_long(sim, 400, 1) == ACCEPTED
    assert cmd_long(sim, 400, 2) == UNSUPPORTED
    assert cmd_long(sim, 31337) == UNSUPPORTED
    assert cmd_long(sim, 176, 1, 11) == ACCEPTED
    assert sim.autopilots[0].mode == PlaneMode.RTL


def test_messages_for_other_systems_are_ignored() -> None:
    sim = sim_of()
    msg = mavlink.MAVLink_command_long_message(2, 1, 176, 0, 1, 15, 0, 0, 0, 0, 0)
    assert sim.handle(0, mavlink.MAVLink(None).parse_char(msg.pack(GCS)), 0.0) is None
    assert sim.autopilots[0].mode == PlaneMode.MANUAL
    assert cmd_long(sim, 176, 1, 15, i=1, target=2) == ACCEPTED
    assert sim.autopilots[1].mode == PlaneMode.GUIDED


def test_auto_mission_reaches_items_in_order_then_rtl() -> None:
    sim = sim_of(SLOW)
    items = [(0, 0), (400, 0), (400, 400)]
    deliver(sim, 0, mavlink.MAVLink_mission_count_message(1, 1, len(items), 0))
    for seq, (e, n) in enumerate(items):
        lat, lon, _ = enu_to_geodetic(e, n, 0, sim.origin)
        x, y = round(lat * 1e7), round(lon * 1e7)
        msg = mavlink.MAVLink_mission_item_int_message(
            1, 1, seq, 3, 16, 0, 1, 0, 0, 0, 0, x, y, 120.0, 0
        )
        deliver(sim, 0, msg)
    assert cmd_long(sim, 300) == ACCEPTED
    msgs = run(sim, 120.0)
    reached = [m.seq for m in msgs if m.get_type() == "MISSION_ITEM_REACHED"]
    assert reached == [1, 2]
    texts = [m.text for m in msgs if m.get_type() == "STATUSTEXT"]
    assert any("Mission complete" in t for t in texts)
    assert sim.autopilots[0].mode == PlaneMode.RTL


def test_gcs_failsafe_rtl_with_statustext() -> None:
    sim = sim_of(params=[ParamOverride(None, "FS_GCS_ENABL", 1)])
    cmd_long(sim, 176, 1, 15)
    deliver(sim, 0, mavlink.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3))
    msgs = run(sim, 4.0)
    mode_before = sim.autopilots[0].mode
    msgs = run(sim, 2.0)
    assert mode_before == PlaneMode.GUIDED
    assert sim.autopilots[0].mode == PlaneMode.RTL
    assert any(m.get_type() == "STATUSTEXT" and "Failsafe" in m.text for m in msgs)
    assert sim.autopilots[1].mode == PlaneMode.MANUAL  # never heard a GCS: no failsafe


def test_sim_params_change_envelope_and_kill() -> None:
    sim = sim_of()
    out = deliver(sim, 0, mavlink.MAVLink_param_set_message(1, 1, b"SIM_YAW_RATE", 10.0, 9))
    assert out.broadcast[0].get_type() == "PARAM_VALUE"
    assert out.broadcast[0].param_value == 10.0
    assert sim.env.max_yaw_rate_rad_s[0] == pytest.approx(math.radians(10))
    out = deliver(sim, 0, mavlink.MAVLink_param_set_message(1, 1, b"SIM_YAW_RATE", -3.0, 9))
    assert out.reply[0].param_value == 10.0  # refused: unchanged value
    deliver(sim, 0, mavlink.MAVLink_param_set_message(1, 1, b"SIM_KILL", 1.0, 2))
    assert sim.autopilots[0].faults.dead
    msgs = run(sim, 2.0)
    assert sim.handle(0, mavlink.MAVLink(None).parse_char(
        mavlink.MAVLink_param_request_list_message(1, 1).pack(GCS)), 0.0) is None  # fmt: skip
    assert not sim.autopilots[0].thrust
    assert len(msgs) > 0  # vehicle 2 still talks


def test_same_seed_same_noisy_telemetry() -> None:
    def positions(seed: int) -> list[tuple[int, int, int]]:
        sim = sim_of(PAPER, seed=seed, faults=[parse_fault("noise=5")],
                     params=[ParamOverride(None, "INITIAL_MODE", 12)])  # fmt: skip
        msgs = run(sim, 20.0)
        return [
            (m.time_boot_ms, m.lat, m.lon) for m in msgs if m.get_type() == "GLOBAL_POSITION_INT"
        ]

    a, b, c = positions(7), positions(7), positions(8)
    assert a == b
    assert a != c
    assert len(a) == 5 * 201  # 10 Hz over 20 s, both ends included


def test_telemetry_heading_and_attitude_conventions() -> None:
    sim = sim_of()
    msgs = run(sim, 0.2)
    gpi = next(m for m in msgs if m.get_type() == "GLOBAL_POSITION_INT")
    att = next(m for m in msgs if m.get_type() == "ATTITUDE")
    assert gpi.hdg == 9000  # yaw 0 (east) is heading 90°
    assert att.yaw == pytest.approx(math.pi / 2)
    assert gpi.vy == 10000
    assert gpi.vx == 0
    assert np.isclose(gpi.relative_alt / 1000, 300, atol=1)


def _random_value(ftype: str, length: int, rng: np.random.Generator) -> Any:
    def one() -> Any:
        if ftype == "float":
            return float(
                rng.choice([0.0, 1.0, -1.0, 1e9, -1e9, math.nan, math.inf, rng.normal() * 1e3])
            )
        if ftype == "double":
            return float(rng.normal() * 1e6)
        if ftype == "char":
            return bytes(rng.integers(32, 127, size=length).astype(np.uint8))
        bits = int("".join(ch for ch in ftype if ch.isdigit()))
        if ftype.startswith("u"):
            return int(rng.integers(0, 2**bits, dtype=np.uint64))
        return int(rng.integers(-(2 ** (bits - 1)), 2 ** (bits - 1)))

    if ftype == "char":
        return one()
    return [one() for _ in range(length)] if length else one()


def test_random_field_values_of_every_handled_message_never_crash() -> None:
    from sitl.handlers import HANDLERS

    rng = np.random.default_rng(11)
    sim = sim_of()
    for name in HANDLERS:
        cls = getattr(mavlink, f"MAVLink_{name.lower()}_message")
        for _ in range(60):
            lengths = dict(zip(cls.ordered_fieldnames, cls.array_lengths, strict=True))
            fields = {
                f: _random_value(t, lengths[f], rng)
                for f, t in zip(cls.fieldnames, cls.fieldtypes, strict=True)
            }
            if "target_system" in fields and rng.random() < 0.8:
                fields["target_system"] = 1
            if "command" in fields and name.startswith("COMMAND") and rng.random() < 0.8:
                fields["command"] = int(rng.choice([176, 178, 192, 300, 400, 511, 512, 224, 246]))
            msg = cls(**fields)
            deliver(sim, 0, msg)
            run(sim, 0.02)
    before = sim.state.pos_enu_m[0].copy()
    run(sim, 2.0)
    assert np.all(np.isfinite(sim.state.pos_enu_m))
    assert not np.array_equal(before, sim.state.pos_enu_m[0])  # still flying
    assert cmd_long(sim, 512, 148) == ACCEPTED  # still answering

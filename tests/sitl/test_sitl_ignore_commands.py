"""The "stuck autopilot" fault: a vehicle that acknowledges commands and does not act on them."""

from __future__ import annotations

import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from gcs_ppf.geodesy import enu_to_geodetic
from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.mission import load_mission_file
from sitl.engine import Simulation
from sitl.faults import FaultState, parse_fault
from tests.sitl.sitl_helpers import TWO, Client, run_sitl
from tests.sitl.test_sitl_vehicle import (
    ACCEPTED,
    DENIED,
    FAILED,
    HEADING,
    ack,
    cmd_long,
    deliver,
    reposition,
    run,
    slew,
)

ALTITUDE, SPEED = 43001, 43000


def sim_with(*faults: str) -> Simulation:
    return Simulation(load_mission_file(TWO), faults=[parse_fault(f) for f in faults])


def yaw(sim: Simulation, i: int = 0) -> float:
    return float(sim.state.yaw_rad[i])


def test_ignore_parses_and_applies_from_its_time() -> None:
    spec = parse_fault("3:ignore=40")
    assert (spec.vehicle_id, spec.ignore_from_s) == (3, 40.0)
    state = FaultState()
    spec.apply(state)
    assert not state.ignoring_commands(39.99)
    assert state.ignoring_commands(40.0)
    assert state.ignoring_commands(1e6)  # for good
    for bad in ["ignore=-1", "ignore=x", "ignore"]:
        with pytest.raises(ValueError, match="--fault"):
            parse_fault(bad)


def test_before_its_time_the_vehicle_obeys() -> None:
    sim = sim_with("1:ignore=5")
    assert cmd_long(sim, 176, 1, 15) == ACCEPTED
    assert sim.autopilots[0].mode == PlaneMode.GUIDED


def test_stuck_vehicle_acks_every_flight_command_and_keeps_flying_its_last_course() -> None:
    """In GUIDED on a course north, then stuck: a course west, an altitude, a speed, a
    guided point, LOITER, RTL, disarm — each ACCEPTED, none acted on; it stays in GUIDED on
    its course north at its altitude and speed."""
    sim = sim_with("1:ignore=2")
    ap = sim.autopilots[0]
    assert cmd_long(sim, 176, 1, 15) == ACCEPTED
    assert slew(sim, HEADING, 0, 0.0, 100.0) == ACCEPTED  # north
    run(sim, 20.0)
    assert yaw(sim) == pytest.approx(math.pi / 2, abs=0.01)
    z0, v0 = float(sim.state.pos_enu_m[0, 2]), float(sim.state.speed_m_s[0])

    assert slew(sim, HEADING, 0, 270.0, 100.0) == ACCEPTED  # west: ignored
    assert slew(sim, HEADING, 0, 360.0, 100.0) == ACCEPTED  # even what it would deny
    assert slew(sim, ALTITUDE, 0, 0, 0, z=900.0, frame=6) == ACCEPTED
    assert slew(sim, SPEED, 0, 250.0) == ACCEPTED
    assert cmd_long(sim, 178, 0, 250) == ACCEPTED  # DO_CHANGE_SPEED
    assert reposition(sim, 1500, -5000, 300) == ACCEPTED
    assert cmd_long(sim, 176, 1, 12) == ACCEPTED  # LOITER
    assert cmd_long(sim, 20) == ACCEPTED  # RTL
    assert cmd_long(sim, 17) == ACCEPTED  # LOITER_UNLIM
    assert cmd_long(sim, 400, 0, 21196) == ACCEPTED  # forced disarm
    out = deliver(sim, 0, mavlink.MAVLink_set_mode_message(1, 1, 12))
    assert ack(out, 11) == ACCEPTED
    lat, lon, _ = enu_to_geodetic(0, 0, 0, sim.origin)
    item = mavlink.MAVLink_mission_item_int_message(
        1, 1, 0, 6, 16, 2, 0, 0, 0, 0, 0, round(lat * 1e7), round(lon * 1e7), 300, 0
    )
    assert deliver(sim, 0, item).reply[0].type == 0  # MAV_MISSION_ACCEPTED
    target = mavlink.MAVLink_set_position_target_global_int_message(
        0, 1, 1, 6, 0, 0, 0, 900.0, 0, 0, 0, 0, 0, 0, 0, 0
    )
    assert not deliver(sim, 0, target).reply

    run(sim, 30.0)
    assert ap.mode == PlaneMode.GUIDED
    assert ap.armed
    assert yaw(sim) == pytest.approx(math.pi / 2, abs=0.01)  # still north
    assert float(sim.state.pos_enu_m[0, 2]) == pytest.approx(z0, abs=1.0)
    assert float(sim.state.speed_m_s[0]) == pytest.approx(v0, abs=1.0)
    hb = ap.heartbeat()
    assert hb.custom_mode == PlaneMode.GUIDED  # its telemetry tells the truth


def test_stuck_in_manual_it_never_enters_guided() -> None:
    """Stuck from the start: the mode change is ACCEPTED, the HEARTBEAT keeps MANUAL and
    the vehicle flies straight on."""
    sim = sim_with("1:ignore=0")
    yaw0 = yaw(sim)
    assert cmd_long(sim, 176, 1, 15) == ACCEPTED
    assert sim.autopilots[0].heartbeat().custom_mode == PlaneMode.MANUAL
    assert slew(sim, HEADING, 0, 0.0, 100.0) == ACCEPTED  # in MANUAL it would be FAILED
    run(sim, 10.0)
    assert yaw(sim) == pytest.approx(yaw0, abs=1e-6)


def test_other_vehicles_and_other_messages_are_unaffected() -> None:
    sim = sim_with("1:ignore=0")
    assert cmd_long(sim, 176, 1, 15, i=1, target=2) == ACCEPTED  # vehicle 2 obeys
    assert sim.autopilots[1].mode == PlaneMode.GUIDED
    assert slew_to(sim, 1, 2, 0.0) == ACCEPTED
    # Requests and parameters still work on the stuck vehicle.
    assert cmd_long(sim, 511, 33, 200_000) == ACCEPTED
    assert cmd_long(sim, 511, 12345, 1) == FAILED
    assert cmd_long(sim, 999) != ACCEPTED  # unknown command: not a flight command
    out = deliver(sim, 0, mavlink.MAVLink_param_set_message(1, 1, b"SIM_YAW_RATE", 10.0, 9))
    assert out.broadcast[0].param_value == 10.0


def slew_to(sim: Simulation, i: int, sysid: int, heading_deg: float) -> int:
    msg = mavlink.MAVLink_command_int_message(
        sysid, 1, 0, HEADING, 0, 0, 0, heading_deg, 100.0, 0, 0, 0, 0
    )
    return ack(deliver(sim, i, msg), HEADING)


def param_set(sim: Simulation, name: bytes, value: float) -> Any:
    return deliver(sim, 0, mavlink.MAVLink_param_set_message(1, 1, name, value, 2))


def test_sim_cmd_ignore_at_run_time_and_back() -> None:
    sim = Simulation(load_mission_file(TWO))
    ap = sim.autopilots[0]
    assert cmd_long(sim, 176, 1, 15) == ACCEPTED
    assert slew(sim, HEADING, 0, 0.0, 100.0) == ACCEPTED  # north
    run(sim, 20.0)
    out = param_set(sim, b"SIM_CMD_IGNORE", 1.0)
    assert out.broadcast[0].param_value == 1.0
    assert ap.faults.ignoring_commands(sim.sim_s)
    assert slew(sim, HEADING, 0, 180.0, 100.0) == ACCEPTED  # south: ignored
    run(sim, 20.0)
    assert yaw(sim) == pytest.approx(math.pi / 2, abs=0.01)
    param_set(sim, b"SIM_CMD_IGNORE", 0.0)
    assert not ap.faults.ignoring_commands(sim.sim_s)
    assert slew(sim, HEADING, 0, 360.0, 100.0) == DENIED  # validated again
    assert slew(sim, HEADING, 0, 180.0, 100.0) == ACCEPTED
    run(sim, 30.0)
    assert yaw(sim) == pytest.approx(-math.pi / 2, abs=0.01)  # south now
    assert param_set(sim, b"SIM_CMD_IGNORE", 2.0).reply[0].param_value == 0.0  # refused


@pytest.mark.realtime  # a `python -m sitl` process
def test_ignore_fault_by_command_line_over_tcp() -> None:
    """``python -m sitl … --fault 1:ignore=0``: over a real link the mode change is
    ACCEPTED and the HEARTBEAT still reports MANUAL."""
    with run_sitl(TWO, "--fault", "1:ignore=0", speedup=10) as sitl, Client(sitl.port(0)) as c:
        assert c.set_mode(1, int(PlaneMode.GUIDED)).result == ACCEPTED
        c.drain()
        modes = {c.wait("HEARTBEAT", lambda m: m.get_srcSystem() == 1).custom_mode
                 for _ in range(3)}  # fmt: skip
        assert modes == {int(PlaneMode.MANUAL)}

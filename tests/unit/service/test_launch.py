"""The launcher against a scripted fake ArduPlane: confirmations, resends, refusals, takeoff."""

from __future__ import annotations

import asyncio
import dataclasses
import time
from collections.abc import Coroutine
from typing import Any

import numpy as np
import pytest

from gcs_ppf.geodesy import enu_to_geodetic, geodetic_to_enu
from gcs_ppf.guidance.holding import path_clearance
from gcs_ppf.mavlink import commands
from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.mavlink.telemetry import ArmingReason, CommandAck, ParamValue, VehicleTelemetry
from gcs_ppf.mission import Mission, Origin, load_mission_file
from gcs_ppf.planning.scene import Obstacles, obstacles_from_mission
from gcs_ppf.service import launch
from gcs_ppf.service.launch import CommandFailed, Retry
from gcs_ppf.service.launch_wait import clear_ahead
from tests.conftest import EXAMPLES

pytestmark = pytest.mark.realtime  # acks and retries in wall time (0.1 s)

FAST = Retry(attempts=3, ack_timeout_s=0.1, state_timeout_s=0.1, climb_timeout_s=1.0,
             poll_s=0.002)  # fmt: skip
ACCEPTED, DENIED, FAILED = 0, 2, 4


class FakePlane:
    """Answers like ArduPlane, a few ms later: COMMAND_ACK, then a HEARTBEAT with the new
    state; PARAM_VALUE for PARAM_SET / PARAM_REQUEST_READ.  ``script[command]`` lists, per
    send, what happens: "ok", "lost" (no ACK), "unshown" (ACCEPTED, state unchanged), or a
    MAV_RESULT number; past its end, "ok"."""

    def __init__(self, sysid: int, height_m: float, armed: bool = False,
                 mode: int = PlaneMode.MANUAL, climbs: bool = True) -> None:  # fmt: skip
        self.t = VehicleTelemetry(sysid, 1, custom_mode=int(mode), armed=armed,
                                  relative_alt_m=height_m, groundspeed_m_s=0.0)  # fmt: skip
        self.script: dict[int, list[Any]] = {}
        self.sent: list[Any] = []
        self.climbs = climbs
        self.has_tkoff_alt = True
        self.tkoff_alt_m = 50.0
        self.tkoff_dist_m: float | None = None
        self.heights_at_guided: list[float | None] = []
        self.param_sets_lost = 0  # PARAM_SETs lost, the value before read back instead

    def _later(self, **changes: Any) -> None:
        def apply() -> None:
            self.t = dataclasses.replace(self.t, **changes)

        asyncio.get_running_loop().call_later(0.003, apply)

    def receive(self, msg: Any) -> None:
        self.sent.append(msg)
        kind = msg.get_type()
        if kind in ("PARAM_SET", "PARAM_REQUEST_READ"):
            name = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode()
            name = name.rstrip("\x00")
            if kind == "PARAM_SET" and self.param_sets_lost:
                self.param_sets_lost -= 1
            elif kind == "PARAM_SET" and name == "TKOFF_ALT":
                self.tkoff_alt_m = float(msg.param_value)
            elif kind == "PARAM_SET" and name == "TKOFF_DIST":
                self.tkoff_dist_m = float(msg.param_value)
            if self.has_tkoff_alt:
                now = time.monotonic() + 0.003
                params: tuple[ParamValue, ...] = (ParamValue("TKOFF_ALT", self.tkoff_alt_m, now),)
                if self.tkoff_dist_m is not None:
                    params += (ParamValue("TKOFF_DIST", self.tkoff_dist_m, now),)
                self._later(params=params)
            return
        if kind not in ("COMMAND_LONG", "COMMAND_INT"):
            return
        steps = self.script.get(msg.command, [])
        step = steps.pop(0) if steps else "ok"
        if step == "lost":
            return
        if step == "ack_lost":  # done, but its COMMAND_ACK never arrives
            step = "ok"
            self._apply(msg)
            return
        now = time.monotonic() + 0.003
        result = ACCEPTED if step in ("ok", "unshown") else int(step)
        acks = tuple(a for a in self.t.command_acks if a.command != msg.command)
        self._later(command_acks=(*acks, CommandAck(msg.command, result, now)))
        if step != "ok":
            return
        self._apply(msg)

    def _apply(self, msg: Any) -> None:
        state: dict[str, Any] = {}
        if msg.command == commands.MAV_CMD_DO_SET_MODE:
            state["custom_mode"] = int(msg.param2)
            if int(msg.param2) == PlaneMode.GUIDED:
                self.heights_at_guided.append(self.t.relative_alt_m)
        elif msg.command == commands.MAV_CMD_DO_REPOSITION and int(msg.param2) & 1:
            state["custom_mode"] = int(PlaneMode.GUIDED)  # its change-mode flag
            self.heights_at_guided.append(self.t.relative_alt_m)
        elif msg.command == commands.MAV_CMD_COMPONENT_ARM_DISARM:
            state["armed"] = msg.param1 == 1.0
            if self.t.custom_mode == PlaneMode.TAKEOFF and self.climbs:
                self._climb()
        asyncio.get_running_loop().call_later(
            0.006, lambda: self._later(last_heartbeat_s=time.monotonic() + 0.003, **state)
        )

    def _climb(self) -> None:
        """The takeoff roll (fast, still low), then the climb to 95 % of TKOFF_ALT."""
        loop = asyncio.get_running_loop()
        top = 0.95 * self.tkoff_alt_m
        loop.call_later(0.01, lambda: self._later(groundspeed_m_s=8.0, relative_alt_m=0.5))
        loop.call_later(0.05, lambda: self._later(relative_alt_m=0.5 * top))
        loop.call_later(0.09, lambda: self._later(relative_alt_m=top))


class FakeFleet:
    def __init__(self, *planes: FakePlane) -> None:
        self.planes = {p.t.system_id: p for p in planes}

    def telemetry(self, system_id: int) -> VehicleTelemetry | None:
        plane = self.planes.get(system_id)
        return None if plane is None else plane.t

    async def send(self, system_id: int, msg: Any) -> None:
        self.planes[system_id].receive(msg)


Events = list[tuple[str, int | None, dict[str, Any]]]


def run(coro: Coroutine[Any, Any, Any]) -> Any:
    async def bounded() -> Any:
        async with asyncio.timeout(10.0):
            return await coro

    return asyncio.run(bounded())


def recorder() -> tuple[Events, launch.EventSink]:
    events: Events = []

    def event(kind: str, vehicle_id: int | None = None, **detail: Any) -> None:
        events.append((kind, vehicle_id, detail))

    return events, event


def commands_sent(plane: FakePlane, command: int) -> int:
    return sum(1 for m in plane.sent if m.get_type() == "COMMAND_LONG" and m.command == command)


def test_a_mode_change_is_confirmed_by_the_ack_and_then_the_heartbeat() -> None:
    plane = FakePlane(1, 100.0, armed=True)
    events, event = recorder()
    sends = run(launch.set_mode(FakeFleet(plane), 1, PlaneMode.GUIDED, event, FAST))
    assert sends == 1
    assert plane.t.custom_mode == PlaneMode.GUIDED
    assert events == []


def test_a_lost_ack_is_resent() -> None:
    plane = FakePlane(1, 100.0)
    plane.script[commands.MAV_CMD_COMPONENT_ARM_DISARM] = ["lost", "lost"]
    events, event = recorder()
    assert run(launch.arm(FakeFleet(plane), 1, event, FAST)) == 3
    assert commands_sent(plane, commands.MAV_CMD_COMPONENT_ARM_DISARM) == 3
    assert plane.t.armed
    assert [e[0] for e in events] == ["command_resent", "command_resent"]


def test_a_lost_ack_of_a_command_the_heartbeat_shows_done_confirms_it() -> None:
    plane = FakePlane(1, 100.0)
    plane.script[commands.MAV_CMD_DO_SET_MODE] = ["ack_lost"]
    events, event = recorder()
    assert run(launch.set_mode(FakeFleet(plane), 1, PlaneMode.GUIDED, event, FAST)) == 1
    assert commands_sent(plane, commands.MAV_CMD_DO_SET_MODE) == 1
    assert [e[0] for e in events] == ["command_ack_lost"]


def test_an_accepted_command_the_heartbeat_does_not_show_is_resent() -> None:
    plane = FakePlane(1, 100.0)
    plane.script[commands.MAV_CMD_DO_SET_MODE] = ["unshown"]
    events, event = recorder()
    assert run(launch.set_mode(FakeFleet(plane), 1, PlaneMode.GUIDED, event, FAST)) == 2
    assert "HEARTBEAT" in events[0][2]["after"]


def test_no_ack_at_all_fails_after_the_attempts_with_an_event() -> None:
    plane = FakePlane(1, 100.0)
    plane.script[commands.MAV_CMD_DO_SET_MODE] = ["lost"] * 3
    events, event = recorder()
    with pytest.raises(CommandFailed, match="mode GUIDED"):
        run(launch.set_mode(FakeFleet(plane), 1, PlaneMode.GUIDED, event, FAST))
    assert commands_sent(plane, commands.MAV_CMD_DO_SET_MODE) == 3
    failed = {"command": "mode GUIDED", "result": "no COMMAND_ACK", "attempts": 3}
    assert events[-1] == ("command_failed", 1, failed)


@pytest.mark.parametrize(("result", "name"), [(DENIED, "DENIED"), (FAILED, "FAILED")])
def test_a_refusal_is_final_and_raises_an_event(result: int, name: str) -> None:
    plane = FakePlane(1, 100.0)
    plane.script[commands.MAV_CMD_COMPONENT_ARM_DISARM] = [result]
    events, event = recorder()
    with pytest.raises(CommandFailed) as failed:
        run(launch.arm(FakeFleet(plane), 1, event, FAST))
    assert failed.value.vehicle_id == 1
    assert failed.value.detail["result"] == name
    assert commands_sent(plane, commands.MAV_CMD_COMPONENT_ARM_DISARM) == 1  # not resent
    assert events == [("command_failed", 1, {"command": "arm", "result": name, "attempts": 1})]


def test_a_vehicle_on_the_ground_takes_off_and_goes_guided_only_near_its_tkoff_alt() -> None:
    """Low but already rolling fast (the takeoff roll passes 5 m/s 1.3 s after arming): still
    on the ground; TKOFF_ALT set and read back, TAKEOFF, arm, GUIDED at ≥ 90 % of it."""
    ground = FakePlane(2, 0.2, mode=PlaneMode.MANUAL)
    ground.t = dataclasses.replace(ground.t, groundspeed_m_s=12.0)
    flying = FakePlane(1, 150.0, armed=True, mode=PlaneMode.LOITER)
    events, event = recorder()
    run(launch.launch(FakeFleet(flying, ground), [1, 2], 80.0, event, FAST))
    assert [m.get_type() for m in ground.sent][:1] == ["PARAM_SET"]
    modes = [int(m.param2) for m in ground.sent if getattr(m, "command", None) == 176]
    assert modes == [PlaneMode.TAKEOFF] + [PlaneMode.GUIDED] * launch.STRAIGHT_ON_COPIES
    assert ground.heights_at_guided[0] is not None
    assert ground.heights_at_guided[0] >= 0.9 * 80.0
    assert flying.t.custom_mode == ground.t.custom_mode == PlaneMode.GUIDED
    assert commands_sent(flying, commands.MAV_CMD_COMPONENT_ARM_DISARM) == 0  # armed already
    assert ("takeoff", 2, {"takeoff_alt_m": 80.0}) in events


def test_a_vehicle_whose_height_is_not_known_yet_is_waited_for_then_taken_off() -> None:
    """On a lossy link the first position can come after the launch begins: a vehicle on
    the ground whose height has not been reported yet is not taken for one flying (armed
    in GUIDED on the runway, it stayed there); once reported, it takes off."""
    ground = FakePlane(2, 0.2, mode=PlaneMode.MANUAL)
    ground.t = dataclasses.replace(ground.t, relative_alt_m=None)
    events, event = recorder()

    async def launched() -> None:
        asyncio.get_running_loop().call_later(
            0.2, lambda: setattr(ground, "t", dataclasses.replace(ground.t, relative_alt_m=0.2))
        )
        await launch.launch(FakeFleet(ground), [2], 80.0, event, FAST)

    run(launched())
    modes = [int(m.param2) for m in ground.sent if getattr(m, "command", None) == 176]
    assert modes == [PlaneMode.TAKEOFF] + [PlaneMode.GUIDED] * launch.STRAIGHT_ON_COPIES
    assert ("takeoff", 2, {"takeoff_alt_m": 80.0}) in events


def test_a_vehicle_that_never_reports_its_height_fails_the_launch_untouched(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(launch, "HEIGHT_WAIT_S", 0.3)
    silent = FakePlane(2, 0.2, mode=PlaneMode.MANUAL)
    silent.t = dataclasses.replace(silent.t, relative_alt_m=None)
    _, event = recorder()
    with pytest.raises(launch.CommandFailed, match="no height"):
        run(launch.launch(FakeFleet(silent), [2], 80.0, event, FAST))
    assert silent.sent == []  # neither armed nor switched


def test_a_takeoff_distance_makes_them_climb_out_straight() -> None:
    """TKOFF_DIST set (and read back) before TAKEOFF: ArduPlane then climbs towards a point
    that far ahead rather than circling one 200 m ahead."""
    plane = FakePlane(2, 0.0, mode=PlaneMode.MANUAL)
    events, event = recorder()
    run(launch.launch(FakeFleet(plane), [2], 60.0, event, FAST, takeoff_dist_m=1000.0))
    assert plane.tkoff_dist_m == 1000.0
    assert plane.tkoff_alt_m == 60.0
    sets = [m.param_id for m in plane.sent if m.get_type() == "PARAM_SET"]
    assert [s if isinstance(s, str) else s.decode() for s in sets] == ["TKOFF_ALT", "TKOFF_DIST"]
    assert not [e for e in events if e[0] == "parameter_unanswered"]


def test_the_takeoff_altitude_waited_for_is_the_one_read_back() -> None:
    plane = FakePlane(3, 0.0)
    plane.has_tkoff_alt = False  # answers no PARAM_VALUE: the value sent is waited for
    events, event = recorder()
    assert run(launch.take_off(FakeFleet(plane), 3, 60.0, event, FAST)) == 60.0
    assert ("parameter_unanswered", 3, {"name": "TKOFF_ALT", "sent": 60.0}) in events
    assert sum(1 for m in plane.sent if m.get_type() == "PARAM_REQUEST_READ") == 2


def test_a_vehicle_that_does_not_climb_fails_the_launch() -> None:
    plane = FakePlane(4, 0.0, climbs=False)
    events, event = recorder()
    with pytest.raises(CommandFailed, match="takeoff"):
        run(launch.launch(FakeFleet(plane), [4], 50.0, event, FAST))
    assert events[-1][0] == "takeoff_failed"
    assert plane.heights_at_guided == []  # never switched to GUIDED


def test_one_vehicle_failing_fails_the_launch_with_its_own_error() -> None:
    good = FakePlane(1, 100.0)
    bad = FakePlane(2, 100.0)
    bad.script[commands.MAV_CMD_COMPONENT_ARM_DISARM] = [DENIED]
    _, event = recorder()
    with pytest.raises(CommandFailed) as failed:
        run(launch.launch(FakeFleet(good, bad), [1, 2], 50.0, event, FAST))
    assert failed.value.vehicle_id == 2


def test_a_vehicle_lost_during_the_launch_is_left_out_and_the_others_go_guided() -> None:
    """Wingman 2 goes silent after its ACK (its HEARTBEAT never shows GUIDED) and the
    watchdog finds it lost: its commands stop at once, the run is told, and the launch of
    the others completes instead of failing on it after every resend."""
    good = FakePlane(1, 100.0)
    dead = FakePlane(2, 100.0)
    dead.script[commands.MAV_CMD_DO_SET_MODE] = ["unshown"] * 10
    lost_at = time.monotonic() + 0.05
    told: list[int] = []
    events, event = recorder()
    run(launch.launch(FakeFleet(good, dead), [1, 2], 50.0, event, FAST,
                      is_lost=lambda vid: vid == 2 and time.monotonic() > lost_at,
                      on_lost=told.append))  # fmt: skip
    assert told == [2]
    assert good.t.custom_mode == PlaneMode.GUIDED
    assert not any(kind == "command_failed" for kind, *_ in events)
    assert commands_sent(dead, commands.MAV_CMD_DO_SET_MODE) < FAST.attempts


def test_a_vehicle_failing_and_not_lost_still_fails_the_launch() -> None:
    good = FakePlane(1, 100.0)
    bad = FakePlane(2, 100.0)
    bad.script[commands.MAV_CMD_DO_SET_MODE] = ["unshown"] * 10
    _, event = recorder()
    with pytest.raises(CommandFailed) as failed:
        run(launch.launch(FakeFleet(good, bad), [1, 2], 50.0, event, FAST,
                          is_lost=lambda vid: False, on_lost=lambda vid: None))  # fmt: skip
    assert failed.value.vehicle_id == 2


def not_ready_until(plane: FakePlane, ready_after_s: float, reason: str) -> None:
    """``plane`` reports its pre-arm checks failing (SYS_STATUS) with ``reason`` (STATUSTEXT)
    until ``ready_after_s`` from now, as real ArduPlane does while its EKF settles."""
    now = time.monotonic()
    plane.t = dataclasses.replace(
        plane.t, prearm_ok=False, arming_reasons=(ArmingReason(reason, now),)
    )
    asyncio.get_running_loop().call_later(
        ready_after_s, lambda: plane._later(prearm_ok=True, gps_fix_type=3)
    )


def test_a_vehicle_is_armed_only_once_its_pre_arm_checks_pass() -> None:
    plane = FakePlane(2, 0.0, mode=PlaneMode.MANUAL)
    events, event = recorder()

    async def scenario() -> None:
        not_ready_until(plane, 0.3, "PreArm: AHRS: waiting for home")
        await launch.launch(FakeFleet(plane), [2], 50.0, event, FAST, ready_timeout_s=5.0)

    run(scenario())
    kinds = [k for k, _, _ in events]
    assert kinds.index("prearm_waiting") < kinds.index("prearm_passed") < kinds.index("takeoff")
    waiting = next(d for k, _, d in events if k == "prearm_waiting")
    assert waiting["reasons"] == ["PreArm: AHRS: waiting for home"]
    passed = next(d for k, _, d in events if k == "prearm_passed")
    assert 0.2 <= passed["waited_s"] <= 2.0
    assert commands_sent(plane, commands.MAV_CMD_COMPONENT_ARM_DISARM) == 1
    assert plane.t.custom_mode == PlaneMode.GUIDED


def test_never_ready_fails_naming_the_vehicles_reasons_and_never_arms() -> None:
    plane = FakePlane(2, 0.0, mode=PlaneMode.MANUAL)
    events, event = recorder()

    async def scenario() -> None:
        not_ready_until(plane, 60.0, "PreArm: GPS 1: Bad fix")
        await launch.launch(FakeFleet(plane), [2], 50.0, event, FAST, ready_timeout_s=0.3)

    with pytest.raises(CommandFailed, match=r"pre-arm checks failed.*PreArm: GPS 1: Bad fix"):
        run(scenario())
    assert commands_sent(plane, commands.MAV_CMD_COMPONENT_ARM_DISARM) == 0
    assert events[-1] == (
        "prearm_failed",
        2,
        {"waited_s": 0.3, "reasons": ["PreArm: GPS 1: Bad fix"]},
    )


def test_an_arm_refused_for_a_reason_that_clears_is_tried_again(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(launch, "ARM_RETRY_S", 0.05)
    plane = FakePlane(1, 100.0, mode=PlaneMode.LOITER)  # flying, disarmed: armed in place
    plane.script[commands.MAV_CMD_COMPONENT_ARM_DISARM] = [FAILED, FAILED]

    def refused_with_reason(msg: Any, receive: Any = plane.receive) -> None:
        if getattr(msg, "command", None) == commands.MAV_CMD_COMPONENT_ARM_DISARM:
            reason = ArmingReason("PreArm: Gyros still settling", time.monotonic())
            plane.t = dataclasses.replace(plane.t, arming_reasons=(reason,))
        receive(msg)

    plane.receive = refused_with_reason  # type: ignore[method-assign]
    events, event = recorder()
    run(launch.launch(FakeFleet(plane), [1], 50.0, event, FAST, ready_timeout_s=5.0))
    refusals = [d for k, _, d in events if k == "arm_refused"]
    assert len(refusals) == 2
    assert refusals[0]["result"] == "FAILED"
    assert refusals[0]["reasons"] == ["PreArm: Gyros still settling"]
    assert plane.t.armed
    assert plane.t.custom_mode == PlaneMode.GUIDED


@pytest.mark.parametrize(("result", "name"), [(DENIED, "DENIED"), (FAILED, "FAILED")])
def test_an_arm_refused_for_good_fails_with_the_result_and_no_retry_past_the_bound(
    monkeypatch: pytest.MonkeyPatch, result: int, name: str
) -> None:
    monkeypatch.setattr(launch, "ARM_RETRY_S", 0.05)
    plane = FakePlane(1, 100.0, mode=PlaneMode.LOITER)
    plane.script[commands.MAV_CMD_COMPONENT_ARM_DISARM] = [result] * 100
    _, event = recorder()
    with pytest.raises(
        CommandFailed, match=f"arm failed \\(result {name}, reasons none given"
    ) as err:
        run(launch.launch(FakeFleet(plane), [1], 50.0, event, FAST, ready_timeout_s=0.3))
    assert err.value.vehicle_id == 1
    tries = commands_sent(plane, commands.MAV_CMD_COMPONENT_ARM_DISARM)
    if result == DENIED:
        assert tries == 1  # final
    else:
        assert 2 <= tries <= 8  # every 0.05 s (+ the reasons' moment) for 0.3 s
    assert not plane.t.armed


def test_a_vehicle_that_took_off_is_sent_straight_on_once_in_guided() -> None:
    """Climbing out north-east, it is switched to GUIDED by a point 5 km on along its course
    at its altitude (DO_REPOSITION, its change-mode flag), rather than by DO_SET_MODE and
    left to circle where it entered GUIDED; a vehicle already flying is switched by
    DO_SET_MODE."""
    ground = FakePlane(2, 0.0, mode=PlaneMode.MANUAL)

    def placed(t: VehicleTelemetry) -> VehicleTelemetry:
        return dataclasses.replace(t, lat_deg=-35.0, lon_deg=149.0, alt_amsl_m=650.0,
                                   vn_m_s=15.0, ve_m_s=15.0)  # fmt: skip

    ground.t = placed(ground.t)
    flying = FakePlane(1, 150.0, armed=True, mode=PlaneMode.LOITER)
    flying.t = placed(flying.t)
    _events, event = recorder()
    run(launch.launch(FakeFleet(flying, ground), [1, 2], 80.0, event, FAST))
    sent = [m for m in ground.sent if getattr(m, "command", None) is not None]
    modes = [int(m.param2) for m in sent if m.command == commands.MAV_CMD_DO_SET_MODE]
    assert modes == [PlaneMode.TAKEOFF]
    point = sent[-1]
    assert point.command == commands.MAV_CMD_DO_REPOSITION
    here = Origin(lat=-35.0, lon=149.0, alt=650.0)
    east, north, up = geodetic_to_enu(point.x / 1e7, point.y / 1e7, point.z, here)
    assert (east, north, up) == pytest.approx((3535.5, 3535.5, 0.0), abs=2.0)
    assert ground.t.custom_mode == flying.t.custom_mode == PlaneMode.GUIDED
    assert commands_sent(flying, commands.MAV_CMD_DO_REPOSITION) == 0


def test_the_switch_to_guided_after_a_takeoff_goes_in_copies_and_survives_losing_two() -> None:
    """Left in TAKEOFF at its altitude, ArduPlane turns back over where it started, across
    the climb-out of a vehicle beside it: the switch goes in ``STRAIGHT_ON_COPIES`` copies,
    and two of them lost cost no resend (one send, lost, left the leader in TAKEOFF for
    two resends and 14.8 m from a wingman at 300 ms latency and 20 % loss)."""
    ground = FakePlane(2, 0.0, mode=PlaneMode.MANUAL)
    ground.t = dataclasses.replace(ground.t, lat_deg=-35.0, lon_deg=149.0, alt_amsl_m=650.0)
    ground.t = dataclasses.replace(ground.t, vn_m_s=15.0, ve_m_s=15.0)
    ground.script[commands.MAV_CMD_DO_REPOSITION] = ["lost", "lost"]
    events, event = recorder()
    run(launch.launch(FakeFleet(ground), [2], 80.0, event, FAST))
    reposition = commands.MAV_CMD_DO_REPOSITION
    repositions = [m for m in ground.sent if getattr(m, "command", None) == reposition]
    assert len(repositions) == launch.STRAIGHT_ON_COPIES
    assert not any(kind == "command_resent" for kind, *_ in events)
    assert ground.t.custom_mode == PlaneMode.GUIDED


def test_a_parameter_set_lost_and_the_value_before_read_back_is_sent_again() -> None:
    """The first PARAM_SET of TKOFF_ALT lost while a PARAM_VALUE of the value before comes:
    sent again, and read back as set; lost every time, it is said not set."""
    plane = FakePlane(3, 0.0)
    plane.param_sets_lost = 1
    events, event = recorder()
    assert run(launch.set_param(FakeFleet(plane), 3, "TKOFF_ALT", 80.0, event, FAST)) == 80.0
    assert sum(1 for m in plane.sent if m.get_type() == "PARAM_SET") == 2
    assert not events
    plane = FakePlane(3, 0.0)
    plane.param_sets_lost = 10
    events, event = recorder()
    assert run(launch.set_param(FakeFleet(plane), 3, "TKOFF_ALT", 80.0, event, FAST)) == 50.0
    assert events == [("parameter_not_set", 3, {"name": "TKOFF_ALT", "sent": 80.0, "read": 50.0})]


def test_a_vehicle_that_took_off_is_sent_on_only_as_far_as_the_way_is_clear() -> None:
    """The point that switches it to GUIDED is the one ``clear_ahead`` gives (short of a
    keep-out 1.2 km ahead, say), where ArduPlane circles until the run begins."""
    ground = FakePlane(2, 0.0, mode=PlaneMode.MANUAL)
    ground.t = dataclasses.replace(
        ground.t, lat_deg=-35.0, lon_deg=149.0, alt_amsl_m=650.0, vn_m_s=20.0, ve_m_s=0.0
    )
    asked: list[int] = []

    def clear(vid: int, t: VehicleTelemetry) -> tuple[float, float]:
        asked.append(vid)
        return 0.0, 1200.0

    _events, event = recorder()
    run(launch.launch(FakeFleet(ground), [2], 80.0, event, FAST, clear_ahead=clear))
    point = [m for m in ground.sent if getattr(m, "command", None) is not None][-1]
    assert point.command == commands.MAV_CMD_DO_REPOSITION
    here = Origin(lat=-35.0, lon=149.0, alt=650.0)
    east, north, _ = geodetic_to_enu(point.x / 1e7, point.y / 1e7, point.z, here)
    assert (east, north) == pytest.approx((0.0, 1200.0), abs=2.0)
    assert asked == [2]


def test_on_the_line_abreast_the_vehicles_beside_the_sphere_stop_short_of_it() -> None:
    """``examples/arduplane_3.json``: climbed out at 50 m on their northward courses, the
    leader (x = 0) and the wingman at x = 272 would pass 30 m and 8 m from the 150 m sphere
    1.5 km on; each is sent on only to where it stays twice the safe distance and two turn
    radii from it, the wingman at x = -272 (284 m from it) the whole 5 km.  One already
    beside the sphere is sent along a course that leads away from it."""
    mission = load_mission_file(EXAMPLES / "arduplane_3.json")
    lim = mission.limits
    keep = 2.0 * lim.safe_distance_obstacle + 2.0 * lim.v_max / lim.max_yaw_rate
    centre = np.array(mission.obstacles[0].center)
    radius = mission.obstacles[0].radius

    def sent(x: float, y: float) -> np.ndarray:
        lat, lon, alt = enu_to_geodetic(x, y, 50.0, mission.origin)
        t = VehicleTelemetry(
            1, 1, lat_deg=lat, lon_deg=lon, alt_amsl_m=alt, vn_m_s=22.0, ve_m_s=0.0
        )
        point = clear_ahead(mission, t)
        assert point is not None
        return np.array([x + point[0], y + point[1], 50.0])

    assert sent(-272.0, 20.0)[:2] == pytest.approx((-272.0, 20.0 + launch.STRAIGHT_ON_M))
    for x in (0.0, 272.0):
        stop = sent(x, 20.0)
        assert stop[0] == pytest.approx(x)
        assert 700.0 < stop[1] < 1400.0
        assert np.linalg.norm(stop - centre) - radius == pytest.approx(keep, abs=0.5)
    beside = sent(272.0, 1300.0)  # 105 m from its surface: turned off its course
    start = np.array([272.0, 1300.0, 50.0])
    assert path_clearance(start + 1e-6, beside, spheres_of(mission)) > 25.0
    assert beside[0] > 272.0 + 100.0  # away from the sphere, not into it


def spheres_of(mission: Mission) -> Obstacles:
    return obstacles_from_mission(mission)

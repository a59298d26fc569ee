"""Command confirmation against the scripted fake ArduPlane of ``test_launch``: a lost ACK is
sent again, a refusal is noticed at once, a command no HEARTBEAT shows (a guided point) is
confirmed by its ACK alone, and ``confirm_all`` reports a vehicle's failure without raising."""

from __future__ import annotations

from dataclasses import replace
from functools import partial

import pytest

from gcs_ppf.mavlink import commands
from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.service import confirmation
from gcs_ppf.service.confirmation import CommandFailed, Order
from tests.unit.service.test_launch import FAILED, FAST, FakeFleet, FakePlane, recorder, run

REPOSITION = commands.MAV_CMD_DO_REPOSITION


def hold(vid: int) -> Order:
    return Order(vid, partial(commands.reposition, vid, -35.0, 149.0, 700.0, 120.0),
                 REPOSITION, "hold: guided loiter")  # fmt: skip


def sends(plane: FakePlane, command: int) -> int:
    return sum(1 for m in plane.sent if getattr(m, "command", None) == command)


def test_a_lost_ack_is_sent_again_until_accepted() -> None:
    plane = FakePlane(1, 100.0, armed=True, mode=PlaneMode.GUIDED)
    plane.script[REPOSITION] = ["lost", "lost", "ok"]
    events, event = recorder()
    o = hold(1)
    attempts = run(confirmation.confirmed_command(
        FakeFleet(plane), 1, o.make, o.command, None, o.what, event, FAST))  # fmt: skip
    assert attempts == 3
    assert sends(plane, REPOSITION) == 3
    assert [k for k, *_ in events] == ["command_resent", "command_resent"]


def test_without_a_heartbeat_to_show_it_a_lost_ack_is_not_taken_for_done() -> None:
    """The vehicle is in GUIDED already: its HEARTBEAT cannot tell that a guided point
    arrived, so only an ACK confirms it and three lost ones fail."""
    plane = FakePlane(1, 100.0, armed=True, mode=PlaneMode.GUIDED)
    plane.script[REPOSITION] = ["lost", "lost", "lost"]
    events, event = recorder()
    o = hold(1)
    with pytest.raises(CommandFailed, match="hold: guided loiter"):
        run(confirmation.confirmed_command(
            FakeFleet(plane), 1, o.make, o.command, None, o.what, event, FAST))  # fmt: skip
    assert events[-1][0] == "command_failed"
    assert events[-1][2]["result"] == "no COMMAND_ACK"


def test_a_refusal_is_noticed_at_once_and_not_sent_again() -> None:
    plane = FakePlane(1, 100.0, armed=True, mode=PlaneMode.GUIDED)
    plane.script[REPOSITION] = [FAILED]
    events, event = recorder()
    o = hold(1)
    with pytest.raises(CommandFailed):
        run(confirmation.confirmed_command(
            FakeFleet(plane), 1, o.make, o.command, None, o.what, event, FAST))  # fmt: skip
    assert sends(plane, REPOSITION) == 1
    assert events == [("command_failed", 1, {"command": "hold: guided loiter",
                                             "result": "FAILED", "attempts": 1})]  # fmt: skip


def test_confirm_all_reports_the_vehicle_that_failed_and_confirms_the_others() -> None:
    good, lossy, refusing = (FakePlane(i, 100.0, armed=True, mode=PlaneMode.GUIDED)
                             for i in (1, 2, 3))  # fmt: skip
    lossy.script[REPOSITION] = ["lost", "lost"]
    refusing.script[REPOSITION] = [FAILED]
    events, event = recorder()
    failed = run(confirmation.confirm_all(
        FakeFleet(good, lossy, refusing), [hold(1), hold(2), hold(3)], event, FAST))  # fmt: skip
    assert failed == {3}
    assert (sends(good, REPOSITION), sends(lossy, REPOSITION), sends(refusing, REPOSITION)) == (
        1, 3, 1)  # fmt: skip
    assert [(k, v) for k, v, _ in events if k == "command_failed"] == [("command_failed", 3)]


def test_confirm_all_stops_a_vehicles_later_orders_after_its_failure() -> None:
    plane = FakePlane(1, 100.0, armed=True, mode=PlaneMode.GUIDED)
    plane.script[REPOSITION] = [FAILED]
    altitude = Order(1, partial(commands.guided_change_altitude, 1, 700.0, 0.0),
                     commands.MAV_CMD_GUIDED_CHANGE_ALTITUDE, "hold: altitude")  # fmt: skip
    _, event = recorder()
    failed = run(confirmation.confirm_all(FakeFleet(plane), [hold(1), altitude], event, FAST))
    assert failed == {1}
    assert sends(plane, commands.MAV_CMD_GUIDED_CHANGE_ALTITUDE) == 0


def test_copies_get_a_command_through_a_link_that_loses_some_in_one_attempt() -> None:
    """A hold sent three copies at a time acts at the first attempt when two are lost."""
    plane = FakePlane(1, 100.0, armed=True, mode=PlaneMode.GUIDED)
    plane.script[REPOSITION] = ["lost", "lost", "ok"]
    events, event = recorder()
    o = hold(1)
    retry = replace(FAST, copies=3)
    attempts = run(confirmation.confirmed_command(
        FakeFleet(plane), 1, o.make, o.command, None, o.what, event, retry))  # fmt: skip
    assert attempts == 1
    assert sends(plane, REPOSITION) == 3
    assert events == []

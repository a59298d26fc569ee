"""The fleet's requests to a newly discovered vehicle, and what GET /vehicles shows."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Coroutine
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_ppf.mavlink import commands
from gcs_ppf.mavlink.codec import Codec, MAVLinkMessage
from gcs_ppf.mavlink.telemetry import AIRFRAME_PARAMS, VehicleTelemetry
from gcs_ppf.service.fleet import (
    ALL_SILENT_FACTOR,
    PARAM_ASKS,
    STREAMED,
    Fleet,
    Vehicle,
    silent_vehicles,
)
from gcs_ppf.service.settings import Settings


def _wire(msg: MAVLinkMessage, system: int = 7) -> MAVLinkMessage:
    (decoded,) = Codec().parse(Codec(system, 1).encode(msg))
    return decoded


class Recording(Fleet):
    def __init__(self, tmp_path: Path) -> None:
        self.spawned: list[Coroutine[Any, Any, Any]] = []
        super().__init__(Settings(db=tmp_path / "db", tlog_dir=None), self._spawn_recorded)
        self.sent: list[tuple[int, Any]] = []

    def _spawn_recorded(self, coro: Coroutine[Any, Any, Any]) -> asyncio.Task[Any]:
        self.spawned.append(coro)
        return None  # type: ignore[return-value]  # run by the test itself

    async def send(self, system_id: int, msg: Any) -> None:
        self.sent.append((system_id, msg))


def test_streams_by_message_interval_only_and_every_airframe_parameter(tmp_path: Path) -> None:
    """A REQUEST_DATA_STREAM after SET_MESSAGE_INTERVAL would override the intervals on
    ArduPilot (measured: VFR_HUD and SYS_STATUS at 10 Hz), so none is sent."""
    fleet = Recording(tmp_path)
    heartbeat = mavlink2.MAVLink_heartbeat_message(1, 3, 0, 0, 3, 3)
    fleet._on_message(1, _wire(heartbeat))
    (request,) = fleet.spawned
    asyncio.run(request)
    kinds = [m.get_type() for _, m in fleet.sent]
    assert "REQUEST_DATA_STREAM" not in kinds
    intervals = [m for _, m in fleet.sent if m.get_type() == "COMMAND_LONG"]
    assert all(m.command == commands.MAV_CMD_SET_MESSAGE_INTERVAL for m in intervals)
    assert sorted(int(m.param1) for m in intervals) == sorted(STREAMED)
    asked = [m.param_id for _, m in fleet.sent if m.get_type() == "PARAM_REQUEST_READ"]
    assert sorted(asked) == sorted(AIRFRAME_PARAMS)
    assert {sysid for sysid, _ in fleet.sent} == {7}


def test_missing_parameters_are_asked_again_and_the_airframe_is_shown(tmp_path: Path) -> None:
    fleet = Recording(tmp_path)
    fleet._on_message(1, _wire(mavlink2.MAVLink_heartbeat_message(1, 3, 0, 0, 3, 3)))
    fleet.spawned[0].close()
    for name, value in (("TECS_CLMB_MAX", 5.0), ("GUIDED_P", 5000.0)):
        fleet._on_message(1, _wire(mavlink2.MAVLink_param_value_message(
            name.encode(), value, 9, 100, 1)))  # fmt: skip
    asyncio.run(fleet.request_airframe_params(7, missing_only=True))
    asked = {m.param_id for _, m in fleet.sent}
    assert asked == set(AIRFRAME_PARAMS) - {"TECS_CLMB_MAX", "GUIDED_P"}
    (shown,) = fleet.vehicles()
    assert shown["airframe"]["climb_max_m_s"] == 5.0
    assert shown["airframe"]["guided_p"] == 5000.0
    assert shown["airframe"]["roll_limit_deg"] is None


def test_parameters_not_answered_are_asked_again_with_our_heartbeats_a_few_times(
    tmp_path: Path,
) -> None:
    """A lossy link loses PARAM_VALUEs: each heartbeat asks again for those missing, at most
    ``PARAM_ASKS`` times; one answered meanwhile is not asked for again."""
    fleet = Recording(tmp_path)
    fleet.settings = fleet.settings.model_copy(update={"heartbeat_hz": 1000.0})
    fleet._on_message(1, _wire(mavlink2.MAVLink_heartbeat_message(1, 3, 0, 0, 3, 3)))
    fleet.spawned[0].close()
    fleet._on_message(
        1, _wire(mavlink2.MAVLink_param_value_message(b"TECS_CLMB_MAX", 5.0, 9, 100, 1))
    )

    async def beat_for(seconds: float) -> None:
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(fleet.heartbeats(), seconds)

    asyncio.run(beat_for(0.3))
    asked = [m.param_id for _, m in fleet.sent if m.get_type() == "PARAM_REQUEST_READ"]
    assert "TECS_CLMB_MAX" not in asked
    assert asked.count("TECS_SINK_MAX") == PARAM_ASKS
    assert len(asked) == PARAM_ASKS * (len(AIRFRAME_PARAMS) - 1)


def _heard(sysid: int, last_heard_s: float, rate: float = 1.0, since_s: float = 90.0) -> Vehicle:
    """A vehicle heard every 0.1 s of ours from ``since_s`` to ``last_heard_s``, its clock
    at ``rate`` (time_boot_ms 0 at ``since_s``)."""
    v = Vehicle(sysid, 0, VehicleTelemetry(sysid, 1), last_heard_s)
    v.clock.rate = rate
    walls = [*np.arange(since_s, last_heard_s, 0.1), last_heard_s]
    for w in walls:
        v.boot_history.append((float(w), round(1000 * rate * (w - since_s))))
    return v


def test_a_vehicle_silent_while_the_others_are_heard_is_lost_after_the_timeout() -> None:
    """Counted on the clock of the vehicle heard last (×10): 4.5 s, then 5.5 s of it."""
    quiet = _heard(1, 100.0, rate=10.0)
    assert silent_vehicles([quiet, _heard(2, 100.45, 10.0), _heard(3, 100.45, 10.0)],
                           100.45, timeout_s=5.0) == []  # fmt: skip
    late = silent_vehicles([quiet, _heard(2, 100.55, 10.0), _heard(3, 100.55, 10.0)],
                           100.55, timeout_s=5.0)  # fmt: skip
    assert [v.system_id for v in late] == [1]


def test_a_ground_station_starved_of_cpu_does_not_lose_every_vehicle_at_once() -> None:
    """Every link read 1 s late (10 vehicle s at ×10): nobody is behind anybody by the
    others' clocks, so nobody is lost until every vehicle has been silent for three
    timeouts of its own."""
    fleet = [_heard(i, 100.0 + 0.01 * i, rate=10.0) for i in (1, 2, 3, 4, 5)]
    assert silent_vehicles(fleet, 101.0, timeout_s=5.0) == []
    late = 100.05 + ALL_SILENT_FACTOR * 0.5 + 0.01
    assert len(silent_vehicles(fleet, late, timeout_s=5.0)) == 5


def test_a_single_vehicle_is_lost_after_the_timeout() -> None:
    assert len(silent_vehicles([_heard(1, 100.0)], 105.1, timeout_s=5.0)) == 1
    lost = _heard(2, 100.0)
    lost.lost = True
    assert silent_vehicles([lost], 105.1, timeout_s=5.0) == []


def test_a_clock_not_measured_yet_is_timed_on_a_teammates() -> None:
    """Wingman 3 silent since 100.0 with no rate of its own (1.0), the others at ×10 and
    heard: lost after 0.5 s of ours (5 of the others' seconds), not 5 s."""
    quiet = _heard(3, 100.0)
    quiet.clock.rate = 1.0
    fleet = [_heard(1, 100.55, rate=10.0), _heard(2, 100.55, rate=10.0), quiet]
    assert [v.system_id for v in silent_vehicles(fleet, 100.55, timeout_s=5.0)] == [3]
    fleet = [_heard(1, 100.45, rate=10.0), _heard(2, 100.45, rate=10.0), quiet]
    assert silent_vehicles(fleet, 100.45, timeout_s=5.0) == []


def _two_links(tmp_path: Path) -> Recording:
    fleet = Recording(tmp_path)

    async def add() -> None:
        await fleet.add_link("tcp:127.0.0.1:9")
        await fleet.add_link("tcp:127.0.0.1:10")

    asyncio.run(add())
    for coro in fleet.spawned:  # the links' run(): not run here
        coro.close()
    fleet.spawned.clear()
    return fleet


def _position(boot_ms: int, lat_deg: float, lon_deg: float = 8.0) -> MAVLinkMessage:
    return mavlink2.MAVLink_global_position_int_message(
        boot_ms, int(lat_deg * 1e7), int(lon_deg * 1e7), 400_000, 100_000, 0, 0, 0, 0
    )


def test_one_system_id_on_two_links_at_once_is_told_and_not_followed(
    tmp_path: Path, caplog: Any
) -> None:
    """Two vehicles with one id: each link carries its own position (1.1 km apart)."""
    fleet = _two_links(tmp_path)
    heartbeat = mavlink2.MAVLink_heartbeat_message(1, 3, 0, 0, 3, 3)
    fleet._on_message(1, _wire(heartbeat))
    fleet._on_message(1, _wire(_position(10_000, 47.0)))
    assert fleet.duplicates() == {}
    fleet._on_message(2, _wire(heartbeat))
    # Not known yet to be one vehicle (link 2 has carried no position): no start with it,
    # and nothing told yet.
    assert fleet.duplicates() == {7: (1, 2)}
    assert fleet.by_id[7].duplicate_links == ()
    with caplog.at_level("WARNING", logger="gcs_ppf.service.fleet"):
        fleet._on_message(2, _wire(_position(10_000, 47.01)))
    assert fleet.duplicates() == {7: (1, 2)}
    assert fleet.duplicates([8]) == {}
    assert fleet.by_id[7].link_id == 1  # commands stay on the link first heard
    assert "system id 7 heard on links 1, 2 at once" in caplog.text
    assert fleet.vehicles()[0]["duplicate_links"] == [1, 2]
    # Link 2 silent past the timeout: one link again, and a vehicle that then moves to
    # link 2 (link 1 silent) is followed there.
    fleet.by_id[7].heard_on[2] -= 60.0
    fleet._on_message(1, _wire(heartbeat))
    assert fleet.duplicates() == {}
    fleet.by_id[7].heard_on[1] -= 60.0
    fleet._on_message(2, _wire(heartbeat))
    assert fleet.duplicates() == {}
    assert fleet.by_id[7].link_id == 2
    for coro in fleet.spawned:
        coro.close()


def test_one_vehicle_on_two_links_is_commanded_on_the_one_still_heard(tmp_path: Path) -> None:
    """A radio and a backup: the same position at the same time on both links (one 0.3 s
    behind) is one vehicle, not a duplicate; its commands move to the backup once the
    other link carries its clock half a second further (the commanding one silent)."""
    fleet = _two_links(tmp_path)
    heartbeat = mavlink2.MAVLink_heartbeat_message(1, 3, 0, 0, 3, 3)
    for link, boot in ((1, 10_000), (2, 9_700)):
        fleet._on_message(link, _wire(heartbeat))
        fleet._on_message(link, _wire(_position(boot, 47.0 + boot * 1e-9)))
    vehicle = fleet.by_id[7]
    assert fleet.duplicates() == {}
    assert vehicle.redundant_links == (1, 2)
    assert fleet.vehicles()[0]["redundant_links"] == [1, 2]
    first = vehicle.link_id
    other = 2 if first == 1 else 1
    for boot in range(10_100, 10_800, 100):  # the commanding link silent: 0.7 s on
        fleet._on_message(other, _wire(_position(boot, 47.0)))
    assert vehicle.link_id == other
    assert vehicle.link_change == (first, other, "behind")
    for coro in fleet.spawned:
        coro.close()


def test_a_removed_link_is_not_a_duplicate(tmp_path: Path) -> None:
    fleet = _two_links(tmp_path)
    heartbeat = mavlink2.MAVLink_heartbeat_message(1, 3, 0, 0, 3, 3)
    fleet._on_message(1, _wire(heartbeat))
    fleet._on_message(1, _wire(_position(10_000, 47.0)))
    fleet._on_message(2, _wire(heartbeat))
    fleet._on_message(2, _wire(_position(10_000, 47.01)))
    assert fleet.duplicates() == {7: (1, 2)}
    asyncio.run(fleet.remove_link(2))
    assert fleet.duplicates() == {}
    for coro in fleet.spawned:
        coro.close()


def test_our_heartbeat_keeps_1_hz_of_the_vehicles_clock(tmp_path: Path) -> None:
    """CONVENTIONS §5 in the vehicle's seconds: a SITL at ×10 hears 10 of our heartbeats a
    second, so its GCS failsafe (FS_LONG_TIMEOUT 5 of its seconds) never takes us for
    dead; before its clock is measured (its first second) at least 10 a second of ours."""
    from gcs_ppf.mavlink.telemetry import VehicleTelemetry
    from gcs_ppf.service.fleet import Vehicle

    fleet = Recording(tmp_path)
    assert fleet._heartbeat_period_s() == pytest.approx(1.0)  # nobody heard
    vehicle = Vehicle(1, 0, VehicleTelemetry(1, 1), last_heard_s=0.0)
    fleet.by_id[1] = vehicle
    assert fleet._heartbeat_period_s() == pytest.approx(0.1)  # its clock not measured yet
    for k in range(3):
        vehicle.clock.observe(100.0 + 1.5 * k, 15_000 * k)  # 10 of its seconds per ours
    assert vehicle.clock.measured
    assert fleet._heartbeat_period_s() == pytest.approx(0.1)
    vehicle.clock = type(vehicle.clock)()
    for k in range(3):
        vehicle.clock.observe(100.0 + 1.5 * k, 1_500 * k)  # real time
    assert fleet._heartbeat_period_s() == pytest.approx(1.0)

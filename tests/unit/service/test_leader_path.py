"""The target reached along every position the leader reported (``flight.leader_flown``):
a tick late under load sees several positions at once, and the chord from the last tick's
to the latest cuts inside a turn."""

from __future__ import annotations

import math
import time
from typing import Any, cast

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_ppf.geodesy import enu_to_geodetic
from gcs_ppf.mavlink.codec import Codec
from gcs_ppf.mavlink.telemetry import FIXES_KEPT, VehicleTelemetry, apply
from gcs_ppf.planning.scene import FloatArray
from gcs_ppf.service.fleet import Vehicle
from gcs_ppf.service.flight import leader_flown
from gcs_ppf.service.station import Station
from tests.unit.service.test_flight_formation import table3_run

TURN_RADIUS_M = 577.0  # 300 m/s at 30°/s, Table 3's limits
MISS_M = 10.4  # the arc passes this far from the target, outside its 10 m


class Fleet:
    def __init__(self, leader: Vehicle) -> None:
        self.by_id = {leader.system_id: leader}


class FakeStation:
    """What ``leader_flown`` uses of a station: the fleet, the events, ``path_since``."""

    path_since = Station.path_since

    def __init__(self, leader: Vehicle) -> None:
        self.fleet = Fleet(leader)
        self.seen: list[str] = []

    def event(self, run: Any, kind: str, vehicle_id: int | None = None, **detail: Any) -> None:
        self.seen.append(kind)


def arc_m(target: FloatArray) -> FloatArray:
    """25 points 30 m apart on a level turn that passes MISS_M from ``target`` (the middle
    one), the target inside it."""
    angles_rad = np.arange(-12, 13) * 30.0 / TURN_RADIUS_M
    centre = target + np.array([0.0, TURN_RADIUS_M - MISS_M, 0.0])
    around = np.stack([np.sin(angles_rad), -np.cos(angles_rad), np.zeros_like(angles_rad)], 1)
    return np.asarray(centre + TURN_RADIUS_M * around, dtype=float)


def reported(tel: VehicleTelemetry, run: Any, boot_ms: int, pos_m: FloatArray) -> VehicleTelemetry:
    east, north, up = pos_m.tolist()
    lat, lon, alt = enu_to_geodetic(east, north, up, run.mission.origin)
    msg = mavlink2.MAVLink_global_position_int_message(
        boot_ms, round(lat * 1e7), round(lon * 1e7), round(alt * 1e3), 0, 30000, 0, 0, 9000
    )
    (wire,) = Codec().parse(Codec(1, 1).encode(msg))
    return apply(tel, wire, time.monotonic())


def fly(step_fixes: int) -> tuple[bool, list[float]]:
    """The leader along the arc at 10 Hz (30 m a fix), the service looking every
    ``step_fixes`` fixes: whether it judged the target reached, and each look's chord's
    closest distance to the target."""
    run = table3_run()
    target = np.array(run.mission.target)
    points = arc_m(target)
    tel = VehicleTelemetry(1, 1)
    vehicle = Vehicle(1, 0, tel, last_heard_s=time.monotonic())
    station = FakeStation(vehicle)
    reached, chords, last = False, [], None
    for k, p in enumerate(points):
        vehicle.telemetry = reported(vehicle.telemetry, run, 1000 + 100 * k, p)
        if k % step_fixes == 0 or k == len(points) - 1:
            reached = reached or leader_flown(cast(Station, station), run, p)
            if last is not None:
                seg = p - last
                s = min(max(float((target - last) @ seg) / float(seg @ seg), 0.0), 1.0)
                chords.append(float(np.linalg.norm(last + s * seg - target)))
            last = p
    return reached, chords


def test_a_late_tick_judges_the_whole_path_not_its_chord() -> None:
    reached, chords = fly(step_fixes=10)  # a second of flight a look: ×10, a tick late
    assert min(chords) < 10.0  # the chord alone would have called it reached
    assert not reached


def test_the_target_reached_on_the_path_is_reached() -> None:
    run = table3_run()
    target = np.array(run.mission.target)
    points = arc_m(target) + np.array([0, 1.0, 0])
    vehicle = Vehicle(1, 0, VehicleTelemetry(1, 1), last_heard_s=time.monotonic())
    station = FakeStation(vehicle)
    looks = []
    for k, p in enumerate(points):
        vehicle.telemetry = reported(vehicle.telemetry, run, 1000 + 100 * k, p)
        if k % 10 == 9:
            looks.append(leader_flown(cast(Station, station), run, p))
    assert looks == [False, True]  # 9.4 m from it, between the first look and the second


def test_a_clock_gone_back_judges_the_latest_position() -> None:
    run = table3_run()
    vehicle = Vehicle(1, 0, VehicleTelemetry(1, 1), last_heard_s=time.monotonic())
    station = FakeStation(vehicle)
    far = np.array(run.mission.target) + np.array([500.0, 0.0, 0.0])
    vehicle.telemetry = reported(vehicle.telemetry, run, 50_000, far)
    assert not leader_flown(cast(Station, station), run, far)
    vehicle.telemetry = reported(vehicle.telemetry, run, 1_000, far + 1.0)  # rebooted
    path, newest_ms = cast(Station, station).path_since(run.mission, 1, run.leader_fix_ms)
    assert newest_ms == 1_000
    assert path.shape == (1, 3)
    assert len(vehicle.telemetry.recent_fixes) == 2 <= FIXES_KEPT
    assert math.dist(path[0].tolist(), (far + 1.0).tolist()) < 0.05

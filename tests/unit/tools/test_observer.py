"""The independent observer's judge on synthetic tracks: separation, clearance, silence."""

from __future__ import annotations

import random
import socket

import numpy as np
import pytest

from gcs_ppf.frames import local_target_point
from gcs_ppf.mission import Mission
from gcs_ppf.tools.observer import (
    LOWEST_PORT,
    PORT_OFFSETS,
    closest_pass,
    ephemeral_ports,
    free_port,
    free_port_block,
    judge,
    longest_formed_s,
    observed_at,
    slot_distances,
    slot_errors,
)

Track = np.ndarray


def mission(obstacles: list[dict[str, object]]) -> Mission:
    return Mission.model_validate({
        "name": "observer-test",
        "origin": {"lat": 47.0, "lon": 8.0, "alt": 400.0},
        "target": [2000.0, 0.0, 300.0],
        "vehicles": [
            {"id": 1, "role": "leader", "position": [0, 0, 300], "pitch": 0, "yaw": 0},
            {"id": 2, "role": "wingman", "position": [0, 200, 300], "pitch": 0, "yaw": 0,
             "slot": [-100, 100, 0]},
        ],
        "obstacles": obstacles,
    })  # fmt: skip


def straight(t: np.ndarray, y: float, z: float = 300.0, v: float = 100.0) -> Track:
    """[K,5] (t, x, y, z, height) flying east at v."""
    return np.column_stack([t, v * t, np.full_like(t, y), np.full_like(t, z), np.full_like(t, z)])


def test_separation_and_clearance_of_two_parallel_tracks() -> None:
    t = np.arange(0.0, 20.0, 0.1)
    m = mission([{"center": [1000.0, 500.0, 300.0], "radius": 200.0}])
    j = judge(m, {1: straight(t, 0.0), 2: straight(t, 120.0)}, 0.0, 20.0)
    assert j.min_separation_m == pytest.approx(120.0)
    assert j.closest_pair == (1, 2)
    assert j.clearance_m[1] == pytest.approx(300.0, abs=0.1)  # 500 − 200 below its centre
    assert j.clearance_m[2] == pytest.approx(180.0, abs=0.1)
    assert j.min_clearance_m() == pytest.approx(180.0, abs=0.1)
    assert j.min_clearance_m(exclude=[2]) == pytest.approx(300.0, abs=0.1)
    assert j.lowest_m == {1: 300.0, 2: 300.0}
    assert j.leader_to_target_m == pytest.approx(10.0)  # its last sample, 1990 m east


def test_a_silent_vehicle_counts_only_while_it_was_heard() -> None:
    """Vehicle 2 falls silent at 5 s on a course that would cross vehicle 1 at 10 s: no
    position is made up for it after its last sample."""
    t = np.arange(0.0, 20.0, 0.1)
    lead = straight(t, 0.0)
    t2 = t[t <= 5.0]
    crossing = np.column_stack([t2, 1000.0 + 0 * t2, 500.0 - 50.0 * t2, 300.0 + 0 * t2,
                                300.0 + 0 * t2])  # fmt: skip
    j = judge(mission([]), {1: lead, 2: crossing}, 0.0, 19.9)
    assert j.min_separation_m == pytest.approx(float(np.hypot(500.0, 250.0)), abs=1.0)
    assert j.clearance_m == {1: None, 2: None}


def test_zones_count_in_the_clearance_the_observer_judges() -> None:
    """A U of no-fly walls one track flies into, and a stay-inside area the other flies
    outside of: each distance as ``mission.zone_clearance`` gives it, negative inside the
    keep-out."""
    doc = mission([]).model_dump()
    doc["zones"] = [
        {"kind": "polygon", "vertices": [[800, -300], [1200, -300], [1200, 300], [800, 300],
                                          [800, 200], [1100, 200], [1100, -200], [800, -200]]},
        {"kind": "polygon", "inclusion": True, "vertices": [[-500, -500], [2100, -500],
                                                            [2100, 500], [-500, 500]]},
    ]  # fmt: skip
    m = Mission.model_validate(doc)
    t = np.arange(0.0, 12.0, 0.1)  # east at 100 m/s: through the pocket into the back wall
    j = judge(m, {1: straight(t, 0.0), 2: straight(t, 600.0)}, 0.0, 11.9)
    assert j.clearance_m[1] == pytest.approx(-50.0, abs=0.5)  # mid-wall, 50 m from each face
    assert j.clearance_m[2] == pytest.approx(-100.0, abs=0.5)  # 100 m outside the area
    assert judge(mission([]), {1: straight(t, 0.0)}, 0.0, 11.9).clearance_m == {1: None}


def test_gaps_in_a_track_are_not_interpolated_across() -> None:
    ts = np.array([0.0, 0.1, 0.2, 5.0, 5.1])
    mask = observed_at(straight(ts, 0.0), np.array([0.05, 1.0, 5.05, 6.0]))
    assert mask.tolist() == [True, False, True, False]


def test_moving_obstacles_move_from_the_runs_start() -> None:
    t = np.arange(0.0, 10.0, 0.1)
    m = mission([{"center": [0.0, 1000.0, 300.0], "radius": 100.0, "velocity": [100, 0, 0]}])
    # The obstacle keeps pace 1 km north of the vehicle when the run starts at 0 s ...
    j = judge(m, {1: straight(t, 0.0), 2: straight(t, 2000.0)}, 0.0, 9.9, run_start_s=0.0)
    assert j.clearance_m[1] == pytest.approx(900.0, abs=0.1)
    # ... and is 500 m behind it when the run started 5 s later.
    j = judge(m, {1: straight(t, 0.0), 2: straight(t, 2000.0)}, 0.0, 9.9, run_start_s=5.0)
    assert j.clearance_m[1] == pytest.approx(float(np.hypot(500.0, 1000.0)) - 100.0, abs=1.0)


def test_a_vehicle_that_sinks_after_climbing_shows_its_lowest_height() -> None:
    t = np.arange(0.0, 10.0, 0.1)
    climb = straight(t, 500.0)
    climb[:, 4] = np.where(t < 5.0, 10.0 + 20.0 * t, 110.0 - 20.0 * (t - 5.0))
    j = judge(mission([]), {1: straight(t, 0.0), 2: climb}, 0.0, 9.9)
    assert j.lowest_m[2] == pytest.approx(12.0, abs=0.5)  # under the 25 m keep-out
    assert closest_pass(climb, np.array([0.0, 500.0, 300.0])) == pytest.approx(0.0)


def test_how_long_the_formation_held_is_the_longest_time_all_were_in_their_slots() -> None:
    """The wingman on its local target point from 5 s to 12 s, 50 m off it before and
    after: formed for 7 s, whatever it did outside."""
    t = np.arange(0.0, 20.0, 0.1)
    m = mission([])
    leader = straight(t, 0.0)
    slot = np.array(m.vehicles[1].slot)
    on = np.array([local_target_point(leader[k, 1:4], 0.0, 0.0, slot) for k in range(len(t))])
    off = on + np.array([0.0, 50.0, 0.0])
    inside = (t >= 5.0) & (t < 12.0)
    wing = np.where(inside[:, None], on, off)
    wingman = np.column_stack([t, wing, wing[:, 2]])
    held = longest_formed_s(m, {1: leader, 2: wingman}, 0.5, 19.0)
    assert held == pytest.approx(7.0, abs=0.3)


@pytest.mark.realtime  # binds ports on loopback
def test_a_port_block_is_free_at_every_instances_ports_below_the_ephemeral_range() -> None:
    """ArduPilot's SITL binds P + 10·i + 0, 2 and 3: a block checked at P + 10·i only, taken
    from the ephemeral range, collided with an outgoing connection's port."""
    for _ in range(20):
        base = free_port_block(50)
        assert base >= LOWEST_PORT
        assert base + 50 + max(PORT_OFFSETS) < ephemeral_ports()[0]
        for k in range(0, 51, 10):
            for o in PORT_OFFSETS:
                with socket.socket() as s:
                    s.bind(("127.0.0.1", base + k + o))


def climbing(t: np.ndarray, angle_rad: float, yaw_rad: float, v: float = 100.0) -> Track:
    """[K,5] a leader climbing straight at ``angle_rad`` on the course ``yaw_rad``."""
    u = np.array([np.cos(angle_rad) * np.cos(yaw_rad), np.cos(angle_rad) * np.sin(yaw_rad),
                  np.sin(angle_rad)])  # fmt: skip
    p = np.array([0.0, 0.0, 300.0]) + v * t[:, None] * u
    return np.column_stack([t, p, p[:, 2]])


def test_slot_errors_are_in_the_leaders_flight_path_frame() -> None:
    """A wingman 5 m ahead of, 3 m left of and 20 m above its slot behind a leader climbing
    at 35° on a course of 40°: (5, 3, 20), whose length is the slot distance Eq. 6 gives."""
    t = np.arange(0.0, 10.0, 0.1)
    m = mission([])
    angle, course = np.radians(35.0), np.radians(40.0)
    leader = climbing(t, angle, course)
    slot = np.array(m.vehicles[1].slot) + np.array([5.0, 3.0, 20.0])
    wing = np.array(
        [local_target_point(leader[k, 1:4], angle, course, slot) for k in range(len(t))]
    )
    tracks = {1: leader, 2: np.column_stack([t, wing, wing[:, 2]])}
    inner = np.arange(1.0, 9.0, 0.5)
    errors = slot_errors(m, tracks, inner)[2]
    assert np.allclose(errors, [5.0, 3.0, 20.0], atol=1e-6)
    assert np.allclose(slot_distances(m, tracks, inner)[2], np.sqrt(25 + 9 + 400), atol=1e-6)


def test_the_vehicle_clock_at_a_wall_time_is_read_from_the_soonest_sample() -> None:
    """At x10, samples stamped every 0.1 s of the vehicle's, the last two read 30 ms late:
    interpolating the arrivals puts the clock 0.3 s late, the soonest sample does not."""
    import numpy as np

    from gcs_ppf.tools.observer import vehicle_time_at

    stamps = np.arange(0.0, 10.0, 0.1)
    arrivals = stamps / 10.0
    arrivals[-2:] += 0.03
    clock = np.column_stack([arrivals, stamps])
    wall = arrivals[-1]
    true_v = (wall - 0.03) * 10.0 + 0.3  # the last stamp, 30 ms of ours ago, carried on
    assert abs(vehicle_time_at(clock, wall) - true_v) < 0.05
    assert float(np.interp(wall, clock[:, 0], clock[:, 1])) < true_v - 0.25


@pytest.mark.realtime  # binds ports on loopback
def test_a_port_handed_out_is_never_handed_out_again_before_it_is_bound(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A block for the SITL, then one port for the API: the API's port was free because the
    SITL had not bound its block yet, and it was the SITL's second vehicle port."""
    base = free_port_block(20)
    draws = iter([base + 10, base + 11, base + 10])
    draw = random.Random.randrange

    def next_draw(self: random.Random, low: int, high: int) -> int:
        return next(draws, None) or draw(self, low, high)

    monkeypatch.setattr(random.Random, "randrange", next_draw)
    api = free_port()
    assert api not in {base + k + o for k in range(0, 21, 10) for o in PORT_OFFSETS}
    draws = iter([base, api - 10])
    assert free_port_block(20) not in {base, api - 10}

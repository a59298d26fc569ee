"""Unit tests of sitl.navigation (AUTO): reaching, loiters, jumps, completion."""

from __future__ import annotations

import math

from sitl import mission_protocol as mp
from sitl.navigation import AutoEvents, MissionRunner
from sitl.physics import GuidanceKind

HOME = (0.0, 0.0, 100.0)


def item(cmd: int, p1: float = 0.0, p2: float = 0.0, p3: float = 0.0) -> mp.MissionItem:
    return mp.MissionItem(3, cmd, 0, 1, p1, p2, p3, 0.0, 1, 1, 100.0)


def runner(
    items: list[mp.MissionItem], targets: list[tuple[float, float, float] | None]
) -> MissionRunner:
    r = MissionRunner([item(16), *items], [None, *targets])
    r.begin((0.0, 0.0, 100.0), 0.0, 0.0, AutoEvents())
    return r


def test_waypoint_reached_by_radius_or_passing_the_line() -> None:
    r = runner([item(16), item(16)], [(1000.0, 0.0, 100.0), (1000.0, 1000.0, 100.0)])
    assert r.update(HOME, (500.0, 0.0, 100.0), 0.0, 200, 90, 1.0, False).reached == []
    # 150 m abeam but past the line through the waypoint: reached
    ev = r.update(HOME, (1010.0, 150.0, 100.0), 0.0, 200, 90, 2.0, False)
    assert ev.reached == [1]
    assert r.current == 2
    ev = r.update(HOME, (1000.0, 950.0, 100.0), 0.0, 200, 90, 3.0, False)  # inside WP_RADIUS
    assert ev.reached == [2]
    assert ev.complete


def test_loiter_turns_counts_heading_change_on_the_circle() -> None:
    r = runner([item(18, p1=2, p3=300)], [(0.0, 0.0, 100.0)])
    nav = r.target(HOME, 60.0)
    assert nav.kind == GuidanceKind.ORBIT
    assert nav.radius_m == 300
    reached: list[int] = []
    yaw = 0.0
    for k in range(800):  # 2° per update on the circle: two turns take 360 updates
        yaw = math.remainder(yaw - math.radians(2), math.tau)
        a = -math.radians(2) * k
        reached += r.update(
            HOME, (300 * math.cos(a), 300 * math.sin(a), 100.0), yaw, 300, 90, k, False
        ).reached
        if reached:
            break
    assert reached == [1]
    assert 355 <= k <= 365


def test_do_jump_repeats_and_do_change_speed_runs() -> None:
    items = [item(16), item(178, p1=0, p2=150), item(177, p1=1, p2=1)]
    r = runner(items, [(100.0, 0.0, 100.0), None, None])
    ev = r.update(HOME, (100.0, 0.0, 100.0), 0.0, 200, 90, 1.0, False)
    assert ev.reached == [1]
    assert ev.speed_changes == [(0, 150.0)]
    assert r.current == 1  # jumped back once
    ev = r.update(HOME, (100.0, 0.0, 100.0), 0.0, 200, 90, 2.0, False)
    assert ev.complete  # the jump is used up: the mission ends

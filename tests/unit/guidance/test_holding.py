"""Holding circles clear of the obstacles' keep-outs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs

from gcs_ppf.guidance.holding import (
    Hold,
    HoldRequest,
    approach_path,
    clear_run_m,
    formation_holds,
    holding_circle,
    path_clearance,
    points_clearance,
    ring_clearance,
)
from gcs_ppf.guidance.vehicle_motion import Motion
from gcs_ppf.mavlink.ardupilot import TURN_EFFICIENCY
from gcs_ppf.mission import Mission
from gcs_ppf.planning.scene import Obstacles
from gcs_ppf.planning.zones import zone_clearances, zones_from_mission


def spheres(*cr: tuple[float, float, float, float]) -> Obstacles:
    a = np.array(cr, dtype=float).reshape(len(cr), 4)
    return Obstacles(a[:, :3].copy(), a[:, 3].copy(), np.zeros((len(cr), 3)))


def test_without_obstacles_the_circle_is_straight_ahead() -> None:
    hold = holding_circle(np.array([0.0, 0.0, 100.0]), 0.0, 100.0, 90.0, 800.0, spheres(), 50.0)
    assert (hold.x_m, hold.y_m, hold.z_m) == pytest.approx((800.0, 0.0, 100.0))
    assert hold.clearance_m == math.inf


def test_an_obstacle_ahead_moves_the_circle_off_it_and_the_way_there_clear() -> None:
    """Issue 10: vehicles left circling straight ahead flew into the obstacle beyond the
    target. The circle chosen keeps the keep-out, ring and approach."""
    obstacle = spheres((800.0, 0.0, 100.0, 300.0))
    pos = np.array([0.0, 0.0, 100.0])
    hold = holding_circle(pos, 0.0, 100.0, 90.0, 800.0, obstacle, 50.0)
    assert hold.clearance_m >= 50.0
    assert ring_clearance(hold.x_m, hold.y_m, 100.0, 90.0 / TURN_EFFICIENCY, obstacle) >= 50.0
    assert ring_clearance(hold.x_m, hold.y_m, 100.0, 90.0, obstacle) >= 50.0
    assert math.hypot(hold.x_m - 800.0, hold.y_m) > 300.0 + 90.0


def test_a_zone_ahead_moves_the_circle_off_it_as_a_sphere_does() -> None:
    """A hold after a run circled through a U's wall: the spheres alone were checked
    (``examples/scene_u_pocket.json``, a CPU burner per core). Ring, ring as flown and the
    way there keep the keep-out from the zone's walls."""
    zones = zones_from_mission(
        Mission.model_validate(
            {
                "target": [5000.0, 0.0, 100.0],
                "vehicles": [{"id": 1, "role": "leader", "position": [0.0, 0.0, 100.0]}],
                "zones": [{"kind": "polygon", "vertices": [[600, -300], [1000, -300],
                                                           [1000, 300], [600, 300]]}],
            }
        )
    )  # fmt: skip
    pos = np.array([0.0, 0.0, 100.0])
    blind = holding_circle(pos, 0.0, 100.0, 90.0, 800.0, spheres(), 50.0)
    assert zone_clearances(np.array([[blind.x_m, blind.y_m, 100.0]]), zones)[0, 0] < 0.0
    hold = holding_circle(pos, 0.0, 100.0, 90.0, 800.0, spheres(), 50.0, zones=zones)
    assert hold.clearance_m >= 50.0
    a = np.linspace(0.0, 2.0 * math.pi, 360)
    for r in (90.0, 90.0 / TURN_EFFICIENCY):
        ring = np.column_stack([hold.x_m + r * np.cos(a), hold.y_m + r * np.sin(a),
                                np.full(a.shape, 100.0)])  # fmt: skip
        assert zone_clearances(ring, zones).min() >= 50.0 - 0.5
    request = HoldRequest(pos, 0.0, 100.0, 90.0, None)
    together = formation_holds([request], 0.0, 800.0, spheres(), 50.0, zones)
    assert together is not None
    assert together[0].clearance_m >= 50.0


def test_path_clearance_is_the_segments_closest_approach() -> None:
    obs = spheres((50.0, 30.0, 0.0, 10.0))
    a, b = np.array([0.0, 0.0, 0.0]), np.array([100.0, 0.0, 0.0])
    assert path_clearance(a, b, obs) == pytest.approx(20.0)


@settings(max_examples=80, deadline=None)
@given(
    ox=hs.floats(-3000, 3000), oy=hs.floats(-3000, 3000), r=hs.floats(50, 900),
    yaw=hs.floats(-math.pi, math.pi),
)  # fmt: skip
def test_whenever_a_clear_circle_exists_nearby_the_one_chosen_is_clear(
    ox: float, oy: float, r: float, yaw: float
) -> None:
    """One sphere anywhere (not on the vehicle): some candidate keeps the keep-out (a
    sphere cannot surround a vehicle from every side), so the choice keeps it."""
    pos = np.array([0.0, 0.0, 300.0])
    obs = spheres((ox, oy, 300.0, r))
    if np.hypot(ox, oy) - r < 100.0:  # the vehicle itself in the keep-out: nothing to test
        return
    hold = holding_circle(pos, yaw, 300.0, 120.0, 800.0, obs, 50.0)
    assert hold.clearance_m >= 50.0


def test_the_hold_is_chosen_on_the_approach_the_vehicle_flies_not_a_straight_line() -> None:
    """At 210 m/s turning at 0.5 rad/s (420 m wide): checked as a straight line, the circle
    chosen here is reached through the sphere (flown: 143 m inside its surface); checked on
    the flown approach, the circle chosen and the way there keep the keep-out."""
    sphere = Obstacles(np.array([[305.0, -637.0, 400.0]]), np.array([424.0]), np.zeros((1, 3)))
    yaw, radius, keep_out = -1.563, 630.0, 50.0
    m = Motion((0.0, 0.0, 400.0), yaw, 210.0, 0.5, 10.0, 10.0, 1.0)
    pos = np.array(m.pos_m)

    def flown(h: Hold) -> float:
        path = approach_path(m, h.x_m, h.y_m, h.z_m, radius / TURN_EFFICIENCY)
        return points_clearance(path, sphere)

    straight = holding_circle(pos, yaw, 400.0, radius, 800.0, sphere, keep_out)
    assert straight.clearance_m >= keep_out
    assert flown(straight) < 0.0
    hold = holding_circle(pos, yaw, 400.0, radius, 800.0, sphere, keep_out, motion=m)
    assert hold.clearance_m >= keep_out
    assert flown(hold) >= keep_out


def test_circles_of_teammates_flying_side_by_side_do_not_overlap() -> None:
    """Five vehicles 100 m apart abreast, each asked for a circle 800 m ahead: each circle,
    as flown, keeps the safe distance from the ones chosen before it."""
    from gcs_ppf.guidance.holding import flown_width_m, ring_gap

    none = Obstacles(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)))
    taken: list[tuple[Hold, float]] = []
    for k in range(5):
        m = Motion((0.0, 100.0 * k, 150.0), 0.0, 28.0, 0.3, 5.0, 5.0, 2.0)
        hold = holding_circle(np.array(m.pos_m), 0.0, 150.0, 140.0, 800.0, none, 50.0, m,
                              taken, 50.0)  # fmt: skip
        wide = flown_width_m(140.0, m)
        assert ring_gap(hold.x_m, hold.y_m, wide, taken) >= 50.0
        taken.append((hold, wide))
    assert len({(round(h.x_m), round(h.y_m)) for h, _ in taken}) == 5


def test_a_formation_holds_as_it_flies_translated() -> None:
    """Five vehicles abreast, 100 m apart: every circle is its vehicle's position moved by
    one same vector, so the approaches are parallel and the spacing is kept; a sphere in the
    way moves that vector for all of them, never one alone."""
    from gcs_ppf.guidance.holding import HoldRequest, formation_holds

    def requests() -> list[HoldRequest]:
        return [HoldRequest(np.array([0.0, 100.0 * k, 150.0]), 0.0, 150.0 + 100.0 * k, 140.0,
                            Motion((0.0, 100.0 * k, 150.0), 0.0, 28.0, 0.3, 5.0, 5.0, 2.0))
                for k in range(5)]  # fmt: skip

    none = Obstacles(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)))
    holds = formation_holds(requests(), 0.0, 800.0, none, 50.0)
    assert holds is not None
    shifts = {(round(h.x_m - 0.0, 6), round(h.y_m - 100.0 * k, 6)) for k, h in enumerate(holds)}
    assert shifts == {(800.0, 0.0)}  # straight ahead, one vector
    wall = Obstacles(np.array([[800.0, 200.0, 150.0]]), np.array([150.0]), np.zeros((1, 3)))
    moved = formation_holds(requests(), 0.0, 800.0, wall, 50.0)
    assert moved is not None
    shifts = {(round(h.x_m, 6), round(h.y_m - 100.0 * k, 6)) for k, h in enumerate(moved)}
    assert len(shifts) == 1
    assert shifts != {(800.0, 0.0)}
    assert all(h.clearance_m >= 50.0 for h in moved)


def test_a_large_fleet_holds_on_circles_spread_apart_in_its_order() -> None:
    """Thirty vehicles in rows of six, 150 m apart (a stack would climb them side by side for
    minutes): every ring as flown is the separation clear of every other at any height, each
    circle at its vehicle's own height, the foremost row to the furthest circles and each
    row in its order across; a sphere where the grid would be moves all of it."""
    from gcs_ppf.guidance.holding import flown_width_m, spread_holds

    def requests() -> list[HoldRequest]:
        out = []
        for k in range(30):
            pos = (-150.0 * (k // 6), 150.0 * (k % 6), 500.0 + 7.0 * k)
            out.append(HoldRequest(np.array(pos), 0.0, pos[2], 287.0,
                                   Motion(pos, 0.0, 100.0, 0.52, 34.0, 42.0, 1.0)))  # fmt: skip
        return out

    none = Obstacles(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)))
    holds = spread_holds(requests(), 0.0, 800.0, 150.0, none, 50.0)
    assert holds is not None
    wide = flown_width_m(287.0, requests()[0].motion)
    for i, a in enumerate(holds):
        assert a.z_m == requests()[i].z_m
        for b in holds[i + 1 :]:
            assert math.hypot(a.x_m - b.x_m, a.y_m - b.y_m) - 2.0 * wide >= 150.0 - 1e-6
    for i in range(30):
        for j in range(30):
            if i // 6 < j // 6:  # i's row flies ahead of j's
                assert holds[i].x_m > holds[j].x_m
            elif i // 6 == j // 6 and i % 6 < j % 6:  # the order across the row kept
                assert holds[i].y_m < holds[j].y_m
    assert min(h.x_m for h in holds) == pytest.approx(800.0)
    ahead = holds[0]
    sphere = spheres((ahead.x_m, ahead.y_m, 500.0, 300.0))
    moved = spread_holds(requests(), 0.0, 800.0, 150.0, sphere, 50.0)
    assert moved is not None
    assert all(h.clearance_m >= 50.0 for h in moved)
    assert (moved[0].x_m, moved[0].y_m) != (ahead.x_m, ahead.y_m)


def fly_loiter_course(m: Motion, x: float, y: float, ring_m: float, seconds: float) -> Motion:
    """``m`` flown ``seconds`` on ``loiter_course`` by a course P-controller (the turn the
    course error over the heading time constant, at most the turn rate) at 10 Hz."""
    from dataclasses import replace

    from gcs_ppf.guidance.holding import loiter_course

    px, py, _ = m.pos_m
    yaw, dt = m.yaw_rad, 0.1
    for _ in range(round(seconds / dt)):
        course = loiter_course((px, py), x, y, ring_m, m.speed_m_s, m.turn_rate_rad_s,
                               m.heading_tau_s)  # fmt: skip
        err = math.remainder(course - yaw, math.tau)
        yaw += max(-m.turn_rate_rad_s, min(m.turn_rate_rad_s, err / m.heading_tau_s)) * dt
        px += m.speed_m_s * math.cos(yaw) * dt
        py += m.speed_m_s * math.sin(yaw) * dt
    return replace(m, pos_m=(px, py, m.pos_m[2]), yaw_rad=math.remainder(yaw, math.tau))


@settings(max_examples=60, deadline=None)
@given(
    hs.floats(-3000.0, 3000.0), hs.floats(-3000.0, 3000.0), hs.floats(-math.pi, math.pi),
    hs.sampled_from([(28.0, 0.3, 2.0), (100.0, 0.52, 1.0), (210.0, 0.5, 1.5)]),
)  # fmt: skip
def test_the_loiter_course_brings_a_vehicle_from_anywhere_onto_its_ring_clockwise(
    x: float, y: float, yaw: float, airframe: tuple[float, float, float]
) -> None:
    """From any position and heading, a vehicle told ``loiter_course`` by a GUIDED-like
    P-controller is on its ring (as ``on_ring`` judges it) and stays there: the ring 1.5
    turn radii / η wide, reached within the flight to it and two turns round it."""
    from gcs_ppf.guidance.holding import flown_radius_m, on_ring

    speed, omega, tau = airframe
    radius = 1.5 * speed / omega
    ring = flown_radius_m(radius)
    hold = Hold(0.0, 0.0, 300.0, radius, math.inf)
    m = Motion((x, y, 300.0), yaw, speed, omega, 5.0, 5.0, tau)
    to_ring_s = (math.hypot(x, y) + ring) / speed + 2.0 * math.tau * ring / speed
    m = fly_loiter_course(m, 0.0, 0.0, ring, to_ring_s)
    for _ in range(20):  # and round it: judged every 2 s for 40 s
        assert on_ring(m.pos_m, m.yaw_rad, 0.0, hold, speed, omega)
        assert abs(math.hypot(*m.pos_m[:2]) - ring) < 0.25 * speed / omega
        m = fly_loiter_course(m, 0.0, 0.0, ring, 2.0)


def test_on_ring_is_the_ring_at_its_height_level_and_clockwise() -> None:
    from gcs_ppf.guidance.holding import flown_radius_m, on_ring

    hold = Hold(100.0, 0.0, 300.0, 300.0, math.inf)
    ring = flown_radius_m(300.0)
    east = (100.0 + ring, 0.0, 300.0)  # clockwise there is south: ICS yaw −π/2
    assert on_ring(east, -math.pi / 2, 0.0, hold, 100.0, 0.5)
    assert not on_ring(east, math.pi / 2, 0.0, hold, 100.0, 0.5)  # anticlockwise
    assert not on_ring(east, -math.pi / 2, 6.0, hold, 100.0, 0.5)  # still climbing
    assert not on_ring((east[0], 0.0, 330.0), -math.pi / 2, 0.0, hold, 100.0, 0.5)  # 30 m high
    assert not on_ring((east[0] + 150.0, 0.0, 300.0), -math.pi / 2, 0.0, hold, 100.0, 0.5)


def test_a_straight_run_stops_where_it_first_comes_within_the_keep_of_a_sphere() -> None:
    """Heading +y from the origin, a sphere of 150 m centred 158 m aside, 1500 m on: the
    run ends where the path first comes within 100 m of its surface, 1500 - √(250² - 158²)."""
    ball = spheres((150.0, 1500.0, 100.0 + 102.3, 150.0))
    aside = math.hypot(150.0, 102.3)
    start, north = np.array([0.0, 0.0, 100.0]), np.array([0.0, 1.0, 0.0])
    run = clear_run_m(start, north, ball, None, 100.0, 5000.0)
    assert run == pytest.approx(1500.0 - math.sqrt(250.0**2 - aside**2), abs=1e-6)
    assert path_clearance(start, start + run * north, ball) == pytest.approx(100.0, abs=1e-6)
    assert clear_run_m(start, -north, ball, None, 100.0, 5000.0) == 5000.0  # behind
    assert clear_run_m(start, north, ball, None, 10.0, 5000.0) == 5000.0  # passes clear
    inside = np.array([150.0, 1200.0, 202.3])  # within the grown sphere
    assert clear_run_m(inside, north, ball, None, 200.0, 5000.0) == 0.0  # closing
    assert clear_run_m(inside, -north, ball, None, 200.0, 5000.0) == 5000.0  # leaving


def test_a_straight_run_stops_short_of_a_zone_ahead() -> None:
    zones = zones_from_mission(
        Mission.model_validate(
            {
                "target": [5000.0, 0.0, 100.0],
                "vehicles": [{"id": 1, "role": "leader", "position": [0.0, 0.0, 100.0]}],
                "zones": [{"kind": "polygon", "vertices": [[-300, 1000], [300, 1000],
                                                           [300, 1400], [-300, 1400]]}],
            }
        )
    )  # fmt: skip
    start, north = np.array([0.0, 0.0, 100.0]), np.array([0.0, 1.0, 0.0])
    run = clear_run_m(start, north, spheres(), zones, 50.0, 5000.0)
    assert 930.0 <= run <= 950.0
    stop = start + run * north
    assert zone_clearances(stop[None], zones)[0].min() >= 50.0

"""The safety monitor: keep-outs entered, from reported positions alone."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs

from gcs_ppf.guidance.safety_monitor import MAX_ALIGN_S, Monitor, aligned, current, violations
from gcs_ppf.mission import CylinderZone, Mission, PolygonZone
from gcs_ppf.planning.scene import Obstacles
from gcs_ppf.planning.zones import Zones, zones_of


def spheres(*centres_radii: tuple[float, float, float, float]) -> Obstacles:
    m = len(centres_radii)
    a = np.array(centres_radii, dtype=float).reshape(m, 4)
    return Obstacles(a[:, :3].copy(), a[:, 3].copy(), np.zeros((m, 3)))


def test_inside_an_obstacles_safe_distance_is_a_violation_with_its_depth() -> None:
    obs = spheres((0.0, 0.0, 100.0, 50.0))
    pos = np.array([[0.0, 60.0, 100.0], [0.0, 500.0, 100.0]])  # 10 m and 450 m from it
    found = violations([1, 2], pos, obs, None, 50.0, 25.0)
    assert [(v.kind, v.vehicle_id, v.other) for v in found] == [("obstacle", 1, 0)]
    assert found[0].depth_m == pytest.approx(15.0)


def test_teammates_closer_than_the_safe_distance_count_once_per_pair() -> None:
    pos = np.array([[0.0, 0.0, 100.0], [30.0, 0.0, 100.0], [1000.0, 0.0, 100.0]])
    found = violations([7, 3, 9], pos, spheres(), None, 50.0, 25.0)
    assert [(v.kind, v.vehicle_id, v.other) for v in found] == [("teammate", 3, 7)]
    assert found[0].depth_m == pytest.approx(20.0)


def test_the_ground_counts_only_for_vehicles_that_have_flown() -> None:
    pos = np.array([[0.0, 0.0, 10.0], [500.0, 0.0, 10.0]])
    found = violations([1, 2], pos, spheres(), 0.0, 50.0, 25.0, airborne=[True, False])
    assert [(v.kind, v.vehicle_id) for v in found] == [("ground", 1)]
    assert found[0].depth_m == pytest.approx(15.0)


def test_the_monitor_reports_a_violation_when_it_begins_and_counts_each_once() -> None:
    mon = Monitor()
    obs = spheres((0.0, 0.0, 0.0, 50.0))
    inside = violations([1], np.array([[0.0, 60.0, 0.0]]), obs, None, 50.0, 25.0)
    deeper = violations([1], np.array([[0.0, 55.0, 0.0]]), obs, None, 50.0, 25.0)
    clear = violations([1], np.array([[0.0, 500.0, 0.0]]), obs, None, 50.0, 25.0)
    assert len(mon.update(inside)) == 1
    assert mon.update(deeper) == []  # the same one, going on
    assert mon.update(clear) == []
    assert len(mon.update(inside)) == 1  # a new one
    assert mon.count == 2
    assert mon.deepest_m["obstacle"] == pytest.approx(20.0)


@settings(max_examples=60, deadline=None)
@given(
    xs=hs.lists(hs.tuples(hs.floats(-2000, 2000), hs.floats(-2000, 2000), hs.floats(0, 800)),
                min_size=1, max_size=6),
    cx=hs.floats(-1000, 1000), r=hs.floats(1, 500),
)  # fmt: skip
def test_a_violation_is_reported_exactly_when_a_distance_is_short(
    xs: list[tuple[float, float, float]], cx: float, r: float
) -> None:
    """Against a brute-force check of every distance."""
    pos = np.array(xs, dtype=float)
    ids = list(range(1, len(xs) + 1))
    obs = spheres((cx, 0.0, 300.0, r))
    found = {(v.kind, v.vehicle_id, v.other) for v in violations(ids, pos, obs, 0.0, 50.0, 25.0)}
    expect: set[tuple[str, int, int | None]] = set()
    for i, p in enumerate(pos):
        if np.linalg.norm(p - (cx, 0.0, 300.0)) - r < 25.0:
            expect.add(("obstacle", ids[i], 0))
        if p[2] < 25.0:
            expect.add(("ground", ids[i], None))
        for j in range(i + 1, len(pos)):
            if np.linalg.norm(p - pos[j]) < 50.0:
                expect.add(("teammate", ids[i], ids[j]))
    assert found == expect


def test_watching_counts_the_ground_once_a_vehicle_has_been_clear_of_it() -> None:
    mon = Monitor()
    low = np.array([[0.0, 0.0, 5.0]])
    assert mon.watch([1], low, spheres(), 0.0, 50.0, 25.0) == []  # taking off
    assert mon.watch([1], np.array([[0.0, 0.0, 80.0]]), spheres(), 0.0, 50.0, 25.0) == []
    began = mon.watch([1], low, spheres(), 0.0, 50.0, 25.0)
    assert [(v.kind, v.vehicle_id) for v in began] == [("ground", 1)]


def test_reports_of_different_moments_are_carried_to_the_newest() -> None:
    """Two vehicles 60 m apart at one instant, one flying away from the other: its report,
    0.2 s older, puts them 40 m apart; carried along its velocity to the newer report's
    instant (at most ``MAX_ALIGN_S``), it is where it is.  Without ages, nothing moves."""
    positions = np.array([[20.0, 0.0, 100.0], [60.0, 0.0, 100.0]])
    velocities = np.array([[-100.0, 0.0, 0.0], [0.0, 100.0, 0.0]])
    none = spheres()
    assert violations([1, 2], positions, none, None, 50.0, 25.0)  # two moments compared
    together = aligned(positions, velocities, np.array([0.5, 0.3]))
    assert together[0] == pytest.approx([0.0, 0.0, 100.0])
    assert together[1] == pytest.approx(positions[1])
    assert not violations([1, 2], together, none, None, 50.0, 25.0)
    far = aligned(positions, velocities, np.array([5.0, 0.0]))
    assert far[0] == pytest.approx([20.0 - 100.0 * MAX_ALIGN_S, 0.0, 100.0])
    assert aligned(positions, velocities, np.zeros(2)) == pytest.approx(positions)


def test_a_vehicle_gone_silent_is_not_judged_where_it_last_was() -> None:
    """Flown (a CPU burner per core): wingman 4's link died, and 3.5 s later wingman 3 passed
    45.4 m from where 4 had last reported; judged there, that was a violation with no
    vehicle in it.  A report more than ``MAX_ALIGN_S`` behind the newest is not judged."""
    ages = np.array([0.0, 0.4, MAX_ALIGN_S, MAX_ALIGN_S + 0.01, 3.5])
    assert current(ages).tolist() == [True, True, True, False, False]
    assert current(ages + 10.0).tolist() == current(ages).tolist()  # behind the newest
    assert current(np.zeros(0)).tolist() == []
    positions = np.array([[0.0, 0.0, 300.0], [45.4, 0.0, 300.0]])  # 3 now, 4's last report
    now = current(np.array([0.0, 3.5]))
    ids = [i for i, c in zip([3, 4], now, strict=True) if c]
    assert violations([3, 4], positions, spheres(), None, 50.0, 25.0)  # were it judged
    assert not violations(ids, positions[now], spheres(), None, 50.0, 25.0)


def _zones() -> Zones:
    m = Mission.model_validate(
        {
            "target": [0.0, 0.0, 300.0],
            "vehicles": [{"id": 1, "role": "leader", "position": [0.0, 0.0, 300.0]}],
        }
    )
    return zones_of(
        [
            CylinderZone(kind="cylinder", center=(1000.0, 0.0), radius=100.0, ceiling=200.0),
            PolygonZone(  # a U opening west: its pocket is free
                kind="polygon",
                vertices=[
                    (0, 2000),
                    (600, 2000),
                    (600, 2600),
                    (0, 2600),
                    (0, 2400),
                    (400, 2400),
                    (400, 2200),
                    (0, 2200),
                ],
            ),
            PolygonZone(
                kind="polygon",
                vertices=[(-5000, -5000), (5000, -5000), (5000, 5000), (-5000, 5000)],
                inclusion=True,
            ),
        ],
        m.origin,
    )


def test_zones_entered_are_violations_with_their_index_and_depth() -> None:
    pos = np.array(
        [
            [1000.0, 110.0, 150.0],  # 10 m outside the cylinder's wall, under its ceiling
            [1000.0, 0.0, 215.0],  # 15 m over its ceiling
            [1000.0, 0.0, 400.0],  # 200 m over it: clear
            [200.0, 2300.0, 300.0],  # in the U's pocket, 100 m from its walls: clear
            [500.0, 2300.0, 300.0],  # inside the U's solid end, 100 m deep
            [4990.0, 0.0, 300.0],  # 10 m inside the inclusion zone's edge
            [5100.0, 0.0, 300.0],  # 100 m outside it
        ]
    )
    found = violations(list(range(1, 8)), pos, spheres(), None, 50.0, 25.0, zones=_zones())
    got = {(v.vehicle_id, v.other): v.depth_m for v in found}
    assert {v.kind for v in found} == {"zone"}
    assert got == pytest.approx({(1, 0): 15.0, (2, 0): 10.0, (5, 1): 125.0, (6, 2): 15.0,
                                 (7, 2): 125.0})  # fmt: skip


def test_the_monitor_reports_a_zone_entered_once_while_inside() -> None:
    mon = Monitor()
    inside = np.array([[1000.0, 50.0, 150.0]])
    assert (
        mon.watch([1], np.array([[0.0, 0.0, 300.0]]), spheres(), None, 50.0, 25.0, _zones()) == []
    )
    [began] = mon.watch([1], inside, spheres(), None, 50.0, 25.0, _zones())
    assert (began.kind, began.vehicle_id, began.other) == ("zone", 1, 0)
    assert began.depth_m == pytest.approx(75.0)
    assert mon.watch([1], inside, spheres(), None, 50.0, 25.0, _zones()) == []
    assert mon.count == 1
    assert mon.deepest_m["zone"] == pytest.approx(75.0)

"""Seeded scenes: each reproducible on its own, and each family keeps its definition."""

from __future__ import annotations

import math
from itertools import combinations

import numpy as np
import pytest

from gcs_ppf.mission import Mission, zone_clearance, zone_footprint
from gcs_ppf.offline.sweep.families import CLOSE, DENSE, FEASIBLE, MOVING, POCKETS, ZONES
from gcs_ppf.offline.sweep.scenes import (
    SceneError,
    draw_scene,
    influence_at_v_max,
    scene_rng,
    v_slots,
    zone_influence_at_v_max,
)
from gcs_ppf.offline.sweep.spec import Box, FleetSpec, GroundSpec, SceneSpec

SCENES = 60


def _scenes(spec: SceneSpec, seed: int = 3) -> list[Mission]:
    return [draw_scene(spec, seed, i) for i in range(SCENES)]


def _starts(m: Mission) -> list[tuple[float, float, float]]:
    return [v.position for v in m.vehicles]


def test_a_scene_depends_on_its_seed_and_index_alone() -> None:
    later = [draw_scene(MOVING, 11, i) for i in (5, 2, 9)]
    assert later == [draw_scene(MOVING, 11, i) for i in (5, 2, 9)]
    assert draw_scene(MOVING, 11, 5) != draw_scene(MOVING, 11, 6)
    assert draw_scene(MOVING, 11, 5) != draw_scene(MOVING, 12, 5)
    children = np.random.SeedSequence(11).spawn(10)
    assert scene_rng(11, 7).random() == np.random.default_rng(children[7]).random()


def test_feasible_scenes_keep_the_guarantees_conditions() -> None:
    for m in _scenes(FEASIBLE):
        assert 1 <= len(m.vehicles) <= 5
        assert len(m.obstacles) <= 4
        for a, b in combinations(_starts(m), 2):
            assert math.dist(a, b) >= 300.0
        for o in m.obstacles:
            reach = influence_at_v_max(m.limits, o.radius)
            assert all(math.dist(o.center, p) >= reach for p in [*_starts(m), m.target])
            assert o.velocity == (0.0, 0.0, 0.0)
        for o, q in combinations(m.obstacles, 2):
            apart = influence_at_v_max(m.limits, o.radius) + influence_at_v_max(m.limits, q.radius)
            assert math.dist(o.center, q.center) >= apart
        assert m.planner.max_time == 90.0
        assert m.ground is None


@pytest.mark.parametrize("family", [ZONES, POCKETS], ids=lambda f: f.name)
def test_zone_scenes_keep_every_start_and_the_target_out_of_each_zones_influence(
    family: SceneSpec,
) -> None:
    kinds = set()
    for m in _scenes(family):
        assert not m.obstacles
        reach = zone_influence_at_v_max(m.limits, m.planner.dt)
        for z in m.zones:
            kinds.add(z.kind)
            footprint = zone_footprint(z, m.origin)
            assert all(zone_clearance(z, footprint, p) > reach for p in [*_starts(m), m.target])
            assert z.floor is not None
            assert z.ceiling is not None
            assert z.floor < z.ceiling
    assert kinds == ({"cylinder", "polygon"} if family is ZONES else {"polygon"})


def test_a_pocket_opens_towards_the_leaders_start() -> None:
    m = next(m for m in _scenes(POCKETS) if m.zones)
    start = m.leader.position
    for z in m.zones:
        footprint = zone_footprint(z, m.origin)
        cx = sum(p[0] for p in footprint) / len(footprint)
        cy = sum(p[1] for p in footprint) / len(footprint)
        heading = math.atan2(start[1] - cy, start[0] - cx)
        half = max(math.dist(a, b) for a, b in combinations(footprint, 2)) / math.sqrt(8.0)
        dx, dy = 0.9 * half * math.cos(heading), 0.9 * half * math.sin(heading)
        assert z.floor is not None
        assert z.ceiling is not None
        height = (z.floor + z.ceiling) / 2.0
        # The middle of the open side is outside the zone, the middle of the back wall inside.
        assert zone_clearance(z, footprint, (cx + dx, cy + dy, height)) > 0.0
        assert zone_clearance(z, footprint, (cx - dx, cy - dy, height)) < 0.0


def test_the_fleet_is_a_v_within_the_boxes() -> None:
    assert v_slots(3, 100.0) == [(-100.0, 100.0, 0.0), (-100.0, -100.0, 0.0), (-200.0, 200.0, 0.0)]
    for m in _scenes(FEASIBLE):
        x, y, z = m.leader.position
        assert -9000.0 <= x <= -3000.0
        assert abs(y) <= 3000.0
        assert abs(z) <= 500.0
        assert 3000.0 <= m.target[0] <= 9000.0
        assert all(
            -0.3 <= v.pitch <= 0.3 and 100.0 <= (v.speed or 0.0) <= 300.0 for v in m.vehicles
        )


def test_dense_obstacles_may_overlap_but_keep_clear_of_starts_and_target() -> None:
    scenes = _scenes(DENSE)
    overlapping = 0
    for m in scenes:
        for o in m.obstacles:
            reach = influence_at_v_max(m.limits, o.radius)
            assert all(math.dist(o.center, p) >= reach for p in [*_starts(m), m.target])
            assert 100.0 <= o.radius <= 700.0
        overlapping += any(
            math.dist(o.center, q.center)
            < influence_at_v_max(m.limits, o.radius) + influence_at_v_max(m.limits, q.radius)
            for o, q in combinations(m.obstacles, 2)
        )
    assert overlapping > SCENES // 4


def test_moving_obstacles_fly_level_at_up_to_300_m_s() -> None:
    speeds = [math.hypot(*o.velocity[:2]) for m in _scenes(MOVING) for o in m.obstacles]
    assert speeds
    assert max(speeds) <= 300.0
    assert min(speeds) >= 0.0
    assert all(o.velocity[2] == 0.0 for m in _scenes(MOVING) for o in m.obstacles)


def test_close_scenes_start_closer_without_obstacles() -> None:
    scenes = _scenes(CLOSE)
    assert all(not m.obstacles for m in scenes)
    gaps = [math.dist(a, b) for m in scenes for a, b in combinations(_starts(m), 2)]
    assert min(gaps) >= 80.0


def test_a_ground_lies_below_every_start_and_the_target() -> None:
    spec = SceneSpec(ground=GroundSpec(depth_m=(0.0, 100.0)))
    for m in _scenes(spec):
        assert m.ground is not None
        lowest = min(p[2] for p in [*_starts(m), m.target])
        assert lowest - m.ground >= m.limits.safe_distance_obstacle + 40.0


def test_a_family_that_cannot_make_a_scene_says_so() -> None:
    cramped = SceneSpec(
        name="cramped",
        fleet=FleetSpec(
            wingmen=(4, 4),
            start_box=Box(center_m=(-6000.0, 0.0, 0.0), half_size_m=(100.0, 100.0, 0.0)),
        ),
    )
    with pytest.raises(SceneError, match="cramped: no valid scene in 1000 draws"):
        draw_scene(cramped, 0, 0)


def test_a_family_passing_obstacles_as_a_formation_draws_the_same_scenes_with_that_option() -> None:
    whole = FEASIBLE.model_copy(update={"obstacle_passage": "formation"})
    for k in range(4):
        each, passing = draw_scene(FEASIBLE, 3, k), draw_scene(whole, 3, k)
        assert each.obstacle_passage == "each"
        assert passing.obstacle_passage == "formation"
        assert passing.model_copy(update={"obstacle_passage": "each"}) == each

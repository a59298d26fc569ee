"""Neighbour lists: planning with them gives exactly the all-pairs plan."""

from __future__ import annotations

import numpy as np
import pytest

from gcs_ppf.mission import Limits, load_mission_file
from gcs_ppf.offline.benchmark import synthetic_scene, with_polygon_zones
from gcs_ppf.planning.planner import MateSearch, Trajectory, advance
from gcs_ppf.planning.ppf.kernel import attitude_trig
from gcs_ppf.planning.ppf.neighbours import (
    MATES_ALL_PAIRS,
    MATES_GRID,
    OBSTACLE_GRID_MIN_PAIRS,
    nearby_obstacles,
    nearby_teammates,
    nearby_zones,
)
from gcs_ppf.planning.ppf.zone_repulsion import surface_influence_radius
from gcs_ppf.planning.rollout import NEIGHBOUR_LIST_STEPS
from gcs_ppf.planning.scene import Fleet, Obstacles, Scene, kernel_limits, scene_from_mission
from gcs_ppf.planning.zones import zone_distance
from tests.conftest import EXAMPLES

FIELDS = ("t", "pos", "pitch", "yaw", "speed", "state", "avoiding", "formed")


def melee(
    n: int, seed: int, climb_limit: float | None = None, m: int = 5, tied: bool = False
) -> Scene:
    """N vehicles in a 3 km box, every heading and speed, random priorities (``tied``:
    three vehicles to a priority on average), a tenth of them inactive, among M spheres (one
    moving): teammate conflicts all the time."""
    rng = np.random.default_rng(seed)
    pos = rng.uniform(-1500.0, 1500.0, (n, 3)) * [1.0, 1.0, 0.2]
    active = rng.random(n) > 0.1
    active[0] = True
    fleet = Fleet(
        ids=np.arange(1, n + 1, dtype=np.int64),
        pos=pos,
        pitch=rng.uniform(-0.3, 0.3, n),
        yaw=rng.uniform(-np.pi, np.pi, n),
        speed=rng.uniform(100.0, 300.0, n),
        slot=np.zeros((n, 3)),
        rank=(rng.integers(0, n // 3, n) if tied else rng.permutation(n)).astype(np.int64),
        active=active,
    )
    velocity = np.zeros((m, 3))
    velocity[0] = [30.0, -20.0, 0.0]
    obstacles = Obstacles(
        center=rng.uniform(-2000.0, 2000.0, (m, 3)) * [1.0, 1.0, 0.1],
        radius=rng.uniform(50.0, 200.0, m),
        velocity=velocity,
    )
    limits = kernel_limits(Limits())
    if climb_limit is not None:
        limits = limits._replace(max_climb_angle=climb_limit, max_dive_angle=climb_limit)
    return Scene(fleet, obstacles, np.array([20_000.0, 0.0, 0.0]), limits)


def assert_same_plan(scene: Scene, steps: int, dt: float = 0.01) -> Trajectory:
    plans: dict[MateSearch, Trajectory] = {
        mates: advance(scene, dt, steps, mates=mates).trajectory
        for mates in ("all-pairs", "grid", "auto")
    }
    reference = plans["all-pairs"]
    for mates in ("grid", "auto"):
        for field in FIELDS:
            assert np.array_equal(getattr(plans[mates], field), getattr(reference, field)), (
                mates,
                field,
            )
    return reference


@pytest.mark.parametrize("table", [2, 3])
def test_the_paper_scenes_plan_the_same_with_the_grid(table: int) -> None:
    scene = scene_from_mission(load_mission_file(EXAMPLES / f"paper_table{table}.json"))
    plan = assert_same_plan(scene, 30_000)
    assert plan.t[-1] < 300.0  # the whole plan, to the leader's arrival


def test_a_big_formation_plans_the_same_with_the_grid() -> None:
    assert_same_plan(synthetic_scene(120, 40), 1500)


@pytest.mark.parametrize(("seed", "climb_limit", "m"), [(0, None, 5), (1, None, 40), (2, 0.35, 5)])
def test_a_melee_of_conflicts_plans_the_same_with_the_grid(
    seed: int, climb_limit: float | None, m: int
) -> None:
    plan = assert_same_plan(melee(60, seed, climb_limit, m), 1500)
    assert plan.avoiding.sum() > 1000  # teammates repelled each other throughout


def test_tied_priorities_plan_the_same_with_the_grid() -> None:
    scene = melee(60, 3, tied=True)
    assert np.unique(scene.fleet.rank).size < 40  # (vehicles of one priority ignore each other)
    plan = assert_same_plan(scene, 1500)
    assert plan.avoiding.sum() > 1000


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_obstacle_grid_finds_the_same_obstacles_as_every_pair(seed: int) -> None:
    scene = melee(300, seed, m=60)
    f, o = scene.fleet, scene.obstacles
    n, m = f.pos.shape[0], o.center.shape[0]
    assert n * m >= OBSTACLE_GRID_MIN_PAIRS
    start, near = np.zeros(n + 1, dtype=np.int64), np.empty(n * m, dtype=np.int64)
    nearby_obstacles(f.pos, o.center, o.radius, o.velocity, scene.limits, 0.01, 25, start, near)
    for i in range(n):  # every pair, by the same bound
        d2 = ((f.pos[i] - o.center) ** 2).sum(axis=1)
        reach = (
            o.radius
            + 25.0
            + 300.0 / (np.pi / 6)
            + 3 * 3.0
            + np.linalg.norm(o.velocity, axis=1) * 3.0
        )
        reach += (300.0 + np.linalg.norm(o.velocity, axis=1)) * 0.25
        expected = np.flatnonzero(d2 <= reach**2)
        assert np.array_equal(near[start[i] : start[i + 1]], expected), i
    assert start[n] > n  # most vehicles have obstacles near


def test_the_grid_keeps_fewer_mates_than_all_pairs() -> None:
    scene = synthetic_scene(500, 0)
    f = scene.fleet
    n = f.pos.shape[0]
    trig = np.empty((n, 7))
    attitude_trig(f.pitch, f.yaw, trig)
    counts = {}
    for search in (MATES_ALL_PAIRS, MATES_GRID):
        start = np.zeros(n + 1, dtype=np.int64)
        mates = nearby_teammates(
            f.pos, trig, f.speed, f.rank, f.active, scene.limits, 0.01, 25,
            search, start, np.empty(4, dtype=np.int64),
        )  # fmt: skip
        for i in range(n):  # ascending, active, of higher priority
            mine = mates[start[i] : start[i + 1]]
            assert np.all(np.diff(mine) > 0)
            assert np.all(f.rank[mine] < f.rank[i])
        counts[search] = start[n]
    assert counts[MATES_ALL_PAIRS] == n * (n - 1) // 2
    assert counts[MATES_GRID] < counts[MATES_ALL_PAIRS] / 5


def test_the_zone_lists_hold_every_zone_a_vehicle_can_reach_within_the_horizon() -> None:
    """Every zone whose surface a vehicle could come within influence of over the next
    steps (moved by v_max a step, in any direction) is on its list; far ones are not."""
    scene = with_polygon_zones(synthetic_scene(50, 0), 60)
    rng = np.random.default_rng(3)
    pos = np.column_stack(
        [rng.uniform(0, 40_000, 400), rng.uniform(-7000, 7000, 400), rng.uniform(-500, 500, 400)]
    )
    speed = rng.uniform(100.0, 300.0, 400)
    lim, dt = scene.limits, 0.01
    kind, geom, vstart, verts = scene.zones.arrays
    start = np.zeros(401, dtype=np.int64)
    near = np.empty(400 * len(kind), dtype=np.int64)
    nearby_zones(pos, speed, kind, geom, lim, dt, NEIGHBOUR_LIST_STEPS, start, near)
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    reach = surface_influence_radius(lim.v_max, omega, lim.safe_distance_obstacle)
    reach += 3.0 * lim.v_max * dt
    travel = lim.v_max * NEIGHBOUR_LIST_STEPS * dt
    listed = 0
    for i in range(400):
        mine = set(near[start[i] : start[i + 1]].tolist())
        assert list(near[start[i] : start[i + 1]]) == sorted(mine)
        listed += len(mine)
        for k in range(len(kind)):
            d = zone_distance(k, pos[i, 0], pos[i, 1], pos[i, 2], kind, geom, vstart, verts)[0]
            if d <= reach + travel:
                assert k in mine, (i, k, d)
            if d > 3.0 * (reach + travel) + 2.0 * geom[k, 2]:
                assert k not in mine, (i, k, d)
    assert 0 < listed < 400 * len(kind) // 4  # the lists do cut the work

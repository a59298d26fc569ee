"""The separation guard: vertical resolutions from telemetry, outside the planner."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from gcs_ppf.guidance.separation_guard import closest_approach, formation_tolerance_m, resolve
from gcs_ppf.mission import Mission
from gcs_ppf.planning.scene import Scene, scene_from_mission


def pair(wingman: list[float], yaw: float, ground: float | None = None) -> Scene:
    """The leader at the origin flying east at 100 m/s; a wingman at ``wingman``."""
    doc = {
        "target": [20000.0, 0.0, 300.0],
        "vehicles": [
            {"id": 1, "role": "leader", "position": [0.0, 0.0, 300.0]},
            {"id": 2, "role": "wingman", "position": wingman, "yaw": yaw,
             "slot": [-100.0, 100.0, 0.0]},
        ],
        **({} if ground is None else {"ground": ground}),
    }  # fmt: skip
    return scene_from_mission(Mission.model_validate(doc))


def guard(scene: Scene) -> tuple[np.ndarray, list[bool]]:
    guided = scene.fleet.pos + np.array([1500.0, 0.0, 0.0])
    return resolve(scene, guided, distance_m=100.0, horizon_s=4.0, resolution_m=150.0)


def test_closest_approach_within_the_horizon() -> None:
    d, w = np.array([100.0, 0.0, 0.0]), np.array([-50.0, 0.0, 0.0])
    assert closest_approach(d, w, 10.0) == pytest.approx(0.0)
    assert closest_approach(d, w, 1.0) == pytest.approx(50.0)
    assert closest_approach(d, -w, 10.0) == pytest.approx(100.0)  # moving apart
    assert closest_approach(d, np.zeros(3), 10.0) == pytest.approx(100.0)


def test_a_converging_wingman_above_the_leader_climbs_and_the_leader_keeps_its_plan() -> None:
    scene = pair([200.0, 150.0, 330.0], -math.pi / 2)  # crossing ahead of the leader
    points, resolving = guard(scene)
    assert resolving == [False, True]
    assert points[1, 2] == pytest.approx(330.0 + 150.0)
    assert np.allclose(points[0], scene.fleet.pos[0] + [1500.0, 0.0, 0.0])
    assert np.allclose(points[1, :2], scene.fleet.pos[1, :2] + [1500.0, 0.0])  # course kept


def test_below_it_descends_but_not_into_the_ground_and_never_towards_the_other() -> None:
    points, _ = guard(pair([200.0, 150.0, 270.0], -math.pi / 2))
    assert points[1, 2] == pytest.approx(270.0 - 150.0)
    points, _ = guard(pair([200.0, 150.0, 270.0], -math.pi / 2, ground=100.0))
    assert points[1, 2] == pytest.approx(100.0 + 25.0)  # down to the ground's keep-out
    points, _ = guard(pair([200.0, 150.0, 270.0], -math.pi / 2, ground=245.0))
    assert points[1, 2] == pytest.approx(270.0)  # at the keep-out: holds, does not climb


def test_no_conflict_no_resolution() -> None:
    alongside = pair([0.0, 200.0, 300.0], 0.0)  # parallel, 200 m off
    assert guard(alongside)[1] == [False, False]
    away = pair([0.0, 120.0, 300.0], math.pi / 2)  # close but leaving
    assert guard(away)[1] == [False, False]
    lost = replace(alongside, fleet=alongside.fleet.copy())
    lost.fleet.active[1] = False
    assert guard(lost)[1] == [False, False]


def test_a_resolution_in_force_holds_until_the_miss_clears_the_release_margin() -> None:
    scene = pair([0.0, 120.0, 330.0], 0.0)  # alongside at 120 m: no new conflict below 100
    guided = scene.fleet.pos.copy()

    def resolving(s: Scene, previous: list[bool] | None) -> list[bool]:
        return resolve(
            s, guided, distance_m=100.0, horizon_s=4.0, resolution_m=150.0, previous=previous
        )[1]

    assert resolving(scene, None) == [False, False]
    assert resolving(scene, [False, True]) == [False, True]
    assert resolving(pair([0.0, 160.0, 330.0], 0.0), [False, True]) == [False, False]


def test_the_overtaking_vehicle_gives_way_too() -> None:
    """The leader (priority) closes on a slower wingman from behind and below: both move
    apart vertically, the leader down, the wingman up."""
    doc = {
        "target": [20000.0, 0.0, 300.0],
        "vehicles": [
            {"id": 1, "role": "leader", "position": [0.0, 0.0, 300.0], "speed": 200.0},
            {"id": 2, "role": "wingman", "position": [300.0, 10.0, 320.0], "speed": 100.0,
             "slot": [-100.0, 100.0, 0.0]},
        ],
    }  # fmt: skip
    scene = scene_from_mission(Mission.model_validate(doc))
    points, resolving = guard(scene)
    assert resolving == [True, True]
    assert points[0, 2] == pytest.approx(300.0 - 150.0)
    assert points[1, 2] == pytest.approx(320.0 + 150.0)
    ahead = replace(scene, fleet=scene.fleet.copy())
    ahead.fleet.speed[0] = 100.0  # same speed: no overtaking, no conflict
    assert guard(ahead)[1] == [False, False]


def test_resolutions_and_margins_may_be_per_vehicle_and_differ_up_and_down() -> None:
    """An ArduPlane climbs or sinks at most TECS_CLMB_MAX / TECS_SINK_MAX: it is asked only
    that times the horizon (``gcs_ppf.guidance.airframe.guard_tuning``), up and down apiece."""
    up = pair([200.0, 150.0, 330.0], -math.pi / 2)
    guided = up.fleet.pos + np.array([1500.0, 0.0, 0.0])
    per = np.array([150.0, 63.5])
    points, resolving = resolve(
        up, guided, distance_m=np.array([100.0, 100.0]), horizon_s=12.7, resolution_m=per,
        resolution_down_m=np.array([150.0, 40.0]),
    )  # fmt: skip
    assert resolving == [False, True]
    assert points[1, 2] == pytest.approx(330.0 + 63.5)
    down = pair([200.0, 150.0, 270.0], -math.pi / 2)
    points, _ = resolve(
        down, down.fleet.pos.copy(), distance_m=100.0, horizon_s=12.7, resolution_m=per,
        resolution_down_m=np.array([150.0, 40.0]),
    )  # fmt: skip
    assert points[1, 2] == pytest.approx(270.0 - 40.0)
    # the giving-way vehicle's own distance decides: a small margin sees no conflict
    alongside = pair([0.0, 120.0, 300.0], 0.0)
    _, resolving = resolve(
        alongside, alongside.fleet.pos.copy(), distance_m=np.array([200.0, 100.0]),
        horizon_s=4.0, resolution_m=150.0,
    )  # fmt: skip
    assert resolving == [False, False]
    _, resolving = resolve(
        alongside, alongside.fleet.pos.copy(), distance_m=np.array([100.0, 130.0]),
        horizon_s=4.0, resolution_m=150.0,
    )  # fmt: skip
    assert resolving == [False, True]


def test_two_vehicles_flying_formation_are_left_to_the_planner() -> None:
    """As TCAS in formation flight: the same converging pair, both in formation (the leader
    and a wingman near its slot), gets no resolution; one of them out of it, it does."""
    scene = pair([200.0, 150.0, 330.0], -math.pi / 2)
    guided = scene.fleet.pos + np.array([1500.0, 0.0, 0.0])
    kw = {"distance_m": 100.0, "horizon_s": 4.0, "resolution_m": 150.0}
    _, both = resolve(scene, guided, in_formation=[True, True], **kw)  # type: ignore[arg-type]
    assert both == [False, False]
    _, one = resolve(scene, guided, in_formation=[True, False], **kw)  # type: ignore[arg-type]
    assert one == [False, True]


def test_the_formation_tolerance_keeps_the_closest_slots_a_safe_distance_apart() -> None:
    slots = np.array([[-100.0, 100.0, 0.0], [-100.0, -100.0, 0.0], [-200.0, 200.0, 0.0]])
    tol = formation_tolerance_m(slots, 50.0)
    assert tol == pytest.approx((math.hypot(100.0, 100.0) - 50.0) / 2.0)
    assert formation_tolerance_m(np.array([[-50.0, 0.0, 0.0]]), 50.0) == 0.0  # no room

"""The compiled kernel agrees with the plain-numpy reference, step by step."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gcs_ppf.mission import Mission, load_mission_file
from gcs_ppf.offline.plan import PlanRun, plan_mission
from gcs_ppf.offline.sweep.families import FEASIBLE
from gcs_ppf.offline.sweep.scenes import draw_scene
from gcs_ppf.planning.planner import Trajectory, advance
from gcs_ppf.planning.ppf.kernel import YIELD_BACK_TURNS, influence_radius, teammate_conflict
from gcs_ppf.planning.ppf.reference import reference_step
from gcs_ppf.planning.ppf.repulsion import CONFLICT
from gcs_ppf.planning.scene import Fleet, Scene, scene_from_mission

EXAMPLES = Path(__file__).resolve().parents[4] / "examples"
BREACHES = Path(__file__).resolve().parents[3] / "data" / "breaches"


def _state_at(scene: Scene, tr: Trajectory, k: int) -> Scene:
    """The state of step ``k`` of a plan ``tr`` made from ``scene``."""
    f = scene.fleet
    fleet = Fleet(f.ids, tr.pos[k].copy(), tr.pitch[k].copy(), tr.yaw[k].copy(),
                  tr.speed[k].copy(), f.slot, f.rank, f.active)  # fmt: skip
    return Scene(fleet, scene.obstacles.at(float(tr.t[k])), scene.target, scene.limits)


def _agree_step_by_step(scene: Scene, tr: Trajectory, dt: float, n_records: int) -> set[int]:
    """Check one kernel step against the reference from ``n_records`` states of the plan
    ``tr`` made from ``scene``; the PPF states seen."""
    return _agree_at(scene, tr, dt, np.linspace(0, len(tr) - 2, n_records).astype(int))


def _agree_at(scene: Scene, tr: Trajectory, dt: float, records: np.ndarray) -> set[int]:
    """Check one kernel step against the reference from the states ``records`` of the plan
    ``tr`` made from ``scene``; the PPF states seen."""
    states_seen: set[int] = set()
    for k in records:
        s = _state_at(scene, tr, int(k))
        f, o = s.fleet, s.obstacles
        ours = advance(s, dt, 1)
        pos, pitch, yaw, speed, state = reference_step(
            f.pos,
            f.pitch,
            f.yaw,
            f.speed,
            f.slot,
            f.rank,
            f.active,
            o.center,
            o.radius,
            o.velocity,
            s.target,
            s.limits,
            dt,
        )
        got = ours.scene.fleet
        assert np.allclose(got.pos, pos, atol=1e-7), k
        assert np.allclose(got.speed, speed, atol=1e-7), k
        assert np.allclose(got.pitch, pitch, atol=1e-9), k
        assert np.allclose(np.angle(np.exp(1j * (got.yaw - yaw))), 0.0, atol=1e-9), k
        assert np.array_equal(ours.trajectory.state[0], state), k
        states_seen.update(state.tolist())
    return states_seen


@pytest.mark.parametrize("scene", ["table2_ppf", "table3_ppf"])
def test_one_step_from_states_along_the_paper_plans(
    scene: str, request: pytest.FixtureRequest
) -> None:
    run: PlanRun = request.getfixturevalue(scene)
    assert {1, 3} <= _agree_step_by_step(run.scene, run.trajectory, run.dt, 400)


def test_one_step_agrees_while_a_vehicle_gives_way_back() -> None:
    """The kept breach (tests/data/breaches): wingman 2 gives way back to wingman 3 (of
    lower priority) just before they pass; the reference agrees on every step near it."""
    mission = load_mission_file(BREACHES / "feasible_ground_49_6m.json")
    scene = scene_from_mission(mission)
    tr = advance(scene, mission.planner.dt, 1500).trajectory  # 15 s
    gap = np.linalg.norm(tr.pos[:, 1] - tr.pos[:, 2], axis=1)
    near = np.flatnonzero(gap < 300.0)
    near = near[near < len(tr) - 1]
    assert any(_gives_way_back(scene, tr, int(k), mission.planner.dt) for k in near)
    _agree_at(scene, tr, mission.planner.dt, near)


@pytest.mark.parametrize(
    ("name", "start", "end"),
    [("overtake_24_1m.json", 3350, 3700), ("feasible_ground_49_6m.json", 0, 1500)],
)
def test_one_step_agrees_while_giving_way_to_a_teammate_first(
    name: str, start: int, end: int
) -> None:
    """The kept breaches: a vehicle in a teammate conflict inside an obstacle's influence
    (``teammates_first``: wingman 2 overtaking wingman 4 round the sphere, 33.5–37 s) and
    one in a conflict above the ground (no room); the reference agrees on those steps."""
    mission = load_mission_file(BREACHES / name)
    scene = scene_from_mission(mission)
    tr = advance(scene, mission.planner.dt, end + 1).trajectory
    _agree_at(scene, tr, mission.planner.dt, np.arange(start, end, 5))


def test_one_step_agrees_while_a_diving_vehicle_turns_round_an_obstacle() -> None:
    """Feasible sweep, seed 2, scene 84105: wingman 4, diving at 45°, turns sideways round
    an obstacle and pitches for the wanted elevation (``trend_matrix``), 81–86 s."""
    scene = scene_from_mission(draw_scene(FEASIBLE, 2, 84105))
    tr = advance(scene, 0.01, 8601).trajectory
    _agree_at(scene, tr, 0.01, np.arange(8100, 8600, 4))


def test_one_step_agrees_while_handing_back_to_the_obstacles() -> None:
    """Feasible sweep, seed 2, scene 47127: wingman 3 gives way to wingman 2 inside an
    obstacle's influence until the room runs out (``HAND_BACK_TURNS``), then the obstacles
    first, 19–23 s."""
    scene = scene_from_mission(draw_scene(FEASIBLE, 2, 47127))
    tr = advance(scene, 0.01, 2301).trajectory
    _agree_at(scene, tr, 0.01, np.arange(1900, 2300, 2))


def _gives_way_back(scene: Scene, tr: Trajectory, k: int, dt: float) -> bool:
    """Whether wingman 2 (index 1) gives way back to wingman 3 (index 2) in record ``k``."""
    lim, speed = scene.limits, tr.speed[k]
    cp = np.cos(tr.pitch[k])
    vel = speed[:, None] * np.stack([cp * np.cos(tr.yaw[k]), cp * np.sin(tr.yaw[k]),
                                     np.sin(tr.pitch[k])], axis=1)  # fmt: skip
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    reach = influence_radius(speed[2], omega, lim.safe_distance_uav) + speed[2] * dt
    d, w = tr.pos[k, 2] - tr.pos[k, 1], vel[1] - vel[2]
    kind, _, _, _ = teammate_conflict(d[0], d[1], d[2], w[0], w[1], w[2], speed[2], speed[1],
                                      reach, lim, dt, False, YIELD_BACK_TURNS)  # fmt: skip
    return bool(kind == CONFLICT)


@pytest.mark.parametrize("name", ["paper_table2.json", "paper_table3.json"])
def test_one_step_agrees_under_an_airframes_flight_path_limits(name: str) -> None:
    """ArduPlane's default pitch limits (+20°, −25°): the plan keeps to them."""
    scene = scene_from_mission(load_mission_file(EXAMPLES / name))
    limits = scene.limits._replace(max_climb_angle=math.radians(20.0),
                                   max_dive_angle=math.radians(25.0))  # fmt: skip
    scene = replace(scene, limits=limits)
    tr = advance(scene, 0.01, 6000).trajectory  # 60 s
    assert tr.pitch.max() <= math.radians(20.0) + 1e-9
    assert tr.pitch.min() >= -math.radians(25.0) - 1e-9
    assert 1 in _agree_step_by_step(scene, tr, 0.01, 150)


def test_one_step_agrees_in_held_turns_where_the_wingmen_lead_the_slots_swing() -> None:
    """ArduPlane's route with its 90° and 180° turns held (``turns: "hold"``): from states
    along its plan, the leader turning, the wingmen leading their slots round with it."""
    run = plan_mission(load_mission_file(EXAMPLES / "arduplane_route_uturn_3.json"))
    tr = run.trajectory
    assert run.scene.limits.leader_turn_rate < math.inf
    rate = np.abs(np.diff(np.unwrap(tr.yaw[:, 0]))) / np.diff(tr.t)
    turning = np.flatnonzero(rate > math.radians(1.0))[:: max(1, len(tr) // 4000)]
    assert turning.size > 20
    _agree_at(run.scene, tr, run.dt, turning[np.linspace(0, turning.size - 1, 60).astype(int)])


def test_one_step_agrees_while_a_wingman_round_an_obstacle_gives_ground_back() -> None:
    """The five-vehicle line abreast, each vehicle avoiding on its own: the leader and the
    wingmen on its right go round the sphere (56–80 s), the slots placed along the
    leader's way to its target while it avoids (``formation_frame: "course"``), a
    wingman with its slot behind it giving the ground back."""
    doc = json.loads((EXAMPLES / "arduplane_5.json").read_text())
    doc = {**doc, "formation_frame": "course", "obstacle_passage": "each"}
    run = plan_mission(Mission.model_validate(doc))
    tr = run.trajectory
    passage = np.flatnonzero((tr.t >= 56.0) & (tr.t <= 80.0))
    _agree_at(run.scene, tr, run.dt, passage[np.linspace(0, passage.size - 2, 80).astype(int)])


def test_one_step_agrees_where_the_pad_is_dropped_for_the_targets_sake() -> None:
    """Table 3 passed as a formation: its target lies inside the pad's reach round the last
    sphere (``repulsion.padding``), so that sphere is passed the paper's way near the end,
    the leader the paper's leader while it repels it."""
    doc = json.loads((EXAMPLES / "paper_table3.json").read_text())
    run = plan_mission(Mission.model_validate({**doc, "obstacle_passage": "formation"}))
    tr = run.trajectory
    late = np.flatnonzero(tr.t >= 50.0)
    assert late.size > 100
    _agree_at(run.scene, tr, run.dt, late[np.linspace(0, late.size - 2, 80).astype(int)])


def test_one_step_agrees_while_the_leader_passes_with_its_whole_formation() -> None:
    """The five-vehicle line abreast with ``obstacle_passage: "formation"``: the leader's
    keep-out padded by its farthest slot, turning round the sphere as its formation follows
    (held turns), from its first turn away to its last."""
    doc = json.loads((EXAMPLES / "arduplane_5.json").read_text())
    run = plan_mission(Mission.model_validate({**doc, "obstacle_passage": "formation"}))
    tr = run.trajectory
    assert run.scene.limits.leader_keep_out_pad > 0.0
    passage = np.flatnonzero(tr.avoiding[:, 0])
    assert passage.size > 100
    _agree_at(run.scene, tr, run.dt, passage[np.linspace(0, passage.size - 2, 80).astype(int)])

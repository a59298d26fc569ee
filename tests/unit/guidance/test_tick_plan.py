"""The tick's plan: the closed-loop planning margin on the teammates' safe distance."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_ppf.guidance.online import VehicleState, scene_now
from gcs_ppf.guidance.tick_plan import teammate_margin_m
from gcs_ppf.mission import load_mission_file
from gcs_ppf.planning.scene import scene_from_mission
from tests.conftest import EXAMPLES


@pytest.mark.parametrize(
    ("name", "on_teammates"),
    [
        ("arduplane_3", 0.0),
        ("arduplane_formation_takeoff_5", 0.0),
        ("paper_table2", 45.0),
        ("paper_table3", (100.0 * math.sqrt(2.0) - 2.0 * 50.0) / 4.0),  # slots 100·√2 m apart
    ],
)
def test_the_teammates_margin_is_dropped_at_arduplanes_scale_only(
    name: str, on_teammates: float
) -> None:
    """ArduPlane's scale (the plan's speed changes flown): the slots of a line abreast, 141 m
    apart, lay inside each neighbour's conflict band with the margin and never formed; the
    obstacles keep it. The paper's scale keeps it on both, on the teammates within what the
    slots leave (Table 3's)."""
    mission = load_mission_file(EXAMPLES / f"{name}.json")
    assert teammate_margin_m(mission, 45.0) == pytest.approx(on_teammates)
    states = {v.id: VehicleState((v.position[0], v.position[1], v.position[2]), 0.0, v.yaw,
                                 mission.limits.v_init) for v in mission.vehicles}  # fmt: skip
    obstacles = scene_from_mission(mission).obstacles
    lim = scene_now(mission, states, set(states), obstacles, 45.0,
                    teammate_margin_m=teammate_margin_m(mission, 45.0)).limits  # fmt: skip
    assert lim.safe_distance_uav == pytest.approx(mission.limits.safe_distance_uav + on_teammates)
    assert lim.safe_distance_obstacle == pytest.approx(mission.limits.safe_distance_obstacle + 45.0)


@pytest.mark.parametrize("name", ["paper_table2", "paper_table3"])
def test_the_teammates_margin_never_puts_the_slots_inside_each_others_keep_out(name: str) -> None:
    """With the whole 100 m on Table 3's 50 m, slots 141 m apart could never be flown; with
    half of what they have beyond the safe distance (45.7 m), two wingmen joining them still
    counted each other a conflict (twice the widened safe distance, a turn allowed for)."""
    mission = load_mission_file(EXAMPLES / f"{name}.json")
    margin = teammate_margin_m(mission, 100.0)
    slots = np.array([[0.0, 0.0, 0.0], *(w.slot for w in mission.wingmen)])
    gaps = np.linalg.norm(slots[:, None] - slots[None], axis=-1)[np.triu_indices(len(slots), 1)]
    assert 2.0 * (mission.limits.safe_distance_uav + margin) < gaps.min()
    assert margin == pytest.approx(min(100.0, (gaps.min() - 2.0 * 50.0) / 4.0))

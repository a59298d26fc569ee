"""The tick's plan: the closed-loop planning margin on the obstacles, not the teammates."""

from __future__ import annotations

import pytest

from gcs_ppf.guidance.online import VehicleState, scene_now
from gcs_ppf.guidance.tick_plan import TEAMMATE_MARGIN_M
from gcs_ppf.mission import load_mission_file
from gcs_ppf.planning.scene import scene_from_mission
from tests.conftest import EXAMPLES


@pytest.mark.parametrize("name", ["arduplane_3", "arduplane_formation_takeoff_5", "paper_table3"])
def test_the_planning_margin_widens_the_obstacles_keep_out_only(name: str) -> None:
    """The slots of Table 3 and of a line abreast, 141 m apart, lay inside each neighbour's
    conflict band with a margin on the teammates' safe distance and never formed; the
    obstacles keep the whole margin."""
    mission = load_mission_file(EXAMPLES / f"{name}.json")
    states = {v.id: VehicleState((v.position[0], v.position[1], v.position[2]), 0.0, v.yaw,
                                 mission.limits.v_init) for v in mission.vehicles}  # fmt: skip
    obstacles = scene_from_mission(mission).obstacles
    lim = scene_now(mission, states, set(states), obstacles, 45.0,
                    teammate_margin_m=TEAMMATE_MARGIN_M).limits  # fmt: skip
    assert lim.safe_distance_uav == pytest.approx(mission.limits.safe_distance_uav)
    assert lim.safe_distance_obstacle == pytest.approx(mission.limits.safe_distance_obstacle + 45.0)

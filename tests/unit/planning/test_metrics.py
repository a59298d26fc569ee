"""Plan metrics computed from the trajectory alone (CONVENTIONS §4), here the ground."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from gcs_ppf.mission import Mission
from gcs_ppf.offline.plan import flight_context, plan_mission
from gcs_ppf.planning.metrics import compute_metrics
from gcs_ppf.planning.scene import scene_from_mission

LOW_FLIGHT = Mission.model_validate({
    "ground": 0.0,
    "planner": {"max_time": 30.0},
    "target": [5000.0, 0.0, 40.0],
    "vehicles": [{"id": 1, "role": "leader", "position": [0.0, 0.0, 400.0], "pitch": -0.5}],
})  # fmt: skip


def test_ground_clearance_is_the_lowest_height_and_a_dip_below_it_is_a_collision() -> None:
    plan = plan_mission(LOW_FLIGHT)
    tr = plan.trajectory
    lowest = float(tr.pos[:, 0, 2].min())
    assert plan.metrics["min_ground_clearance_m"] == pytest.approx(lowest)
    assert plan.metrics["collisions"] == 0
    sunk = replace(tr, pos=tr.pos - np.array([0.0, 0.0, lowest - 10.0]))  # 10 m up at worst
    context = flight_context(LOW_FLIGHT, scene_from_mission(LOW_FLIGHT))
    m = compute_metrics(sunk, context)
    assert m["min_ground_clearance_m"] == pytest.approx(10.0)
    assert m["collisions"] == 1
    assert m["per_vehicle"]["1"]["collisions"] == 1


def test_no_ground_no_ground_clearance() -> None:
    free = plan_mission(LOW_FLIGHT.model_copy(update={"ground": None}))
    assert free.metrics["min_ground_clearance_m"] is None

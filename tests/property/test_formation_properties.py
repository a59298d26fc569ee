"""Formation maintenance: a wingman on the wrong side of the leader crosses to its slot."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from gcs_ppf.mission import Mission
from gcs_ppf.offline.plan import plan_mission
from gcs_ppf.planning.metrics import local_target_points

FORM_WITHIN_S = 30.0


def wrong_side(across: float, back: float, above: float, slot_side: float) -> Mission:
    """A leader flying east and a wingman beside it, ``across`` metres on the other side of
    the leader's track from its slot (100 m to the left or right and 100 m behind)."""
    slot = [-100.0, 100.0 * slot_side, 0.0]
    wingman = [back, -across * slot_side, 1000.0 + above]
    return Mission.model_validate(
        {
            "planner": {"max_time": 60.0},
            "target": [30000.0, 0.0, 1000.0],
            "vehicles": [
                {"id": 1, "role": "leader", "position": [0.0, 0.0, 1000.0], "yaw": 0.0},
                {"id": 2, "role": "wingman", "position": wingman, "yaw": 0.0, "slot": slot},
            ],
        }
    )


@given(
    across=st.floats(60.0, 300.0),
    back=st.floats(-200.0, -60.0),
    above=st.floats(-60.0, 60.0),
    slot_side=st.sampled_from([-1.0, 1.0]),
)
def test_a_wingman_on_the_wrong_side_crosses_to_its_slot(
    across: float, back: float, above: float, slot_side: float
) -> None:
    """It crosses behind or above the leader and reaches its slot within 30 s, keeping the
    safe distance (the planner before the crossing rule stopped at the conflict band)."""
    mission = wrong_side(across, back, above, slot_side)
    run = plan_mission(mission)
    tr = run.trajectory
    gap = np.linalg.norm(local_target_points(tr, run.scene.fleet.slot)[:, 1] - tr.pos[:, 1], axis=1)
    formed = gap <= mission.limits.target_accuracy
    assert formed.any()
    assert tr.t[np.argmax(formed)] <= FORM_WITHIN_S
    assert run.metrics["min_separation_m"] >= mission.limits.safe_distance_uav
    assert formed[-1]

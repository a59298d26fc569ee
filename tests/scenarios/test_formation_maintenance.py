"""Formation maintenance after the obstacles (issue 12, item 1): the wingmen return to their
slots, crossing behind or above a teammate, and hold them to the target."""

from __future__ import annotations

import numpy as np
import pytest

from gcs_ppf.mission import Mission, load_mission_file
from gcs_ppf.offline.plan import PlanRun, plan_mission
from gcs_ppf.planning.metrics import local_target_points
from tests.conftest import EXAMPLES

HELD_S = 10.0  # as tests/integration/test_arduplane.py asks of the flown formation


def all_formed(run: PlanRun, accuracy: float) -> np.ndarray:
    """[K] whether every wingman is within ``accuracy`` of its local target point (Eq. 6)."""
    tr = run.trajectory
    gap = np.linalg.norm(local_target_points(tr, run.scene.fleet.slot) - tr.pos, axis=-1)
    formed: np.ndarray = (gap[:, 1:] <= accuracy).all(axis=1)
    return formed


def longest_held_s(t: np.ndarray, formed: np.ndarray) -> float:
    """The longest stretch of time over which ``formed`` holds at every record."""
    best, start = 0.0, None
    for k in range(len(t)):
        if formed[k] and start is None:
            start = t[k]
        if start is not None and (not formed[k] or k == len(t) - 1):
            best = max(best, float((t[k] if formed[k] else t[k - 1]) - start))
            start = None
    return best


def test_table3_forms_before_the_leader_arrives_and_holds_it(
    table3: Mission, table3_ppf: PlanRun
) -> None:
    """The paper: "the UAVs still rapidly enter the overall formation maintenance stage from
    68.29 s" (flight 68.5 s).  Every wingman is in its slot at once before the arrival and
    from then on to the target, within 72 s."""
    m = table3_ppf.metrics
    t = table3_ppf.trajectory.t
    formed = all_formed(table3_ppf, table3.limits.target_accuracy)
    assert m["reached"]
    assert m["flight_time_s"] <= 72.0
    assert m["formation_time_s"] is not None
    assert m["formation_time_s"] < m["flight_time_s"]
    assert formed[-1]  # in formation at the arrival
    since = t[len(t) - np.argmin(formed[::-1])] if not formed.all() else t[0]
    assert m["flight_time_s"] - since >= 1.0  # and held for the last second at least


def test_table3_wingmen_hold_their_slots_height_while_the_leader_descends(
    table3_ppf: PlanRun,
) -> None:
    """On the final descent no wingman sits off its slot's height (Eq. 6: the slot's place
    in the leader's frame; before, wingmen stayed 25 m above it across the leader's track)."""
    tr = table3_ppf.trajectory
    last = tr.t >= tr.t[-1] - 1.0
    gap = local_target_points(tr, table3_ppf.scene.fleet.slot)[last] - tr.pos[last]
    assert np.abs(gap[:, 1:, 2]).max() <= 10.0


def test_table2_forms_no_later_than_before(table2_ppf: PlanRun) -> None:
    assert table2_ppf.metrics["formation_time_s"] <= 27.0


@pytest.mark.parametrize(
    "name",
    ["arduplane_3", "arduplane_5", "arduplane_formation_takeoff_3",
     "arduplane_formation_takeoff_5"],
)  # fmt: skip
def test_arduplane_missions_form_and_hold_past_the_obstacle(name: str) -> None:
    """The missions flown on real ArduPlane (line abreast: wingman 3's slot lies in the
    obstacle's keep-out; it went round the far side and stayed across the leader's track):
    planned offline, every wingman is in its slot at once for HELD_S and at the arrival."""
    mission = load_mission_file(EXAMPLES / f"{name}.json")
    run = plan_mission(mission)
    lim = mission.limits
    formed = all_formed(run, lim.target_accuracy)
    assert run.metrics["reached"]
    assert formed[-1]
    assert longest_held_s(run.trajectory.t, formed) >= HELD_S
    assert run.metrics["min_separation_m"] >= lim.safe_distance_uav
    assert run.metrics["min_obstacle_clearance_m"] >= lim.safe_distance_obstacle

"""Table 3 scene (obstacles, tighter formation): safety and arrival."""

from __future__ import annotations

import numpy as np

from gcs_ppf.mission import Mission
from gcs_ppf.offline.plan import PlanRun
from tests.checks import assert_within_kinematic_limits

PAPER_FLIGHT_TIME_S = 68.5


def test_leader_reaches_target_in_about_the_papers_time(table3_ppf: PlanRun) -> None:
    m = table3_ppf.metrics
    assert m["reached"]
    assert 0.8 * PAPER_FLIGHT_TIME_S <= m["flight_time_s"] <= 1.3 * PAPER_FLIGHT_TIME_S


def test_safety_distances_hold(table3: Mission, table3_ppf: PlanRun) -> None:
    m = table3_ppf.metrics
    assert m["min_separation_m"] >= table3.limits.safe_distance_uav
    assert m["min_obstacle_clearance_m"] >= table3.limits.safe_distance_obstacle
    assert m["collisions"] == 0


def test_kinematic_limits_hold(table3: Mission, table3_ppf: PlanRun) -> None:
    assert_within_kinematic_limits(table3_ppf.metrics, table3.limits)


def test_formation_breaks_around_obstacles(table3_ppf: PlanRun) -> None:
    """Wingmen avoid obstacles (leaving their slots) and rejoin them afterwards."""
    tr = table3_ppf.trajectory
    assert tr.avoiding[:, 1:].any()
    wingman_formed = tr.formed[:, 1:]
    assert wingman_formed[-1].sum() >= 1
    assert (np.diff(wingman_formed.astype(int), axis=0) == -1).any()  # a wingman left its slot

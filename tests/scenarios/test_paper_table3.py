"""Table 3 scene (obstacles, tighter formation): safety and arrival."""

from __future__ import annotations

import numpy as np

from gcs_ppf.mission import Mission
from gcs_ppf.offline import PlanRun

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
    lim = table3.limits
    m = table3_ppf.metrics
    assert m["max_yaw_rate_rad_s"] <= lim.max_yaw_rate + 1e-9
    assert m["max_pitch_rate_rad_s"] <= lim.max_pitch_rate + 1e-9
    assert lim.v_min - 1e-9 <= m["min_speed_m_s"] <= m["max_speed_m_s"] <= lim.v_max + 1e-9
    assert m["max_accel_m_s2"] <= lim.accel + 1e-6
    assert m["max_decel_m_s2"] <= lim.decel + 1e-6


def test_formation_breaks_around_obstacles(table3_ppf: PlanRun) -> None:
    """Wingmen avoid obstacles (leaving their slots) and rejoin them afterwards."""
    tr = table3_ppf.trajectory
    assert tr.avoiding[:, 1:].any()
    wingman_formed = tr.formed[:, 1:]
    assert wingman_formed[-1].sum() >= 1
    assert (np.diff(wingman_formed.astype(int), axis=0) == -1).any()  # a wingman left its slot

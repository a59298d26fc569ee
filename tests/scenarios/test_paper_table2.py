"""Table 2 scene (no obstacles): formation, kinematic limits, initial heading."""

from __future__ import annotations

import math

import numpy as np

from gcs_ppf.mission import Mission
from gcs_ppf.offline.plan import PlanRun
from gcs_ppf.planning.metrics import local_target_points
from tests.checks import assert_within_kinematic_limits

PAPER_FORMATION_TIME_S = 22.0


def test_leader_reaches_target(table2_ppf: PlanRun) -> None:
    m = table2_ppf.metrics
    assert m["reached"]
    assert m["leader_distance_to_target_m"] <= 10.0
    assert m["collisions"] == 0


def test_wingmen_form_near_the_papers_time_and_stay_formed(
    table2: Mission, table2_ppf: PlanRun
) -> None:
    m = table2_ppf.metrics
    formed_at = m["formation_time_s"]
    assert formed_at is not None
    assert formed_at <= PAPER_FORMATION_TIME_S * 1.5  # "by about the paper's 22 s"
    tr = table2_ppf.trajectory
    gap = np.linalg.norm(local_target_points(tr, table2_ppf.scene.fleet.slot) - tr.pos, axis=-1)
    after = tr.t >= formed_at
    assert gap[after][:, 1:].max() <= table2.limits.target_accuracy


def test_every_step_respects_the_kinematic_limits(table2: Mission, table2_ppf: PlanRun) -> None:
    assert_within_kinematic_limits(table2_ppf.metrics, table2.limits)


def test_leader_leaves_the_start_along_its_initial_heading(
    table2_ppf: PlanRun, table2_apf: PlanRun
) -> None:
    """Fig. 5b: PPF respects the initial heading (yaw 0, east); APF jumps to the target."""
    omega = math.pi / 6

    def first_turn(run: PlanRun, seconds: float) -> tuple[float, float]:
        """Heading of the leader's first step, and its yaw after ``seconds``."""
        tr = run.trajectory
        k = int(np.searchsorted(tr.t, seconds))
        step = tr.pos[1, 0] - tr.pos[0, 0]
        return abs(math.atan2(step[1], step[0])), abs(float(tr.yaw[k, 0]))

    ppf_first_step, ppf_yaw_1s = first_turn(table2_ppf, 1.0)
    apf_first_step, _ = first_turn(table2_apf, 1.0)
    assert ppf_first_step <= omega * table2_ppf.dt + 1e-9
    assert ppf_yaw_1s <= omega * 1.0 + 1e-9
    assert apf_first_step > math.radians(30)  # straight at the target, 48° to the left


def test_leader_waits_then_leads(table2_ppf: PlanRun) -> None:
    """Fig. 8: the leader flies slowly (s3) until the formation forms, then accelerates."""
    tr = table2_ppf.trajectory
    formed_at = table2_ppf.metrics["formation_time_s"]
    before = (tr.t > 0) & (tr.t < formed_at - 0.1)  # record 0 is the initial state
    assert np.all(tr.state[before, 0] == 3)
    assert tr.speed[before, 0].max() <= 100.0 + 1e-9
    assert tr.speed[-1, 0] > 250.0

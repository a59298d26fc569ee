"""A vehicle overtaking a teammate gives way, whatever their priorities (rules of the air).

The paper's priorities (Eq. 12–13) leave it to the overtaken one alone; from v_min it cannot
turn out of the way of a faster teammate closing from behind.  Found by the sweep of
10,000 feasible scenes: scene 7198 of seed 0 came to 41.9 m (safe 50 m).
"""

from __future__ import annotations

import math

import pytest

from gcs_ppf.offline.plan import plan_mission
from gcs_ppf.offline.sweep.families import FEASIBLE
from gcs_ppf.offline.sweep.scenes import draw_scene
from gcs_ppf.planning.ppf.kernel import overtaking


def test_scene_7198_keeps_the_safe_distance() -> None:
    mission = draw_scene(FEASIBLE, 0, 7198)
    m = plan_mission(mission).metrics
    assert m["min_separation_m"] >= mission.limits.safe_distance_uav
    assert m["min_obstacle_clearance_m"] >= mission.limits.safe_distance_obstacle
    assert m["reached"]


@pytest.mark.parametrize(
    ("bearing_deg", "expected"),
    [(180.0, True), (180.0 - 69.0, True), (180.0 + 69.0, True), (180.0 - 71.0, False),
     (90.0, False), (0.0, False)],
)  # fmt: skip
def test_overtaking_is_coming_up_within_70_degrees_of_the_tail(
    bearing_deg: float, expected: bool
) -> None:
    """The teammate flies along +x at 100 m/s, we at 150 m/s the same way; we are 500 m
    from it at the bearing given (0° dead ahead of it, 180° dead astern)."""
    b = math.radians(bearing_deg)
    d = (500.0 * math.cos(b), 500.0 * math.sin(b), 0.0)
    assert overtaking(*d, 100.0, 0.0, 0.0, 150.0, 0.0, 0.0) is expected


def test_a_teammate_no_slower_along_its_track_is_not_overtaken() -> None:
    astern = (-500.0, 0.0, 0.0)
    assert overtaking(*astern, 100.0, 0.0, 0.0, 150.0, 0.0, 0.0)
    assert not overtaking(*astern, 100.0, 0.0, 0.0, 100.0, 0.0, 0.0)  # as fast
    assert not overtaking(*astern, 100.0, 0.0, 0.0, 150.0 * 0.6, 150.0 * 0.8, 0.0)  # 90 along

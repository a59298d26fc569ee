"""The separation and clearance breaches the property tests and the sweeps drew keep both safe
distances now (docs/sweeps.md; ``repulsion.yielding_back``, ``repulsion.teammates_first``,
``steering.trend_matrix``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from gcs_ppf.mission import Mission, load_mission_file
from gcs_ppf.offline.plan import plan_mission
from gcs_ppf.offline.sweep.families import FEASIBLE
from gcs_ppf.offline.sweep.scenes import draw_scene

BREACHES = Path(__file__).resolve().parents[1] / "data" / "breaches"

# (seed, index) of the feasible family's breaches: 7198 of seed 0 (41.9 m), 3361 (49.4 m)
# and 8220 (39.4 m) of seed 1 with the planner of session 8; 3251, 8402 of seed 0 and 785,
# 1411 of seed 1 with session 6's overtaking rule (left out); of the 100,000 of seed 2,
# 52599 (17.8 m) and 97954 (48.9 m: a vehicle turned into a teammate by an obstacle's
# influence) and 84105 (17.7 m from an obstacle: a 45° dive that nodded at 45° while it
# turned sideways round it); with the rule of giving way to a teammate first, 38269
# (20.9 m) and 47127 (20.1 m from an obstacle: the hand-back to the obstacles,
# ``primitives.HAND_BACK_TURNS``).
SWEPT = [
    (0, 7198),
    (1, 3361),
    (1, 8220),
    (0, 3251),
    (0, 8402),
    (1, 785),
    (1, 1411),
    (2, 52599),
    (2, 97954),
    (2, 84105),
    (2, 38269),
    (2, 47127),
]


def _assert_kept(mission: Mission) -> None:
    m = plan_mission(mission).metrics
    assert m["min_separation_m"] >= mission.limits.safe_distance_uav
    if m["min_obstacle_clearance_m"] is not None:
        assert m["min_obstacle_clearance_m"] >= mission.limits.safe_distance_obstacle
    assert m["collisions"] == 0


@pytest.mark.parametrize("path", sorted(BREACHES.glob("*.json")), ids=lambda p: p.stem)
def test_the_kept_breach_scenes_keep_the_safe_distance(path: Path) -> None:
    """feasible_ground_49_6m.json: wingmen that turn back across each other to their slots
    behind the leader kept 49.56 m (the one of higher priority turned into the other).
    overtake_24_1m.json: wingman 2, catching up at 245 m/s, turned into wingman 4 while it
    avoided the obstacle and passed it at 24.1 m."""
    _assert_kept(load_mission_file(path))


@pytest.mark.parametrize(("seed", "index"), SWEPT)
def test_the_swept_breach_scenes_keep_the_safe_distance(seed: int, index: int) -> None:
    _assert_kept(draw_scene(FEASIBLE, seed, index))


# Of the 100,000 of seed 2 with ``obstacle_passage: "formation"``: 79277 (400 m into a
# sphere: a leader started inside the radius of its formation's turn, turning at it),
# 66308 (310 m: the repulsion of a sphere further off, summed in, held its course), 96592
# (235 m), 4750, 9877, 85712 and 773 (24.9 m).
PASSING_WHOLE = [79277, 66308, 96592, 98867, 4750, 9877, 85712, 773]


@pytest.mark.parametrize("index", PASSING_WHOLE)
def test_the_breach_scenes_passing_as_a_formation_keep_the_safe_distance(index: int) -> None:
    spec = FEASIBLE.model_copy(update={"obstacle_passage": "formation"})
    _assert_kept(draw_scene(spec, 2, index))

"""Where a run may start from: none inside a keep-out, none far from its start."""

from __future__ import annotations

from gcs_ppf.guidance.start_check import Misplaced, far_m, misplaced
from gcs_ppf.mission import Mission
from tests.conftest import EXAMPLES

TABLE3 = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())


def at_start() -> dict[int, tuple[float, float, float]]:
    return {v.id: v.position for v in TABLE3.vehicles}


def test_at_their_start_positions_nothing_keeps_the_start() -> None:
    assert misplaced(TABLE3, at_start()) == []
    assert misplaced(TABLE3, {}) == []


def test_inside_a_sphere_near_a_teammate_and_far_each_named() -> None:
    o = TABLE3.obstacles[0]
    positions = at_start()
    positions[3] = (o.center[0], o.center[1], o.center[2] + o.radius + 5.0)  # 20 m inside
    positions[5] = (positions[4][0] + 30.0, positions[4][1], positions[4][2])  # 20 m inside
    positions[1] = (positions[1][0] + far_m(TABLE3) + 1.0, positions[1][1], positions[1][2])
    found = misplaced(TABLE3, positions)
    assert Misplaced(3, "obstacle", 0, 20.0) in found
    assert Misplaced(4, "teammate", 5, 20.0) in found
    assert Misplaced(1, "far", None, round(far_m(TABLE3) + 1.0, 1)) in found
    assert found[0].words() == "vehicle 3 is 20.0 m inside the keep-out of obstacle 0"
    assert found[-1].words() == "vehicle 1 is 9001 m from its start position"

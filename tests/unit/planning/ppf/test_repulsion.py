"""Teammate conflicts (Eq. 12–13 with teammates as moving obstacles): giving way back."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_ppf.mission import Mission
from gcs_ppf.planning.ppf.primitives import AVOIDANCE_TURN_ANGLE, TRIG_COLUMNS, YIELD_BACK_TURNS
from gcs_ppf.planning.ppf.repulsion import yielding_back
from gcs_ppf.planning.scene import scene_from_mission

OMEGA = math.pi / 6


def _overtaking(gap: float, lateral: float) -> np.ndarray:
    """Vehicle 0 (higher priority) at 300 m/s ``gap`` m behind vehicle 1 (at v_min, 100 m/s,
    ``lateral`` m to its right), both flying +x; ``trig`` after ``yielding_back``."""
    scene = scene_from_mission(Mission.model_validate({"target": [9000.0, 0.0, 0.0],
        "vehicles": [{"id": 1, "role": "leader", "position": [0.0, 0.0, 0.0]}]}))  # fmt: skip
    pos = np.array([[-gap, lateral, 0.0], [0.0, 0.0, 0.0]])
    speed = np.array([300.0, 100.0])
    trig = np.zeros((2, TRIG_COLUMNS))
    trig[:, 0], trig[:, 2] = 1.0, 1.0  # level, heading +x
    trig[:, 4] = speed
    mate_start = np.array([0, 0, 1])  # vehicle 1 gives way to vehicle 0
    mates = np.array([0])
    active = np.ones(2, dtype=bool)
    formed = np.zeros(2, dtype=bool)
    yielding_back(pos, speed, trig, active, mate_start, mates, formed, scene.limits, 0.01)
    return trig


def test_a_conflict_left_near_its_closest_approach_makes_the_other_give_way_back() -> None:
    """Overtaken from behind at 200 m/s, a vehicle at v_min has not solved the conflict
    0.5 s before the closest approach: the one overtaking gives way too, away from it."""
    trig = _overtaking(100.0, 10.0)
    assert trig[0, 10] == 1.0
    assert trig[1, 10] == 0.0
    assert trig[0, 7:10] == pytest.approx([0.0, 1.0, 0.0])  # away from vehicle 1 (-y)


@pytest.mark.parametrize("lateral", [10.0, 300.0])
def test_no_giving_way_back_early_or_on_a_clear_miss(lateral: float) -> None:
    """2 s before the closest approach (beyond ``YIELD_BACK_TURNS``) only the vehicle of
    lower priority gives way; a miss of 300 m is no conflict at all."""
    late = YIELD_BACK_TURNS * AVOIDANCE_TURN_ANGLE / OMEGA
    assert late < 2.0
    assert _overtaking(400.0, lateral)[:, 10].sum() == 0.0
    assert _overtaking(100.0, 300.0)[:, 10].sum() == 0.0

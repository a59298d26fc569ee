"""Teammate conflicts (Eq. 12–13 with teammates as moving obstacles): giving way back, and
giving way to a teammate first while the obstacles leave room."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_ppf.mission import Mission
from gcs_ppf.planning.ppf.primitives import (
    AVOIDANCE_TURN_ANGLE,
    TRIG_COLUMNS,
    YIELD_BACK_TURNS,
    influence_radius,
    room_to_turn_away,
)
from gcs_ppf.planning.ppf.repulsion import teammates_first, yielding_back
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


@pytest.mark.parametrize("speed", [100.0, 300.0])
@pytest.mark.parametrize("keep_out", [125.0, 900.0])
def test_room_to_turn_away_head_on_ends_at_the_influence_radius(
    speed: float, keep_out: float
) -> None:
    """Head-on (no lateral offset) the room ends where the influence radius says a full
    turn just clears (Fig. 2), ``travel`` metres further out."""
    rho = speed / OMEGA
    r = influence_radius(speed, OMEGA, keep_out)
    assert room_to_turn_away(r + 10.0 + 1e-6, 0.0, 0.0, -1.0, 0.0, 0.0, 10.0, rho, keep_out)
    assert not room_to_turn_away(r + 10.0 - 1e-3, 0.0, 0.0, -1.0, 0.0, 0.0, 10.0, rho, keep_out)


def test_room_to_turn_away_off_axis_and_when_not_closing() -> None:
    """Abeam of the keep-out, or flying away from it, a vehicle has room; off the axis it
    has room nearer than head-on: the circle turning away keeps ρ + keep-out from the centre."""
    rho, keep = 300.0 / OMEGA, 500.0
    r = influence_radius(300.0, OMEGA, keep)
    assert room_to_turn_away(0.0, keep + 1.0, 0.0, 1.0, 0.0, 0.0, 9.0, rho, keep)  # abeam
    assert room_to_turn_away(-600.0, 0.0, 0.0, -1.0, 0.0, 0.0, 9.0, rho, keep)  # flying away
    off = math.radians(30.0)
    d = 0.8 * r  # inside the head-on radius, 30° off the axis
    pos = (d * math.cos(off), d * math.sin(off), 0.0)
    centre = math.hypot(pos[0], pos[1] + rho)  # circle turning away (to +y)
    assert room_to_turn_away(*pos, -1.0, 0.0, 0.0, 0.0, rho, keep) == (centre - rho >= keep)


def test_teammates_first_only_with_room() -> None:
    """With room a teammate's push alone repels and no obstacle is steered away from; without
    room, or with no teammate repelling, the obstacles first (``obstacles_first``)."""
    push, obstacle = (-0.5, 0.5, 0.0), (1.0, 0.0, 0.0)
    assert teammates_first(*push, True, *obstacle, True) == (-0.5, 0.5, 0.0, 0.0, 0.0, 0.0)
    assert teammates_first(*push, True, *obstacle, False) == pytest.approx(
        (1.0, 0.5, 0.0, 1.0, 0.0, 0.0)
    )
    assert teammates_first(0.0, 0.0, 0.0, False, *obstacle, True) == (1.0, 0.0, 0.0, 1.0, 0.0, 0.0)

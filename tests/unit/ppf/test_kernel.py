"""The PPF kernel's equation groups, one at a time."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from gcs_ppf.mission import Mission
from gcs_ppf.planner import advance
from gcs_ppf.ppf.kernel import (
    MAX_AVOID_PITCH,
    S2_LOCAL_MINIMUM,
    braking_speed,
    influence_radius,
    to_vcs,
    trend,
)
from gcs_ppf.scene import scene_from_mission

OMEGA = math.pi / 6


def solo(
    position: list[float], yaw: float, target: list[float], obstacles: list[dict[str, Any]]
) -> Mission:
    return Mission.model_validate(
        {
            "target": target,
            "vehicles": [{"id": 1, "role": "leader", "position": position, "yaw": yaw}],
            "obstacles": obstacles,
        }
    )


def printed_eq10(r_o: float, speed: float, r_v: float) -> float:
    rv = speed / OMEGA + r_v
    return math.sqrt((r_o + rv) ** 2 - r_o**2)


def test_printed_eq10_starts_avoidance_inside_large_obstacles() -> None:
    """Erratum 4: as printed, R < R_o for Table 3's big obstacles at 100 m/s."""
    assert printed_eq10(850.0, 100.0, 25.0) < 850.0
    assert printed_eq10(650.0, 100.0, 25.0) < 650.0
    assert influence_radius(100.0, OMEGA, 850.0 + 25.0) > 875.0


@pytest.mark.parametrize("speed", [100.0, 300.0])
@pytest.mark.parametrize("keep_out", [75.0, 875.0])
def test_influence_radius_is_where_a_full_turn_just_clears(speed: float, keep_out: float) -> None:
    """Fig. 2 geometry: from R, heading at the centre, a full-rate turn's circle passes the
    centre at exactly ``keep_out``."""
    r = influence_radius(speed, OMEGA, keep_out)
    rho = speed / OMEGA
    angles = np.linspace(0.0, math.pi, 200_001)
    # vehicle at (-r, 0) heading +x, turning left on a circle centred at (-r, rho)
    x = -r + rho * np.sin(angles)
    y = rho - rho * np.cos(angles)
    assert np.hypot(x, y).min() == pytest.approx(keep_out, rel=1e-6)


def test_trend_is_a_saturated_sign() -> None:
    step = OMEGA * 0.01
    assert trend(1.0, OMEGA, 0.01) == 1.0
    assert trend(-0.2, OMEGA, 0.01) == -1.0
    assert trend(step / 2, OMEGA, 0.01) == pytest.approx(0.5)
    assert trend(0.0, OMEGA, 0.01) == 0.0


@pytest.mark.parametrize(("v0", "d"), [(100.0, 0.0), (100.0, 500.0), (220.0, 37.0)])
def test_braking_speed_matches_eq21_22(v0: float, d: float) -> None:
    a = 40.0
    vi = braking_speed(v0, d, a)
    dt_prime = (vi - v0) / a  # Eq. 21
    dd_prime = vi * dt_prime - a * dt_prime**2 / 2  # Eq. 22
    assert dd_prime == pytest.approx(d, abs=1e-9)


def test_to_vcs_is_eq16_to_18() -> None:
    pitch, yaw = 0.3, -1.1
    f = np.array([1.0, 2.0, 3.0])
    a_fv = np.array(
        [[math.cos(pitch), 0, math.sin(pitch)], [0, 1, 0], [-math.sin(pitch), 0, math.cos(pitch)]]
    )
    b_fv = np.array(
        [[math.cos(yaw), math.sin(yaw), 0], [-math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]]
    )
    got = to_vcs(f[0], f[1], f[2], math.cos(pitch), math.sin(pitch), math.cos(yaw), math.sin(yaw))
    assert np.allclose(got, a_fv @ b_fv @ f)


def test_target_left_turns_left_and_target_above_pitches_up() -> None:
    """Erratum 2: f_ψ follows F_v^y (left wing), f_θ follows F_v^z (up)."""
    left = advance(scene_from_mission(solo([0, 0, 0], 0.0, [1000, 1000, 0], [])), 0.01, 1)
    assert left.scene.fleet.yaw[0] == pytest.approx(OMEGA * 0.01)
    assert left.scene.fleet.pitch[0] == pytest.approx(0.0)
    up = advance(scene_from_mission(solo([0, 0, 0], 0.0, [1000, 0, 1000], [])), 0.01, 1)
    assert up.scene.fleet.pitch[0] == pytest.approx(OMEGA * 0.01)
    assert up.scene.fleet.yaw[0] == pytest.approx(0.0)


def test_exact_head_on_enters_s2_and_pulls_up() -> None:
    """Eq. 20: repulsion antiparallel to the velocity; F_add along +z_v pulls the nose up
    (while the vehicle turns round: the wanted direction is behind it), no steeper than
    MAX_AVOID_PITCH."""
    mission = solo(
        [-1200.0, 0.0, 0.0], 0.0, [3000.0, 0.0, 0.0], [{"center": [0.0, 0.0, 0.0], "radius": 850.0}]
    )
    run = advance(scene_from_mission(mission), 0.01, 500)
    tr = run.trajectory
    entered = int(np.argmax(tr.state[:, 0] == S2_LOCAL_MINIMUM))
    assert entered > 0
    assert tr.pitch[entered, 0] > 0.0
    assert tr.pitch[-1, 0] > 0.5
    # The limit is on the wanted direction; pitch follows its elevation in the VCS, which
    # drifts from the ICS elevation by a little while the vehicle also yaws.
    assert tr.pitch.max() <= MAX_AVOID_PITCH + math.radians(2.0)


def test_advance_does_not_mutate_its_input() -> None:
    scene = scene_from_mission(solo([0, 0, 0], 0.0, [5000, 0, 0], []))
    before = scene.fleet.pos.copy()
    advance(scene, 0.01, 10)
    assert np.array_equal(scene.fleet.pos, before)

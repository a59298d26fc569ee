"""Whom each vehicle yields to, found for the fleet at once in a grid (``reach.yields``,
through ``assurance._yields``), is whom the pairwise rule (``overtaking``,
``within_reach``) says, pair by pair, in the same order."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_ppf.guidance import assurance, reach
from gcs_ppf.guidance.assurance import KeepOut, overtaking, within_reach
from gcs_ppf.guidance.vehicle_motion import Motion, escape_s, motion_vector
from gcs_ppf.planning.scene import Obstacles

NO_OBSTACLES = Obstacles(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)))


def pairwise(motions: list[Motion], hold_s: float, keep: KeepOut) -> list[list[int]]:
    return [
        [j for j, o in enumerate(motions)
         if j != i and (j < i or overtaking(m, o)) and within_reach(m, o, hold_s, keep)]
        for i, m in enumerate(motions)
    ]  # fmt: skip


def fleet(rng: np.random.Generator, n: int, extent_m: float, speed_m_s: float) -> list[Motion]:
    out = []
    for _ in range(n):
        x, y = rng.uniform(-extent_m, extent_m, 2)
        z = rng.uniform(100.0, 600.0)
        speed = speed_m_s * rng.uniform(0.8, 1.2)
        yaw, turning = float(rng.uniform(-math.pi, math.pi)), float(rng.uniform(-0.2, 0.2))
        out.append(Motion((float(x), float(y), float(z)), yaw, float(speed), 0.5, 5.0, 5.0,
                          1.0, turning))  # fmt: skip
    return out


@pytest.mark.parametrize(
    ("n", "extent_m", "speed_m_s"),
    [(2, 500.0, 25.0), (12, 2000.0, 25.0), (60, 3000.0, 100.0), (150, 60_000.0, 25.0)],
)
def test_the_grid_finds_the_pairs_the_pairwise_rule_does(
    n: int, extent_m: float, speed_m_s: float
) -> None:
    rng = np.random.default_rng(n)
    keep = KeepOut(NO_OBSTACLES, None, 25.0, 50.0)
    for _ in range(5):
        motions = fleet(rng, n, extent_m, speed_m_s)
        vectors = [motion_vector(m) for m in motions]
        expected = pairwise(motions, 1.5, keep)
        assert assurance._yields(motions, vectors, 1.5, keep) == expected
    if extent_m > 10_000.0:  # spread out, most pairs out of reach: the grid skips them
        assert sum(map(len, expected)) < n * (n - 1) / 4


def test_a_pair_on_a_threshold_is_left_to_the_pairwise_rule() -> None:
    """Abreast (no overtaking either way, the gap not closing) and exactly at reach: the
    compiled pass says neither, and the pairwise rule decides."""
    a = Motion((0.0, 0.0, 100.0), 0.0, 25.0, 0.5, 5.0, 5.0)
    keep = KeepOut(NO_OBSTACLES, None, 25.0, 50.0)
    horizon = 1.0 + escape_s(a)
    b = Motion((0.0, 2 * 25.0 * horizon + 50.0, 100.0), 0.0, 25.0, 0.5, 5.0, 5.0)
    pos = np.array([a.pos_m, b.pos_m])
    vel = np.array([a.velocity(), b.velocity()])
    esc = np.array([escape_s(a)] * 2)
    _, _, status = reach.yields(pos, vel, np.array([25.0, 25.0]), esc, 1.0, 50.0)
    assert reach.UNDECIDED in status.tolist()
    assert assurance._yields([a, b], [motion_vector(a), motion_vector(b)], 1.0, keep) == (
        pairwise([a, b], 1.0, keep)
    )

"""The compiled prediction's short cuts change no margin: the teammates' instants skipped by
their longest steps, the escape not looked at once one is as good as the hold, and a margin
looked at only as far as its cap (``gcs_ppf.guidance.prediction``); and a climbing escape
climbs as real ArduPlane does."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from gcs_ppf.guidance import prediction
from gcs_ppf.guidance.airframe import Airframe
from gcs_ppf.guidance.online import VehicleState
from gcs_ppf.guidance.vehicle_motion import Command, Motion, motion_vector, straight_track
from gcs_ppf.mission import load_mission_file
from gcs_ppf.planning.scene import FloatArray, IntArray
from gcs_ppf.service.commanding import motion
from tests.conftest import EXAMPLES, ROOT

NO_ZONES = (np.zeros(0, np.int64), np.zeros((0, 5)), np.zeros(1, np.int64), np.zeros((0, 2)))


def walk(rng: np.random.Generator, start: FloatArray, n: int, step_m: float) -> FloatArray:
    """A path of ``n`` instants from ``start``, each step in a random direction, at most
    ``step_m`` long."""
    steps = rng.normal(size=(n - 1, 3))
    steps *= rng.uniform(0.0, step_m, size=(n - 1, 1)) / np.linalg.norm(steps, axis=1)[:, None]
    return np.vstack([start, start + np.cumsum(steps, axis=0)])


def nearest_every_instant(
    path: FloatArray, pool: FloatArray, which: IntArray, start: int, last: int
) -> float:
    """The least distance from ``path`` to the rows ``which`` of ``pool``, every instant."""
    index = start + np.minimum(np.arange(path.shape[0]), last)
    d2 = ((path[None] - pool[which][:, index]) ** 2).sum(-1)
    return math.sqrt(float(d2.min()))


@pytest.mark.parametrize("seed", range(40))
def test_skipping_instants_finds_the_same_nearest_teammate(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n_rows, length = 12, 60
    pool = np.stack(
        [walk(rng, rng.uniform(-800, 800, 3), length, rng.uniform(0, 30)) for _ in range(n_rows)]
    )
    steps = np.array([prediction.longest_step(row) for row in pool])
    which = rng.choice(n_rows, size=rng.integers(1, n_rows), replace=False).astype(np.int64)
    start = int(rng.integers(0, 10))
    last = int(rng.integers(0, length - start))
    path = walk(rng, rng.uniform(-800, 800, 3), int(rng.integers(2, 70)), rng.uniform(0, 30))
    exact = nearest_every_instant(path, pool, which, start, last)
    assert prediction._nearest_teammate(path, pool, steps, which, start, last, math.inf) == exact
    beyond = float(rng.uniform(0, 1500))
    capped = prediction._nearest_teammate(path, pool, steps, which, start, last, beyond)
    assert capped == exact if exact < beyond else capped >= beyond


def test_a_far_teammate_is_not_looked_at_every_instant() -> None:
    """What the skipping is for: a teammate a kilometre off, 20 m an instant, is looked at
    a few times over 60 instants, and still found at its distance."""
    path = np.column_stack([np.arange(60) * 10.0, np.zeros(60), np.zeros(60)])
    row = path + np.array([0.0, 1000.0, 0.0])
    pool, which = row[None], np.zeros(1, np.int64)
    steps = np.array([prediction.longest_step(row)])
    looked = prediction._nearest_teammate(path, pool, steps, which, 0, 59, math.inf)
    assert looked == 1000.0
    never_skipping = np.array([math.inf])  # no bound on the teammate's step: every instant
    assert prediction._nearest_teammate(path, pool, never_skipping, which, 0, 59, 50.0) == 1000.0


@pytest.mark.parametrize("seed", range(200))
def test_judging_with_short_cuts_gives_the_margin_of_every_flight(seed: int) -> None:
    """``judge`` = the least of the hold's margin and the better escape's, each margin over
    every instant against every teammate (the skipping off: steps unbounded)."""
    rng = np.random.default_rng(seed)
    hold_s, after = 1.0, 140
    m = Motion((0.0, 0.0, 300.0), float(rng.uniform(-3, 3)), 30.0, 0.4, 5.0, 5.0)
    vector = motion_vector(m)
    mates = []
    for _ in range(int(rng.integers(1, 8))):
        where = (*rng.uniform(-600, 600, 2), rng.uniform(250, 350))
        mates.append(Motion(where, rng.uniform(-3, 3), 30.0, 0.4, 5.0, 5.0))
    pool = np.stack([straight_track(t, hold_s, after).path for t in mates])
    steps = np.array([prediction.longest_step(row) for row in pool])
    which = np.arange(len(mates), dtype=np.int64)
    centers, radii = rng.uniform(-700, 700, (3, 3)), rng.uniform(50, 250, 3)
    centers[:, 2] = rng.uniform(150, 450, 3)
    keep = (centers, radii, 25.0, 0.0)
    c = Command(float(rng.uniform(-math.pi, math.pi)), float(rng.uniform(250, 350)))
    path, left, right, up_left, up_right = prediction.flights(vector, c.course_rad, c.z_m, hold_s)
    around = (*keep, pool, steps, which, 50.0, *NO_ZONES)
    fast = prediction.judge(path, left, right, up_left, up_right, around)
    escapes = (left, right, up_left, up_right)
    every = np.full_like(steps, math.inf)
    k = path.shape[0] - 1

    def margin(p: FloatArray, start: int, last: int) -> tuple[float, int]:
        around = (*keep, pool, every, which, 50.0, *NO_ZONES)
        return prediction.margin(p, around, start, last, math.inf)

    held = margin(path, 0, k)
    escape = max(margin(arc, k, pool.shape[1] - k - 1) for arc in escapes)
    expected = escape if escape[0] < held[0] else held
    assert fast[0] == expected[0]
    assert fast[1] == expected[1]


CLIMB_PREDICTED_WITHIN_M = 5.0
"""How far a climbing escape's predicted height may run ahead of real ArduPlane's (m):
what the escape counts on and the vehicle does not have."""


def test_a_climbing_escape_climbs_on_real_arduplane_as_predicted() -> None:
    """Real ArduPlane (4.7.0-dev SITL, plane.parm; ``python -m sitl.record_trace URL
    climbing-escape``) told a half turn at the full bank and a 150 m climb at once: over the
    escape's time its height keeps up with the prediction's within
    ``CLIMB_PREDICTED_WITHIN_M`` (it climbed 37.5 m in 12 s, the prediction 37.6 m), and a
    level escape's prediction would not climb at all."""
    data = ROOT / "tests" / "data"
    params = json.loads((data / "arduplane-traces" / "meta.json").read_text())["parameters_read"]
    rows = csv.DictReader((data / "assurance" / "climbing-escape.csv").open())
    fixes = [r for r in rows if r["msg"] == "GLOBAL_POSITION_INT"]
    t = np.array([float(r["t_s"]) for r in fixes])
    height = np.array([float(r["rel_alt_m"]) for r in fixes])
    vn, ve = (np.array([float(r[c]) for r in fixes]) for c in ("vn_m_s", "ve_m_s"))
    k = int(np.argmin(abs(t)))
    course, speed = float(np.arctan2(vn[k], ve[k])), float(np.hypot(vn[k], ve[k]))
    state = VehicleState((0.0, 0.0, float(height[k])), 0.0, course, speed, 0.0, 0.0)
    m = motion_vector(
        motion(
            state,
            Airframe.from_params(params.get),
            load_mission_file(EXAMPLES / "arduplane_3.json"),
        )
    )
    hold_s = prediction.STEP_S
    _, end = prediction.fly_hold(m, course, float(height[k]), hold_s)
    arc = prediction.escape_arc(m, end, 1.0, prediction.climb_out_z(m, end))
    at = hold_s + prediction.STEP_S * np.arange(arc.shape[0])
    flown = np.interp(at, t, height)
    assert float(np.max(arc[:, 2] - flown)) <= CLIMB_PREDICTED_WITHIN_M
    assert flown[-1] - height[k] > 30.0  # it did climb, as the prediction has it

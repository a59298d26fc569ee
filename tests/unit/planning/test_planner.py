"""advance: chunks planned in one call are the chunks planned one call after the other."""

from __future__ import annotations

import numpy as np
import pytest

from gcs_ppf.mission import load_mission_file
from gcs_ppf.offline.benchmark import synthetic_scene
from gcs_ppf.planning.planner import Advance, Method, Trajectory, advance
from gcs_ppf.planning.scene import Scene, scene_from_mission
from tests.conftest import EXAMPLES

FIELDS = ("t", "pos", "pitch", "yaw", "speed", "state", "avoiding", "formed")


def one_after_the_other(
    scene: Scene, n_steps: int, chunk: int, record_every: int, t0: float, method: Method
) -> tuple[Trajectory, Advance, int, float]:
    """Chunks of ``chunk`` steps, each call from the last one's scene and time: the joined
    trajectory, the last call's result, the steps taken and the time reached."""
    parts, t, steps = [], t0, 0
    result = advance(scene, 0.01, 0, t0=t0)
    while steps < n_steps and not result.arrived:
        n = min(chunk, n_steps - steps)
        result = advance(result.scene, 0.01, n, method=method, record_every=record_every, t0=t)
        parts.append(result.trajectory)
        steps += result.steps
        t += result.elapsed_s
    return Trajectory.concatenate(parts), result, steps, t


@pytest.mark.parametrize(
    ("scene", "n_steps", "chunk", "record_every", "method"),
    [
        ("paper_table3.json", 30_000, 100, 1, "ppf"),  # to the leader's arrival, mid-chunk
        ("paper_table2.json", 1234, 100, 7, "ppf"),
        ("paper_table3.json", 950, 37, 1, "apf"),
        ("120 x 40", 400, 37, 3, "ppf"),  # the teammate grid, lists remade at each chunk
    ],
)
def test_chunks_in_one_call_are_the_chunks_one_call_after_the_other(
    scene: str, n_steps: int, chunk: int, record_every: int, method: Method
) -> None:
    start = synthetic_scene(120, 40) if " x " in scene else scene_from_mission(
        load_mission_file(EXAMPLES / scene)
    )  # fmt: skip
    joined, last, steps, t = one_after_the_other(start, n_steps, chunk, record_every, 3.5, method)
    one = advance(start, 0.01, n_steps, method=method, record_every=record_every, t0=3.5,
                  chunk_steps=chunk)  # fmt: skip
    for field in FIELDS:  # bit for bit, the record times too
        assert np.array_equal(getattr(one.trajectory, field), getattr(joined, field)), field
    assert (one.t_s, one.arrived, one.steps) == (t, last.arrived, steps)
    for field in ("pos", "pitch", "yaw", "speed"):
        assert np.array_equal(getattr(one.scene.fleet, field), getattr(last.scene.fleet, field))
    assert np.array_equal(one.scene.obstacles.center, last.scene.obstacles.center)
    if scene == "paper_table3.json" and method == "ppf":
        assert one.arrived
        assert one.steps < n_steps

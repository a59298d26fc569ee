"""The compiled kernel agrees with the plain-numpy reference, step by step."""

from __future__ import annotations

import numpy as np
import pytest

from gcs_ppf.offline import PlanRun
from gcs_ppf.planner import advance
from gcs_ppf.ppf.reference import reference_step
from gcs_ppf.scene import Fleet, Scene


def _state_at(run: PlanRun, k: int) -> Scene:
    tr = run.trajectory
    f = run.scene.fleet
    fleet = Fleet(f.ids, tr.pos[k].copy(), tr.pitch[k].copy(), tr.yaw[k].copy(),
                  tr.speed[k].copy(), f.slot, f.rank, f.active)  # fmt: skip
    return Scene(fleet, run.scene.obstacles.at(float(tr.t[k])), run.scene.target, run.scene.limits)


@pytest.mark.parametrize("scene", ["table2_ppf", "table3_ppf"])
def test_one_step_from_states_along_the_paper_plans(
    scene: str, request: pytest.FixtureRequest
) -> None:
    run: PlanRun = request.getfixturevalue(scene)
    records = np.linspace(0, len(run.trajectory) - 2, 400).astype(int)
    states_seen = set()
    for k in records:
        s = _state_at(run, int(k))
        f, o = s.fleet, s.obstacles
        ours = advance(s, run.dt, 1)
        pos, pitch, yaw, speed, state = reference_step(
            f.pos,
            f.pitch,
            f.yaw,
            f.speed,
            f.slot,
            f.rank,
            f.active,
            o.center,
            o.radius,
            o.velocity,
            s.target,
            s.limits,
            run.dt,
        )
        got = ours.scene.fleet
        assert np.allclose(got.pos, pos, atol=1e-7), k
        assert np.allclose(got.speed, speed, atol=1e-7), k
        assert np.allclose(got.pitch, pitch, atol=1e-9), k
        assert np.allclose(np.angle(np.exp(1j * (got.yaw - yaw))), 0.0, atol=1e-9), k
        assert np.array_equal(ours.trajectory.state[0], state), k
        states_seen.update(state.tolist())
    assert {1, 3} <= states_seen

"""Batches: every scene once, and the same rows however the sweep is cut and wherever it
is planned (here or in a process pool)."""

from __future__ import annotations

from dataclasses import replace

from gcs_ppf.offline.sweep.batches import (
    MAX_BATCH,
    batch_size,
    in_order,
    make_batches,
    plan_here,
    plan_in_pool,
)
from gcs_ppf.offline.sweep.families import DENSE, FEASIBLE
from gcs_ppf.offline.sweep.rows import SceneRow

SPECS = (FEASIBLE, DENSE)


def deterministic(rows: list[SceneRow]) -> list[SceneRow]:
    """``rows`` without what is measured (the planning wall time)."""
    return [replace(r, planning_wall_time_s=None) for r in rows]


def test_every_scene_of_every_family_once() -> None:
    batches = make_batches(SPECS, 23, 5, 4)
    scenes = [(b.spec.name, i) for b in batches for i in range(b.start, b.stop)]
    assert sorted(scenes) == sorted((s.name, i) for s in SPECS for i in range(23))
    assert all(b.seed == 5 and b.stop - b.start <= 4 for b in batches)
    assert batch_size(10_000, 2) == MAX_BATCH
    assert batch_size(16, 2) == 1
    assert batch_size(1, 64) == 1


def test_a_pool_plans_the_same_rows_as_this_process() -> None:
    here = in_order(plan_here(make_batches(SPECS, 6, 9, 6), lambda _: None), SPECS)
    done: list[int] = []
    pooled = in_order(
        plan_in_pool(make_batches(SPECS, 6, 9, 4), 2, lambda rows: done.append(len(rows))),
        SPECS,
    )
    assert sum(done) == 12
    assert [(r.family, r.index) for r in here] == [(s.name, i) for s in SPECS for i in range(6)]
    assert deterministic(pooled) == deterministic(here)

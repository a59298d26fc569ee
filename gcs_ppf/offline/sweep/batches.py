"""A sweep cut into batches of scenes, planned here or in a local process pool.

A batch (one family, a run of scene indices) is the unit of work a worker gets; its rows
depend on the batch alone, so any split and any worker give the same table once the rows
are put back in order (``in_order``). ``gcs_ppf.offline.sweep.cluster`` plans the same
batches on Ray.
"""

from __future__ import annotations

import math
import multiprocessing
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass

from gcs_ppf.offline.sweep.rows import SceneRow, plan_scene
from gcs_ppf.offline.sweep.spec import SceneSpec

Progress = Callable[[Sequence[SceneRow]], None]
"""Called with the rows of each batch as it is done."""
MAX_BATCH = 50
"""Scenes per batch at most (about 2–3 s of planning for the feasible family here)."""


@dataclass(frozen=True)
class Batch:
    """Scenes ``start`` … ``stop - 1`` of the family ``spec`` in the sweep seeded ``seed``."""

    spec: SceneSpec
    seed: int
    start: int
    stop: int


def plan_batch(batch: Batch) -> list[SceneRow]:
    """The rows of ``batch``'s scenes, in index order."""
    return [plan_scene(batch.spec, batch.seed, i) for i in range(batch.start, batch.stop)]


def batch_size(scenes: int, workers: int) -> int:
    """Scenes per batch: about eight batches per worker (the last ones balance the load),
    at most ``MAX_BATCH``."""
    return max(1, min(MAX_BATCH, math.ceil(scenes / (8 * max(workers, 1)))))


def make_batches(specs: Sequence[SceneSpec], n: int, seed: int, size: int) -> list[Batch]:
    """Scenes 0 … n − 1 of every family in ``specs``, ``size`` to a batch."""
    return [
        Batch(spec, seed, start, min(start + size, n))
        for spec in specs
        for start in range(0, n, size)
    ]


def in_order(rows: Iterable[SceneRow], specs: Sequence[SceneSpec]) -> list[SceneRow]:
    """``rows`` by family (in ``specs``' order), then by scene index."""
    rank = {spec.name: k for k, spec in enumerate(specs)}
    return sorted(rows, key=lambda r: (rank[r.family], r.index))


def plan_here(batches: Sequence[Batch], progress: Progress) -> list[SceneRow]:
    """Plan every batch in this process, one after the other."""
    rows: list[SceneRow] = []
    for batch in batches:
        done = plan_batch(batch)
        progress(done)
        rows.extend(done)
    return rows


def plan_in_pool(batches: Sequence[Batch], jobs: int, progress: Progress) -> list[SceneRow]:
    """Plan the batches in ``jobs`` worker processes (started fresh, ``spawn``: no state of
    this process is inherited, on any platform); rows as the batches finish."""
    rows: list[SceneRow] = []
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=jobs, mp_context=context) as pool:
        futures = [pool.submit(plan_batch, batch) for batch in batches]
        for future in as_completed(futures):
            done = future.result()
            progress(done)
            rows.extend(done)
    return rows

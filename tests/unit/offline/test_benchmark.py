"""The speed table: how many runs each figure is the best of."""

from __future__ import annotations

import itertools

import pytest

from gcs_ppf.offline.benchmark import repeated


@pytest.mark.parametrize(
    ("each", "repeats", "min_seconds", "runs"),
    [(0.1, 3, 0.5, 5), (1.0, 3, 0.5, 3), (0.2, 1, 0.0, 1), (0.01, 3, 0.05, 5)],
)
def test_runs_until_enough_runs_and_enough_time(
    each: float, repeats: int, min_seconds: float, runs: int
) -> None:
    calls = itertools.count(1)
    times = repeated(lambda: next(calls) and each, repeats, min_seconds)
    assert len(times) == runs
    assert next(calls) == runs + 1  # run exactly that often


def test_a_short_stall_does_not_decide_the_best() -> None:
    stalls = iter([0.010, 0.011, 0.010] + [0.0065] * 100)  # a stall over the first three runs
    times = repeated(lambda: next(stalls), 3, 0.1)
    assert min(times) == 0.0065

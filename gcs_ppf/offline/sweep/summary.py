"""What a sweep's table says, family by family: how the scenes ended, and the distributions
of separation, clearance, and flight time against the straight-line time.

A scene *fails* unless its outcome is ``reached`` (the leader at the target, both safe
distances kept): a safety breach, the target not reached within ``planner.max_time``, or
an error. Distributions are over the scenes that have the figure (a lone leader has no
separation, a scene without obstacles no clearance, a scene not reached no flight time).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from gcs_ppf.offline.sweep.rows import Outcome, SceneRow

QUANTILES = {"min": 0.0, "p1": 0.01, "p5": 0.05, "median": 0.5, "p95": 0.95, "max": 1.0}


def distribution(values: Sequence[float]) -> dict[str, float] | None:
    """``QUANTILES`` of ``values`` and their count (None for no values)."""
    if not values:
        return None
    q = np.quantile(np.asarray(values, dtype=float), list(QUANTILES.values()))
    return {"scenes": len(values), **{k: float(v) for k, v in zip(QUANTILES, q, strict=True)}}


def families(rows: Sequence[SceneRow]) -> dict[str, list[SceneRow]]:
    """The rows of each family, families in the order they first appear."""
    out: dict[str, list[SceneRow]] = {}
    for row in rows:
        out.setdefault(row.family, []).append(row)
    return out


def figures(rows: Sequence[SceneRow], name: str) -> list[float]:
    """The column ``name`` of the rows that have it (not None)."""
    return [float(v) for r in rows if (v := getattr(r, name)) is not None]


def straight_line_and_flight(rows: Sequence[SceneRow]) -> list[tuple[float, float]]:
    """(straight-line time, flight time) of every reached scene whose target was not at the
    start already."""
    return [
        (r.straight_line_time_s, r.flight_time_s)
        for r in rows
        if r.flight_time_s is not None and r.straight_line_time_s
    ]


def summarise_family(rows: Sequence[SceneRow]) -> dict[str, Any]:
    """One family's outcome counts and rates, failure rate and distributions."""
    n = len(rows)
    counts = {o.value: sum(r.outcome == o for r in rows) for o in Outcome}
    walls = figures(rows, "planning_wall_time_s")
    ratios = [flight / straight for straight, flight in straight_line_and_flight(rows)]
    return {
        "scenes": n,
        "outcomes": counts,
        "outcome_rates": {k: v / n for k, v in counts.items()},
        "failure_rate": 1.0 - counts[Outcome.REACHED.value] / n,
        "min_separation_m": distribution(figures(rows, "min_separation_m")),
        "min_obstacle_clearance_m": distribution(figures(rows, "min_obstacle_clearance_m")),
        "min_ground_clearance_m": distribution(figures(rows, "min_ground_clearance_m")),
        "flight_time_s": distribution(figures(rows, "flight_time_s")),
        "flight_over_straight_line": distribution(ratios),
        "planning_wall_time_s": {"total": float(sum(walls)), "mean": float(np.mean(walls))}
        if walls
        else None,
    }


def summarise(rows: Sequence[SceneRow]) -> dict[str, dict[str, Any]]:
    """``summarise_family`` for every family of ``rows``."""
    return {name: summarise_family(group) for name, group in families(rows).items()}


def _quantiles(d: dict[str, float] | None, fmt: str) -> str:
    if d is None:
        return "none"
    parts = ", ".join(f"{k} {d[k]:{fmt}}" for k in ("min", "p1", "p5", "median", "max"))
    return f"{parts} ({d['scenes']:.0f} scenes)"


def describe(summary: dict[str, dict[str, Any]]) -> list[str]:
    """The summary in a few lines of text per family."""
    lines = []
    for name, s in summary.items():
        outcomes = ", ".join(
            f"{k} {v} ({100 * s['outcome_rates'][k]:.1f} %)" for k, v in s["outcomes"].items() if v
        )
        lines += [
            f"{name}: {s['scenes']} scenes, failed {100 * s['failure_rate']:.2f} %: {outcomes}",
            f"  min separation (m): {_quantiles(s['min_separation_m'], '.1f')}",
            f"  min obstacle clearance (m): {_quantiles(s['min_obstacle_clearance_m'], '.1f')}",
            f"  flight / straight-line time: {_quantiles(s['flight_over_straight_line'], '.2f')}",
        ]
    return lines

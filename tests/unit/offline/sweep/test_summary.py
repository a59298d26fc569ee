"""The summary: outcome counts and rates per family, distributions over the scenes that
have the figure."""

from __future__ import annotations

import pytest

from gcs_ppf.offline.sweep.rows import SceneRow
from gcs_ppf.offline.sweep.summary import describe, distribution, summarise


def test_each_family_is_summarised_on_its_own(rows: list[SceneRow]) -> None:
    summary = summarise(rows)
    assert list(summary) == ["feasible", "mine"]
    feasible, mine = summary["feasible"], summary["mine"]
    assert feasible["scenes"] == 4
    assert feasible["outcomes"]["reached"] == 2
    assert feasible["outcomes"]["not_reached"] == 1
    assert feasible["outcomes"]["clearance"] == 1
    assert feasible["failure_rate"] == pytest.approx(0.5)
    assert feasible["min_separation_m"]["min"] == 60.0
    assert feasible["min_obstacle_clearance_m"]["min"] == 12.5
    assert feasible["flight_over_straight_line"]["max"] == pytest.approx(2.0)
    assert mine["failure_rate"] == pytest.approx(0.5)
    assert mine["min_separation_m"] is None
    assert mine["planning_wall_time_s"]["total"] == pytest.approx(0.02)
    text = "\n".join(describe(summary))
    assert "feasible: 4 scenes, failed 50.00 %" in text
    assert "min separation (m): none" in text


def test_a_distribution_counts_its_scenes() -> None:
    d = distribution([3.0, 1.0, 2.0])
    assert d is not None
    assert (d["scenes"], d["min"], d["median"], d["max"]) == (3, 1.0, 2.0, 3.0)
    assert d["p5"] == pytest.approx(1.1)
    assert distribution([]) is None

"""The campaign's tables: per condition a row per mission, with the formation's figures
beside separation and clearance, from the runs' records."""

from __future__ import annotations

from typing import Any

from gcs_ppf.tools.campaign import CONDITIONS
from gcs_ppf.tools.campaign_tables import format_tables, progress_line, summarize


def _run(k: int, formation: float | None, held: float | None, **extra: Any) -> dict[str, Any]:
    return {"mission": "paper-table3", "condition": "a", "run": k, "state": "completed",
            "ok": True, "violations": [], "min_separation_m": 100.0 + k,
            "min_clearance_m": 200.0 + k, "formation_m": formation, "formation_held_s": held,
            "mission_time_s": 90.0, "wall_s": 9.0, **extra}  # fmt: skip


def test_the_table_gives_the_formations_min_median_and_longest_hold() -> None:
    runs = [_run(0, 326.0, 0.0), _run(1, 8.0, 12.5), _run(2, 40.0, 0.0), _run(3, None, None)]
    summary = summarize(runs, CONDITIONS)
    g = summary["a"]["missions"]["paper-table3"]
    assert (g["formation_min_m"], g["formation_median_m"]) == (8.0, 40.0)
    assert g["formation_held_max_s"] == 12.5
    table = format_tables(summary)
    head, row = table.splitlines()[2:4]
    assert "form min" in head
    assert "form med" in head
    assert "held" in head
    assert row.split()[1:4] == ["4", "0", "4"]  # runs, violations, as expected
    assert row.split()[8:11] == ["8.0", "40.0", "12.5"]  # form min, form med, held


def test_a_run_line_shows_its_formation_when_it_has_one() -> None:
    assert "formation 8.0 m held 12.5 s" in progress_line(_run(1, 8.0, 12.5))
    assert "formation" not in progress_line(_run(3, None, None))

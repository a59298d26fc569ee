"""A reduced closed-loop campaign: Table 3 flown end to end at x10 and on a lossy, late
link at x5 (``gcs_ppf.tools.campaign``), judged by the independent observer. Four flights
(about 95 s here): ``make campaign-check``, not ``make test``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gcs_ppf.tools.campaign import CONDITIONS, run_campaign
from gcs_ppf.tools.campaign_tables import format_tables, summarize
from tests.conftest import EXAMPLES

RUNS = 2


@pytest.mark.integration
@pytest.mark.campaign
def test_reduced_campaign_table3_has_no_violation_and_completes(tmp_path: Path) -> None:
    """(a) x10 and (c) x5 with 300 ms of latency and 20 % loss, RUNS runs each: every run
    completes, and the observer sees no separation under safe_distance_uav and no
    clearance under safe_distance_obstacle from the run's start to 30 s of vehicle time
    after its end."""
    lines: list[str] = []
    results = run_campaign(
        [EXAMPLES / "paper_table3.json"], ["a", "c"], RUNS, tmp_path, progress=lines.append
    )
    print("\n" + "\n".join(lines) + "\n" + format_tables(summarize(results, CONDITIONS)))
    assert len(results) == 2 * RUNS
    assert len((tmp_path / "runs.jsonl").read_text().splitlines()) == 2 * RUNS
    assert set(json.loads((tmp_path / "summary.json").read_text())) == {"a", "c"}
    for rec in results:
        assert not rec.get("error"), rec
        assert rec["violations"] == [], rec
        assert rec["state"] == CONDITIONS[rec["condition"]].expect, rec
        assert rec["min_separation_m"] >= 50.0, rec
        assert rec["min_clearance_m"] >= 25.0, rec
        lo, hi = rec["window_s"]
        assert hi - lo >= rec["mission_time_s"] + 30.0  # watched 30 s past the end
        assert rec["formation_m"] is not None, rec
        assert rec["formation_m"] >= 0.0, rec

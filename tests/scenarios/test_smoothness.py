"""PPF is smoother than the APF baseline on both scenes (metrics.py explains the measure)."""

from __future__ import annotations

import math

import pytest

from gcs_ppf.offline.plan import PlanRun


@pytest.mark.parametrize("scene", ["table2", "table3"])
def test_ppf_turns_less_per_km_than_apf(scene: str, request: pytest.FixtureRequest) -> None:
    ppf: PlanRun = request.getfixturevalue(f"{scene}_ppf")
    apf: PlanRun = request.getfixturevalue(f"{scene}_apf")
    ours, theirs = ppf.metrics["smoothness"], apf.metrics["smoothness"]
    assert ours["heading_change_deg_per_km"] < theirs["heading_change_deg_per_km"]
    hold = "wingman_hold_heading_change_deg_per_km"
    assert ours[hold] < theirs[hold]
    assert ours["max_step_turn_deg"] <= math.degrees(math.pi / 6 * ppf.dt) * math.sqrt(2) + 1e-9
    assert theirs["max_step_turn_deg"] > 10.0  # APF turns at once

"""The planning margins' effect on a mission's formation, planned offline."""

from __future__ import annotations

from pathlib import Path

import pytest

from gcs_ppf.mission import load_mission
from gcs_ppf.offline.margin_effect import margin_effect
from gcs_ppf.planning.scene import Scene, scene_from_mission, with_margins

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"


def scene_of(name: str) -> Scene:
    return scene_from_mission(load_mission((EXAMPLES / name).read_text()))


def test_the_margins_widen_the_safe_distances_as_the_service_does() -> None:
    scene = scene_of("paper_table2.json")
    widened = with_margins(scene, 100.0, 15.0)
    assert widened.limits.safe_distance_obstacle == scene.limits.safe_distance_obstacle + 100.0
    assert widened.limits.safe_distance_uav == scene.limits.safe_distance_uav + 15.0
    assert scene.limits.safe_distance_uav == 50.0  # the input is left as it was


def test_without_margins_it_is_the_offline_plan() -> None:
    """Table 2's plan forms at 25.7 s and arrives at 50.79 s (``gcs-ppf plan``)."""
    e = margin_effect(scene_of("paper_table2.json"), 0.0, 0.0, 0.01, 300.0)
    assert e.formed_s == pytest.approx(25.8, abs=0.1)
    assert e.arrived_s == pytest.approx(50.79, abs=0.01)
    assert e.best_worst_m <= 10.0


def test_table_3_does_not_form_with_the_flown_loops_teammate_margin() -> None:
    """The finding of docs/formation-flown.md: 45.7 m on the teammates' 50 m keeps every
    Table 3 plan from forming, the 100 m on the obstacles does not."""
    scene = scene_of("paper_table3.json")
    assert margin_effect(scene, 100.0, 0.0, 0.01, 300.0).formed_s is not None
    kept_out = margin_effect(scene, 100.0, 45.7, 0.01, 300.0)
    assert kept_out.formed_s is None
    assert kept_out.best_worst_m > 50.0

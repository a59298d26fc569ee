"""``gcs-ppf plan`` draws zones: each cylinder and polygon in the paths' figure, and the
clearance figure (Fig. 13) counts their surfaces as metrics does."""

from __future__ import annotations

import numpy as np
import pytest

from gcs_ppf.mission import load_mission_file
from gcs_ppf.offline import plots
from gcs_ppf.offline.plan import PlanRun, plan_mission
from gcs_ppf.planning.zones import POLYGON
from tests.conftest import EXAMPLES


@pytest.fixture(scope="module")
def zones_run() -> PlanRun:
    mission = load_mission_file(EXAMPLES / "paper_table3_zones.json")
    return plan_mission(
        mission.model_copy(update={"planner": mission.planner.model_copy(update={"dt": 0.05})})
    )


def test_every_zone_outline_is_its_footprint(zones_run: PlanRun) -> None:
    zones = zones_run.scene.zones
    assert len(zones) == 4
    for k in range(len(zones)):
        ring = plots._zone_outline(zones, k)
        assert np.array_equal(ring[0], ring[-1])  # closed
        if zones.kind[k] & POLYGON:
            assert np.array_equal(ring[:-1], zones.verts[zones.vstart[k] : zones.vstart[k + 1]])
        else:
            cx, cy, r = zones.geom[k, :3]
            np.testing.assert_allclose(np.hypot(ring[:, 0] - cx, ring[:, 1] - cy), r)


def test_the_clearance_figure_counts_zones_as_metrics_does(zones_run: PlanRun) -> None:
    clear = plots.obstacle_clearance(zones_run)
    assert clear.shape == zones_run.trajectory.speed.shape
    assert np.isfinite(clear).all()  # no spheres in this scene: every value is a zone's
    assert clear.min() == pytest.approx(zones_run.metrics["min_obstacle_clearance_m"])

"""Ray (the cluster extra): a local Ray of 2 CPUs, started here, plans the same table as a
process pool and as this process, through the command line (`gcs-ppf sweep --ray`)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import pytest
import ray

from gcs_ppf.cli import main
from gcs_ppf.offline.sweep.batches import make_batches
from gcs_ppf.offline.sweep.cluster import ClusterError, plan_on_ray
from gcs_ppf.offline.sweep.families import FEASIBLE
from gcs_ppf.offline.sweep.rows import SceneRow
from gcs_ppf.offline.sweep.table import read_table

pytestmark = pytest.mark.integration  # a Ray is processes talking over loopback


@pytest.fixture(scope="module")
def local_ray() -> Iterator[None]:
    ray.init(num_cpus=2, include_dashboard=False)
    try:
        yield
    finally:
        ray.shutdown()


def table(out: Path) -> list[SceneRow]:
    """The sweep's table without what is measured (the planning wall time)."""
    return [replace(r, planning_wall_time_s=None) for r in read_table(out / "sweep.csv")]


def test_ray_pool_and_this_process_give_the_same_table(local_ray: None, tmp_path: Path) -> None:
    common = ["sweep", "feasible", "moving", "--n", "8", "--seed", "42", "--no-plots"]
    # the Ray started above is used (and left running): --ray local joins it
    assert main([*common, "--ray", "local", "--batch", "3", "--out", str(tmp_path / "ray")]) == 0
    assert ray.is_initialized()
    assert main([*common, "--jobs", "2", "--batch", "5", "--out", str(tmp_path / "pool")]) == 0
    assert main([*common, "--jobs", "1", "--out", str(tmp_path / "here")]) == 0
    on_ray = table(tmp_path / "ray")
    assert len(on_ray) == 16
    assert on_ray == table(tmp_path / "pool") == table(tmp_path / "here")


def test_without_a_ray_or_an_address_nothing_is_planned(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    with pytest.raises(ClusterError, match="no Ray to plan on"):
        plan_on_ray(make_batches([FEASIBLE], 2, 0, 1), None, lambda _: None)

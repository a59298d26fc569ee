"""``gcs-ppf plan`` plots fleets of any size, and a failing figure never costs the data.

The missions are generated here: a leader flying east and wingmen in a grid of slots
behind it, 120 m apart (``limits.safe_distance_uav`` is 50 m), starting a little off
their slots; 2 km to the target at Δt = 0.05 s, so each plan takes a fraction of a second.
"""

from __future__ import annotations

import csv
import json
import math
from itertools import pairwise
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.figure import Figure
from PIL import Image

from gcs_ppf.cli import main
from gcs_ppf.mission import load_mission
from gcs_ppf.offline import output, plots
from gcs_ppf.offline.command import EXIT_PLOT_FAILED
from gcs_ppf.offline.plan import PlanRun, plan_mission

SLOT_SPACING_M = 120.0
FIGURES = {
    "fig05_10_paths.png",
    "fig05b_leader_start.png",
    "fig06_11_local_target_distance.png",
    "fig07_turn_per_step.png",
    "fig08_speed.png",
    "fig12_min_vehicle_distance.png",
}


def fleet_mission(n: int) -> dict[str, Any]:
    """A mission document (CONVENTIONS §3) for a leader and ``n - 1`` wingmen."""
    vehicles: list[dict[str, Any]] = [
        {"id": 1, "role": "leader", "position": [0.0, 0.0, 500.0], "yaw": 0.0}
    ]
    cols = max(1, math.ceil(math.sqrt(n - 1)))
    for k in range(n - 1):
        row, col = divmod(k, cols)
        slot = [-SLOT_SPACING_M * (row + 1), SLOT_SPACING_M * (col - (cols - 1) / 2), 0.0]
        start = [slot[0] - 40.0, slot[1] + 20.0, 500.0 + 15.0 * (k % 3)]
        vehicles.append(
            {"id": k + 2, "role": "wingman", "position": start, "yaw": 0.0, "slot": slot}
        )
    return {
        "name": f"fleet-{n}",
        "planner": {"dt": 0.05, "max_time": 30.0},
        "target": [2000.0, 300.0, 500.0],
        "vehicles": vehicles,
    }


def _write_mission(tmp_path: Path, n: int) -> Path:
    path = tmp_path / f"fleet{n}.json"
    path.write_text(json.dumps(fleet_mission(n)))
    return path


def _assert_png(path: Path) -> None:
    assert path.stat().st_size > 10_000, path.name
    with Image.open(path) as image:
        assert image.format == "PNG", path.name
        width, height = image.size
        image.verify()
    assert 400 < width < 3000, (path.name, width)
    assert 300 < height < 3000, (path.name, height)


@pytest.mark.parametrize("n", [1, 6, 12, 30])
def test_plan_plots_fleets_of_any_size(tmp_path: Path, n: int) -> None:
    out = tmp_path / "out"
    assert main(["plan", str(_write_mission(tmp_path, n)), "--out", str(out)]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    ids = {str(i) for i in range(1, n + 1)}
    assert set(metrics["per_vehicle"]) == ids
    assert set(metrics["comparison"]["ppf"]["heading_change_deg_per_km_per_vehicle"]) == ids
    assert metrics["reached"] is True
    assert "plot_errors" not in metrics
    with (out / "trajectory.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert {r["id"] for r in rows} == ids
    assert len(rows) % n == 0
    assert len(rows) // n > 100
    assert {p.name for p in out.iterdir()} == FIGURES | {"metrics.json", "trajectory.csv"}
    for name in FIGURES:
        _assert_png(out / name)


def test_styles_stay_distinct_for_any_fleet() -> None:
    for n in (1, 2, 5, 6, 11, 12, 21, 22, 30, 100):
        style = plots.fleet_style(n)
        assert len(style.colours) == len(style.line_styles) == n
        looks = set(zip(style.colours, style.line_styles, strict=True))
        assert len(looks) == n, n  # no two vehicles drawn alike
        assert style.summarised == (n - 1 > plots.LEGEND_MAX_WINGMEN)
        if n > len(plots.PAPER_COLOURS):
            assert style.colours[0] not in style.colours[1:]  # the leader stands out
        if style.summarised:  # neighbours on the colour map differ in line style
            wingmen = style.line_styles[1:]
            assert all(a != b for a, b in pairwise(wingmen))


@pytest.fixture(scope="module")
def small_run() -> PlanRun:
    return plan_mission(load_mission(json.dumps(fleet_mission(3))))


def test_nearest_teammate_distance_matches_all_pairs() -> None:
    pos = np.random.default_rng(1).normal(size=(50, 7, 3)) * 100.0
    gaps = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=-1)
    gaps[:, np.arange(7), np.arange(7)] = np.inf
    np.testing.assert_allclose(plots.nearest_teammate_distance(pos), gaps.min(axis=2))
    assert np.isinf(plots.nearest_teammate_distance(pos[:, :1])).all()


@pytest.mark.parametrize("n", [12, 30])
def test_legend_beside_the_axes_not_over_the_data(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, n: int
) -> None:
    run = plan_mission(load_mission(json.dumps(fleet_mission(n))))
    seen: list[Figure] = []
    save = plots._save

    def keep(fig: Figure, path: Path) -> None:
        fig.canvas.draw()
        seen.append(fig)
        save(fig, path)

    monkeypatch.setattr(plots, "_save", keep)
    plots.speeds(run, tmp_path / "speed.png", 100.0, 300.0)
    (fig,) = seen
    ax = fig.axes[0]
    legend = ax.get_legend()
    assert legend is not None
    box, axes_box = legend.get_window_extent(), ax.get_window_extent()
    figure_box = fig.bbox
    assert figure_box.contains(box.x0, box.y0)  # inside the figure
    assert figure_box.contains(box.x1, box.y1)
    if n - 1 > plots.LEGEND_MAX_WINGMEN:  # summarised: leader and limits, a colour bar
        assert len(legend.get_texts()) <= 3
        assert len(fig.axes) == 2
    else:
        assert len(legend.get_texts()) == n
        assert box.x0 >= axes_box.x1  # beside the axes, not over the lines


def test_write_plan_keeps_data_and_other_figures_when_a_figure_fails(
    tmp_path: Path, small_run: PlanRun
) -> None:
    def good(path: Path) -> None:
        plots.speeds(small_run, path, 100.0, 300.0)

    def bad(path: Path) -> None:
        path.write_bytes(b"half a figure")
        raise ValueError("not a valid value for color\nsecond line")

    out = tmp_path / "out"
    errors = output.write_plan(
        out, {"reached": True}, small_run.trajectory, [("a.png", bad), ("b.png", good)]
    )
    assert errors == {"a.png": "ValueError: not a valid value for color"}
    assert json.loads((out / "metrics.json").read_text()) == {
        "reached": True,
        "plot_errors": errors,
    }
    assert sorted(p.name for p in out.iterdir()) == ["b.png", "metrics.json", "trajectory.csv"]
    _assert_png(out / "b.png")


def test_interrupted_plotting_keeps_the_data(tmp_path: Path, small_run: PlanRun) -> None:
    def interrupted(path: Path) -> None:
        path.write_bytes(b"half a figure")
        raise KeyboardInterrupt

    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt):
        output.write_plan(out, {"reached": True}, small_run.trajectory, [("a.png", interrupted)])
    assert sorted(p.name for p in out.iterdir()) == ["metrics.json", "trajectory.csv"]
    assert json.loads((out / "metrics.json").read_text()) == {"reached": True}


def test_plan_reports_a_failed_figure_and_keeps_the_rest(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    mission = _write_mission(tmp_path, 6)
    out = tmp_path / "out"
    assert main(["plan", str(mission), "--out", str(out)]) == 0
    assert (out / "fig08_speed.png").exists()
    capsys.readouterr()

    def broken(*args: object, **kwargs: object) -> None:
        raise RuntimeError("speed axis on fire")

    monkeypatch.setattr(plots, "speeds", broken)
    assert main(["plan", str(mission), "--out", str(out)]) == EXIT_PLOT_FAILED
    err = capsys.readouterr().err
    assert "gcs-ppf: error: figure fig08_speed.png not drawn: RuntimeError: speed axis on fire" in (
        err.splitlines()
    )
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["plot_errors"] == {"fig08_speed.png": "RuntimeError: speed axis on fire"}
    assert set(metrics["per_vehicle"]) == {str(i) for i in range(1, 7)}
    with (out / "trajectory.csv").open() as f:
        assert len(list(csv.DictReader(f))) % 6 == 0
    # The previous run's fig08 is gone with the rest of it: nothing stale, nothing partial.
    assert {p.name for p in out.iterdir()} == (FIGURES - {"fig08_speed.png"}) | {
        "metrics.json",
        "trajectory.csv",
    }
    for name in FIGURES - {"fig08_speed.png"}:
        _assert_png(out / name)

"""``gcs-ppf plan``: outputs of CONVENTIONS §4, exit code 2 and nothing written on bad input."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

from gcs_ppf.cli import main
from tests.conftest import EXAMPLES


def test_plan_writes_metrics_trajectory_and_plots(tmp_path: Path) -> None:
    out = tmp_path / "plan"
    assert main(["plan", str(EXAMPLES / "paper_table3.json"), "--out", str(out)]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    for key in (
        "reached",
        "flight_time_s",
        "formation_time_s",
        "min_separation_m",
        "min_obstacle_clearance_m",
        "collisions",
        "max_pitch_rate_rad_s",
        "max_yaw_rate_rad_s",
        "min_speed_m_s",
        "max_speed_m_s",
        "max_accel_m_s2",
        "max_decel_m_s2",
        "planning_wall_time_s",
        "real_time_factor",
        "per_vehicle",
    ):
        assert key in metrics, key
    assert set(metrics["per_vehicle"]) == {"1", "2", "3", "4", "5"}
    assert metrics["comparison"]["smoother"] == "ppf"
    with (out / "trajectory.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == ["t", "id", "x", "y", "z", "pitch", "yaw", "speed", "state"]
    assert {r["state"] for r in rows} <= {"s1", "s2", "s3"}
    assert len(rows) % 5 == 0
    assert float(rows[-1]["t"]) == pytest.approx(metrics["flight_time_s"], abs=1e-3)
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert "fig05_10_paths.png" in pngs
    assert "fig13_min_obstacle_distance.png" in pngs
    assert all((out / p).stat().st_size > 10_000 for p in pngs)


def _write_bad(tmp_path: Path, edit: str) -> Path:
    doc = json.loads((EXAMPLES / "paper_table3.json").read_text())
    exec(edit, {"doc": doc})  # the edits below are literal test code
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        ("doc['obstacles'][0]['radius'] = -1", "obstacles[0].radius"),
        ("doc['vehicles'][1]['id'] = 1", "vehicles[1].id"),
        ("doc['planner']['speed'] = 3", "planner.speed"),
        ("doc['target'][0] = float('inf')", "target[0]"),
    ],
)
def test_bad_mission_exit_code_2_message_and_no_output(
    tmp_path: Path, edit: str, field: str
) -> None:
    mission = _write_bad(tmp_path, edit)
    out = tmp_path / "out"
    result = subprocess.run(
        [sys.executable, "-m", "gcs_ppf.cli", "plan", str(mission), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert field in lines[0]
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.json"]


def test_missing_file_and_bad_dt_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", str(tmp_path / "nope.json"), "--out", str(tmp_path / "o")]) == 2
    assert "nope.json" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_info:
        main(
            ["plan", str(EXAMPLES / "paper_table3.json"), "--out", str(tmp_path / "o"), "--dt", "0"]
        )
    assert exit_info.value.code == 2
    assert not (tmp_path / "o").exists()

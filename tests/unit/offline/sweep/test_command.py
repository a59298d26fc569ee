"""`gcs-ppf sweep` end to end: the table, the summary and the figures; bad input is exit 2
with the field named, and nothing written."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from PIL import Image

from gcs_ppf.cli import main
from gcs_ppf.offline.sweep.command import EXIT_BAD_INPUT
from gcs_ppf.offline.sweep.table import COLUMNS, read_table

FIGURES = ("sweep_outcomes.png", "sweep_separation_clearance.png", "sweep_flight_time.png")


def test_a_sweep_writes_its_table_summary_and_figures(tmp_path: Path) -> None:
    spec = tmp_path / "mine.toml"
    spec.write_text("planner = { dt = 0.05 }\n[fleet]\nwingmen = [1, 2]\n")
    out = tmp_path / "out"
    assert main(["sweep", "feasible", str(spec), "--n", "4", "--jobs", "1", "--out", str(out)]) == 0
    rows = read_table(out / "sweep.csv")
    assert [(r.family, r.index) for r in rows] == [
        (f, i) for f in ("feasible", "mine") for i in range(4)
    ]
    assert all(r.dt_s == 0.05 and r.vehicles in (2, 3) for r in rows if r.family == "mine")
    assert (out / "sweep.csv").read_text().splitlines()[0].split(",") == list(COLUMNS)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["scenes"] == 8
    assert summary["command"]["n"] == 4
    assert summary["specs"]["mine"]["fleet"]["wingmen"] == [1, 2]
    assert set(summary["families"]) == {"feasible", "mine"}
    assert summary["families"]["mine"]["scenes"] == 4
    for name in FIGURES:
        with Image.open(out / name) as image:
            assert image.format == "PNG"
            assert image.width > 300


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["nowhere", "--n", "2"], "'nowhere' is neither a family"),
        (["feasible", "--n", "0"], "--n: must be at least 1"),
        (["feasible", "feasible", "--n", "2"], "two families share a name"),
        (["BAD", "--n", "2"], "obstacles.radius_m: low 700 exceeds high 30"),
    ],
)
def test_bad_input_is_named_and_nothing_is_written(
    args: list[str], words: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[obstacles]\nradius_m = [700.0, 30.0]\n")
    args = [str(bad) if a == "BAD" else a for a in args]
    out = tmp_path / "out"
    assert main(["sweep", *args, "--jobs", "1", "--out", str(out)]) == EXIT_BAD_INPUT
    assert words in capsys.readouterr().err
    assert not out.exists()

"""The CSV table reads back to the same rows."""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path

from gcs_ppf.offline.sweep.rows import SceneRow
from gcs_ppf.offline.sweep.table import COLUMNS, MEASURED, read_table, write_table


def test_a_table_reads_back_exactly(rows: list[SceneRow], tmp_path: Path) -> None:
    path = tmp_path / "sweep.csv"
    write_table(rows, path)
    assert read_table(path) == rows
    assert path.read_text().splitlines()[0] == ",".join(COLUMNS)
    assert not list(tmp_path.glob(".*partial"))


def test_only_the_wall_time_is_measured() -> None:
    assert MEASURED == ("planning_wall_time_s",)
    assert set(MEASURED) <= {f.name for f in fields(SceneRow)}

"""A sweep's table as CSV: one row per scene, the columns of ``SceneRow`` in its order.

Numbers are written as Python's shortest repr (they read back to the same float), None
as an empty cell, booleans as ``true`` / ``false``. Parquet is not written: pyarrow is not
among the locked dependencies, and a CSV of 10,000 scenes is 2 MB.
"""

from __future__ import annotations

import csv
import os
from collections.abc import Sequence
from dataclasses import asdict, fields
from pathlib import Path
from typing import Any

from pydantic import TypeAdapter

from gcs_ppf.offline.sweep.rows import SceneRow

COLUMNS = tuple(f.name for f in fields(SceneRow))
MEASURED = ("planning_wall_time_s",)
"""Columns that are measured, not computed, and differ between runs of the same sweep."""
_ROW = TypeAdapter(SceneRow)


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def write_table(rows: Sequence[SceneRow], path: Path) -> None:
    """Write ``rows`` to ``path`` whole (through a scratch file and a rename)."""
    scratch = path.with_name(f".{path.name}.partial")
    with scratch.open("w", newline="", encoding="utf-8") as f:
        out = csv.writer(f)
        out.writerow(COLUMNS)
        for row in rows:
            values = asdict(row)
            out.writerow([_cell(values[c]) for c in COLUMNS])
    os.replace(scratch, path)


def read_table(path: Path) -> list[SceneRow]:
    """The rows of a table written by ``write_table``."""
    with path.open(newline="", encoding="utf-8") as f:
        return [
            _ROW.validate_python(
                {k: (v if v != "" or k == "error" else None) for k, v in r.items()}
            )
            for r in csv.DictReader(f)
        ]

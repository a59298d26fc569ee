"""Writing a plan's outputs (CONVENTIONS §4) into a directory.

The data (``metrics.json``, ``trajectory.csv``) goes in first, all or nothing; the
figures follow one by one, each written whole or not at all.  A figure that fails is
reported (``plot_errors`` in ``metrics.json``, returned to the caller) and never costs
the data or the other figures.
"""

from __future__ import annotations

import contextlib
import csv
import json
import os
import shutil
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from gcs_ppf.planning.planner import STATE_NAMES, Trajectory


def write_trajectory_csv(trajectory: Trajectory, path: Path) -> None:
    """One row per vehicle per recorded step: t,id,x,y,z,pitch,yaw,speed,state."""
    tr = trajectory
    with path.open("w", newline="") as f:
        out = csv.writer(f)
        out.writerow(["t", "id", "x", "y", "z", "pitch", "yaw", "speed", "state"])
        ids = tr.ids.tolist()
        for k in range(len(tr)):
            t = f"{tr.t[k]:.4f}"
            for i, vid in enumerate(ids):
                x, y, z = tr.pos[k, i]
                out.writerow(
                    [
                        t,
                        vid,
                        f"{x:.3f}",
                        f"{y:.3f}",
                        f"{z:.3f}",
                        f"{tr.pitch[k, i]:.6f}",
                        f"{tr.yaw[k, i]:.6f}",
                        f"{tr.speed[k, i]:.3f}",
                        STATE_NAMES[int(tr.state[k, i])],
                    ]
                )


def write_json(data: Any, path: Path) -> None:
    path.write_text(json.dumps(data, indent=2, allow_nan=False) + "\n")


def replace_json(data: Any, path: Path) -> None:
    """Write ``path`` through a scratch file and a rename: readers see old or new, whole."""
    scratch = path.with_name(f".{path.name}.partial")
    write_json(data, scratch)
    os.replace(scratch, path)


def write_atomically(out_dir: Path, fill: Callable[[Path], None]) -> None:
    """Call ``fill`` on a fresh scratch directory next to ``out_dir`` and, only if it
    returns, put the scratch directory in place of ``out_dir``: nothing partial is left."""
    out_dir = out_dir.resolve()
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.", dir=out_dir.parent))
    try:
        fill(scratch)
        if out_dir.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.old.", dir=out_dir.parent))
            old.rmdir()
            out_dir.rename(old)
            scratch.rename(out_dir)
            shutil.rmtree(old, ignore_errors=True)
        else:
            scratch.rename(out_dir)
    except BaseException:
        shutil.rmtree(scratch, ignore_errors=True)
        raise


Draw = Callable[[Path], None]
MAX_ERROR_CHARS = 300


def describe_error(exc: BaseException) -> str:
    """``ValueError: first line of the message`` (shortened): one line for a log."""
    lines = str(exc).strip().splitlines()
    text = f"{type(exc).__name__}: {lines[0]}" if lines else type(exc).__name__
    return text if len(text) <= MAX_ERROR_CHARS else text[: MAX_ERROR_CHARS - 1] + "…"


def write_plan(
    out_dir: Path,
    metrics: dict[str, Any],
    trajectory: Trajectory,
    figures: Iterable[tuple[str, Draw]] = (),
) -> dict[str, str]:
    """Put ``metrics.json`` and ``trajectory.csv`` in place of ``out_dir`` (all or
    nothing), then draw each figure into it.

    A figure is drawn to a scratch name and renamed, so a failed one leaves no file;
    its error goes into ``metrics.json`` under ``plot_errors`` (file name → error) and
    the others are still drawn.  Returns those errors (empty when every figure was
    drawn).  Interrupts (``KeyboardInterrupt``) stop the drawing but the data stays.
    """
    out_dir = out_dir.resolve()

    def fill(d: Path) -> None:
        write_json(metrics, d / "metrics.json")
        write_trajectory_csv(trajectory, d / "trajectory.csv")

    write_atomically(out_dir, fill)
    errors = draw_figures(out_dir, figures)
    if errors:
        replace_json({**metrics, "plot_errors": errors}, out_dir / "metrics.json")
    return errors


def draw_figures(out_dir: Path, figures: Iterable[tuple[str, Draw]]) -> dict[str, str]:
    """Draw each figure into ``out_dir``, each to a scratch name then renamed (a failed one
    leaves no file); returns the errors of those that failed (file name → error)."""
    errors: dict[str, str] = {}
    for name, draw in figures:
        scratch = out_dir / f".partial-{name}"  # keeps the extension that picks the format
        try:
            draw(scratch)
            os.replace(scratch, out_dir / name)
        except Exception as exc:
            errors[name] = describe_error(exc)
        finally:
            with contextlib.suppress(FileNotFoundError):
                scratch.unlink()
    return errors

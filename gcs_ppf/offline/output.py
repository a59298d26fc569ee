"""Writing a plan's outputs (CONVENTIONS §4) into a directory, all or nothing."""

from __future__ import annotations

import csv
import json
import shutil
import tempfile
from collections.abc import Callable
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

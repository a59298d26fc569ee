"""What the closed loop's planning margins do to a mission's formation, planned offline.

``python -m gcs_ppf.offline.margin_effect MISSION --obstacle-margin 100 --teammate-margins 0
15 45.7`` plans the mission from its start once per teammate margin, with both safe
distances widened as the service widens them at every tick (``online.scene_now``), and
prints when the formation forms (every wingman within the target accuracy of its slot at
one same moment, on the records every 0.1 s), when the leader arrives, and the worst
wingman's distance from its slot at the best moment.  The flown loop plans every tick
with these margins: a mission whose plan does not form with them cannot form flown.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gcs_ppf.mission import load_mission
from gcs_ppf.planning.metrics import local_target_points
from gcs_ppf.planning.planner import advance
from gcs_ppf.planning.scene import Scene, scene_from_mission, with_margins

RECORD_EVERY = 10  # planner steps between records


@dataclass(frozen=True)
class MarginEffect:
    """One plan: the margins (m), when it formed (None: never) and arrived (s of flight),
    and the worst wingman's distance from its slot at the best moment (m)."""

    obstacle_margin_m: float
    teammate_margin_m: float
    formed_s: float | None
    arrived_s: float | None
    best_worst_m: float


def margin_effect(
    scene: Scene, obstacle_margin_m: float, teammate_margin_m: float, dt: float, max_time_s: float
) -> MarginEffect:
    """Plan ``scene`` with the margins and measure its formation."""
    widened = with_margins(scene, obstacle_margin_m, teammate_margin_m)
    result = advance(widened, dt, round(max_time_s / dt), record_every=RECORD_EVERY)
    tr = result.trajectory
    offsets = np.linalg.norm(local_target_points(tr, scene.fleet.slot) - tr.pos, axis=-1)
    worst = offsets[:, 1:].max(axis=1) if offsets.shape[1] > 1 else np.zeros(len(tr))
    together = worst <= scene.limits.target_accuracy
    return MarginEffect(
        obstacle_margin_m,
        teammate_margin_m,
        float(tr.t[np.argmax(together)]) if together.any() else None,
        result.t_s if result.arrived else None,
        float(worst.min()),
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("mission", type=Path)
    parser.add_argument("--obstacle-margin", type=float, default=100.0, help="m")
    parser.add_argument(
        "--teammate-margins", type=float, nargs="+", default=[0.0, 15.0, 45.7], help="m"
    )
    args = parser.parse_args(argv)
    mission = load_mission(args.mission.read_text())
    scene = scene_from_mission(mission)
    dt, max_time = mission.planner.dt, mission.planner.max_time
    print("obstacle m  teammate m  formed s  arrived s  worst wingman at best m")
    for teammate in args.teammate_margins:
        e = margin_effect(scene, args.obstacle_margin, teammate, dt, max_time)
        formed = "never" if e.formed_s is None else f"{e.formed_s:.1f}"
        arrived = "never" if e.arrived_s is None else f"{e.arrived_s:.2f}"
        print(
            f"{e.obstacle_margin_m:10.1f}  {e.teammate_margin_m:10.1f}  {formed:>8}  "
            f"{arrived:>9}  {e.best_worst_m:24.1f}"
        )


if __name__ == "__main__":
    main()

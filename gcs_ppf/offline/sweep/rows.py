"""One row of a sweep's table: a scene drawn, planned, and judged by the plan's metrics.

The figures are ``metrics.json``'s (``gcs_ppf.planning.metrics``, CONVENTIONS §4), read
from ``plan_mission``; the row adds the scene's identity (family, seed, index), its size,
the straight-line time and one outcome. Everything but ``planning_wall_time_s`` depends
on the family, the seed and the index alone, so a row is the same whichever process or
machine plans it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from gcs_ppf.mission import Mission
from gcs_ppf.offline.plan import plan_mission
from gcs_ppf.offline.sweep.scenes import SceneError, draw_scene
from gcs_ppf.offline.sweep.spec import SceneSpec


class Outcome(StrEnum):
    """How a scene ended; the first that applies, in this order."""

    CLEARANCE = "clearance"
    """A vehicle came closer than ``safe_distance_obstacle`` to an obstacle's surface."""
    GROUND = "ground"
    """A vehicle came closer than ``safe_distance_obstacle`` to the ground."""
    SEPARATION = "separation"
    """Two vehicles came closer than ``safe_distance_uav``."""
    NOT_REACHED = "not_reached"
    """Safe, but the leader was not at the target within ``planner.max_time``."""
    REACHED = "reached"
    """The leader reached the target and both safe distances held throughout."""
    ERROR = "error"
    """No scene could be drawn, or planning raised (``error`` says what)."""


@dataclass(frozen=True)
class SceneRow:
    """One planned scene; distances in metres, times in seconds, None where there is none
    (no teammate, no obstacle, no ground, not reached, not planned)."""

    family: str
    index: int
    seed: int
    vehicles: int | None
    obstacles: int | None
    dt_s: float
    outcome: Outcome
    reached: bool
    flight_time_s: float | None
    straight_line_time_s: float | None
    """The leader's start to the target's accuracy sphere in a straight line at v_max: no
    flight is shorter."""
    formation_time_s: float | None
    min_separation_m: float | None
    min_obstacle_clearance_m: float | None
    min_ground_clearance_m: float | None
    collisions: int | None
    error: str
    planning_wall_time_s: float | None
    """Measured, so it differs from run to run (the only such column)."""


def straight_line_time_s(mission: Mission) -> float:
    """Seconds for the leader to fly straight to the target's accuracy sphere at v_max."""
    lim = mission.limits
    gap = math.dist(mission.leader.position, mission.target) - lim.target_accuracy
    return max(gap, 0.0) / lim.v_max


def outcome(metrics: dict[str, Any], mission: Mission) -> Outcome:
    """The scene's ``Outcome`` from its plan's metrics."""
    lim = mission.limits

    def below(key: str, safe: float) -> bool:
        value = metrics[key]
        return value is not None and value < safe

    if below("min_obstacle_clearance_m", lim.safe_distance_obstacle):
        return Outcome.CLEARANCE
    if below("min_ground_clearance_m", lim.safe_distance_obstacle):
        return Outcome.GROUND
    if below("min_separation_m", lim.safe_distance_uav):
        return Outcome.SEPARATION
    return Outcome.REACHED if metrics["reached"] else Outcome.NOT_REACHED


def plan_scene(spec: SceneSpec, seed: int, index: int) -> SceneRow:
    """Draw scene ``index`` of ``spec`` for ``seed``, plan it, and judge it. A scene that
    cannot be drawn or planned is a row with ``Outcome.ERROR``, not an exception: one bad
    scene does not end a sweep."""
    base: dict[str, Any] = {
        "family": spec.name,
        "index": index,
        "seed": seed,
        "dt_s": spec.planner.dt,
        "vehicles": None,
        "obstacles": None,
        "straight_line_time_s": None,
    }
    try:
        mission = draw_scene(spec, seed, index)
    except SceneError as exc:
        return _error_row(base, str(exc))
    base.update(
        vehicles=len(mission.vehicles),
        obstacles=len(mission.obstacles) + len(mission.zones),
        straight_line_time_s=straight_line_time_s(mission),
    )
    try:
        run = plan_mission(mission)
    except Exception as exc:  # any failure of one scene is that scene's row
        return _error_row(base, f"{type(exc).__name__}: {exc}")
    m = run.metrics
    return SceneRow(
        **base,
        outcome=outcome(m, mission),
        reached=m["reached"],
        flight_time_s=m["flight_time_s"],
        formation_time_s=m["formation_time_s"],
        min_separation_m=m["min_separation_m"],
        min_obstacle_clearance_m=m["min_obstacle_clearance_m"],
        min_ground_clearance_m=m["min_ground_clearance_m"],
        collisions=m["collisions"],
        error="",
        planning_wall_time_s=run.wall_time_s,
    )


def _error_row(base: dict[str, Any], error: str) -> SceneRow:
    return SceneRow(
        **base,
        outcome=Outcome.ERROR,
        reached=False,
        flight_time_s=None,
        formation_time_s=None,
        min_separation_m=None,
        min_obstacle_clearance_m=None,
        min_ground_clearance_m=None,
        collisions=None,
        error=error,
        planning_wall_time_s=None,
    )

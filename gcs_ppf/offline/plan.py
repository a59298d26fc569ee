"""Offline planning: run the planner over a whole mission, timed, chunk by chunk.

This is the imperative shell around the pure ``planner.advance``: it owns the clock (the
wall time of planning alone, after the one-time compilation) and reports progress.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from gcs_ppf.mission import Mission
from gcs_ppf.planning.metrics import FlightContext, compute_metrics
from gcs_ppf.planning.planner import Method, Trajectory, advance, initial_record
from gcs_ppf.planning.route import Loitering, leader_target, leg_flown, legs, onto_target
from gcs_ppf.planning.scene import FloatArray, Scene, scene_from_mission

Progress = Callable[[float], None]  # called with the flight time planned so far


@dataclass(frozen=True)
class PlanRun:
    """A planned mission: the full trajectory (initial state first) and its figures."""

    method: Method
    dt: float
    scene: Scene
    trajectory: Trajectory
    arrived: bool
    wall_time_s: float
    metrics: dict[str, Any]
    waypoints: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    """[W,3] the route's waypoints before the target (ICS)."""
    loiter_radii_m: FloatArray = field(default_factory=lambda: np.zeros(0))
    """[W] the circle each waypoint's loiter is flown on (0: none; ``Leg.loiter_radius_m``)."""


PROGRESS_CHUNKS = 10  # chunks planned between two progress reports


def warm_up(scene: Scene, dt: float, method: Method) -> None:
    """Compile (or load from numba's cache) the kernel, so that timing excludes it."""
    advance(scene, dt, 1, method=method)
    advance(scene, dt, 1, method=method, chunk_steps=1)


def flight_context(mission: Mission, scene: Scene) -> FlightContext:
    return FlightContext(
        target=scene.target,
        slot=scene.fleet.slot,
        obstacles=scene.obstacles,
        target_accuracy=mission.limits.target_accuracy,
        collision_radius=mission.limits.collision_radius,
        ground=mission.ground,
        zones=scene.zones,
    )


def plan_mission(
    mission: Mission,
    *,
    method: Method | None = None,
    dt: float | None = None,
    progress: Progress | None = None,
    chunk_s: float = 1.0,
) -> PlanRun:
    """Plan ``mission`` until the leader reaches its target (through the route's waypoints,
    leg by leg: ``gcs_ppf.planning.route``) or ``planner.max_time``, in
    chunks of ``chunk_s`` of flight (``advance`` with ``chunk_steps``: record times are
    summed chunk by chunk), reporting ``progress`` every ``PROGRESS_CHUNKS`` chunks."""
    method = method or mission.planner.method
    dt = dt or mission.planner.dt
    scene = scene_from_mission(mission)
    warm_up(scene, dt, method)
    chunk = max(1, round(chunk_s / dt))
    total_steps = max(1, round(mission.planner.max_time / dt))
    parts = [initial_record(scene)]
    route = legs(mission)
    state, t, steps, wall, arrived = scene, 0.0, 0, 0.0, False
    leg, leg_times = route[0], []
    loiter = Loitering(state.fleet.pos[0].copy()) if leg.loiter is not None else None
    while steps < total_steps and not arrived:
        fleet = state.fleet
        leg = onto_target(leg, fleet.pos[0], float(fleet.yaw[0]), float(fleet.speed[0]))
        turning = leg.turn_point_m is not None  # straight on to the turn point first
        previous = fleet.pos[0].copy()
        n = min((1 if loiter or turning else PROGRESS_CHUNKS) * chunk, total_steps - steps)
        # a loiter's leader steered a little ahead on the circle, one chunk at a time
        state = replace(state, target=leader_target(leg, fleet.pos[0]))
        start = time.perf_counter()
        result = advance(
            state,
            dt,
            n,
            method=method,
            t0=t,
            chunk_steps=chunk,
            goal_radius_m=0.0 if loiter or turning else leg.radius_m,
            finish_normal=None if loiter or turning else leg.finish_normal,
        )
        wall += time.perf_counter() - start
        parts.append(result.trajectory)
        state, arrived = result.scene, result.arrived
        steps += result.steps
        t = result.t_s
        if loiter is not None and leg.loiter is not None:
            loiter = loiter.on(leg, result.trajectory.pos[:, 0], t)
            arrived = loiter.flown(leg.loiter, t)
        elif turning:  # the waypoint passed on the way to the turn point
            track = np.concatenate([previous[None], result.trajectory.pos[:, 0]])
            arrived = any(leg_flown(leg, a, b) for a, b in itertools.pairwise(track))
        if arrived and not leg.final:  # on to the next leg
            leg_times.append(round(t, 3))
            leg, arrived = route[leg.index + 1], False
            loiter = Loitering(state.fleet.pos[0].copy()) if leg.loiter is not None else None
        if progress is not None:
            progress(t)
    trajectory = Trajectory.concatenate(parts)
    metrics = compute_metrics(trajectory, flight_context(mission, scene), planning_wall_time_s=wall)
    metrics["method"] = method
    metrics["dt_s"] = dt
    if mission.route:
        metrics["waypoint_times_s"] = leg_times
    waypoints = np.array([w.position for w in mission.route], dtype=float).reshape(-1, 3)
    radii = np.array([leg.loiter_radius_m for leg in route[:-1]], dtype=float)
    return PlanRun(method, dt, scene, trajectory, arrived, wall, metrics, waypoints, radii)

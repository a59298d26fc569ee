"""The planner's pure entry point: advance a scene by some steps of PPF (or APF).

``advance`` takes a ``Scene`` and returns the scene after the steps and the trajectory
it recorded; inputs are never mutated.  The service calls it online from telemetry, the
offline runner calls it chunk by chunk until the leader arrives.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from gcs_ppf.planning.ppf.neighbours import MATES_ALL_PAIRS, MATES_AUTO, MATES_GRID
from gcs_ppf.planning.rollout import APF, PPF, run_chunks, run_fleet
from gcs_ppf.planning.scene import BoolArray, FloatArray, IntArray, Scene

Method = Literal["ppf", "apf"]
MateSearch = Literal["auto", "all-pairs", "grid"]
_MATE_SEARCH = {"auto": MATES_AUTO, "all-pairs": MATES_ALL_PAIRS, "grid": MATES_GRID}
STATE_NAMES = {1: "s1", 2: "s2", 3: "s3"}  # PPF state codes of Trajectory.state
StateArray = NDArray[np.int8]


@dataclass(frozen=True)
class Trajectory:
    """Recorded steps: K records of N vehicles (vehicle order as in the scene).

    t[K] s; pos[K,N,3] m; pitch, yaw[K,N] rad; speed[K,N] m/s; state[K,N] PPF state
    1–3; avoiding[K,N] repelled by an obstacle or teammate; formed[K,N] wingman within
    the target accuracy of its local target point (as seen at the start of the step).
    """

    ids: IntArray
    t: FloatArray
    pos: FloatArray
    pitch: FloatArray
    yaw: FloatArray
    speed: FloatArray
    state: StateArray
    avoiding: BoolArray
    formed: BoolArray

    @staticmethod
    def concatenate(parts: list[Trajectory]) -> Trajectory:
        first = parts[0]
        fields = [f for f in first.__dataclass_fields__ if f != "ids"]
        joined = {f: np.concatenate([getattr(p, f) for p in parts]) for f in fields}
        return Trajectory(ids=first.ids, **joined)

    def __len__(self) -> int:
        return int(self.t.shape[0])


@dataclass(frozen=True)
class Advance:
    """Result of ``advance``: the scene afterwards, what was recorded, and whether the
    leader arrived (then ``elapsed_s`` stops at the arrival instant); ``t_s`` is the time
    of the scene afterwards (``t0`` plus ``elapsed_s``, chunk by chunk with ``chunk_steps``)."""

    scene: Scene
    trajectory: Trajectory
    arrived: bool
    steps: int
    elapsed_s: float
    t_s: float


def initial_record(scene: Scene, t0: float = 0.0) -> Trajectory:
    """The scene's state as a one-record trajectory at time ``t0``."""
    f = scene.fleet
    n = f.ids.shape[0]
    return Trajectory(
        ids=f.ids.copy(),
        t=np.array([t0]),
        pos=f.pos[None].copy(),
        pitch=f.pitch[None].copy(),
        yaw=f.yaw[None].copy(),
        speed=f.speed[None].copy(),
        state=np.ones((1, n), dtype=np.int8),
        avoiding=np.zeros((1, n), dtype=bool),
        formed=np.zeros((1, n), dtype=bool),
    )


def _room_for_records(
    k: int, n: int
) -> tuple[
    FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, StateArray, BoolArray, BoolArray
]:
    """Empty arrays for ``k`` records of ``n`` vehicles: t, pos, pitch, yaw, speed, state,
    avoiding, formed (as in ``Trajectory``)."""
    return (
        np.empty(k),
        np.empty((k, n, 3)),
        np.empty((k, n)),
        np.empty((k, n)),
        np.empty((k, n)),
        np.empty((k, n), dtype=np.int8),
        np.empty((k, n), dtype=bool),
        np.empty((k, n), dtype=bool),
    )


def advance(
    scene: Scene,
    dt: float,
    n_steps: int,
    *,
    method: Method = "ppf",
    record_every: int = 1,
    t0: float = 0.0,
    mates: MateSearch = "auto",
    chunk_steps: int | None = None,
    goal_radius_m: float | None = None,
    finish_normal: FloatArray | None = None,
) -> Advance:
    """Run ``n_steps`` planner steps of ``dt`` seconds from ``scene`` (stopping early when
    the leader reaches the target).  Records every ``record_every``-th step and the last;
    record times are ``t0`` plus the flight time since the start.  ``mates`` is how PPF
    finds the teammates each vehicle checks for conflicts (``nearby_teammates``); every
    choice gives the same plan.  With ``chunk_steps``, the result is exactly that of calls
    of ``chunk_steps`` steps one after the other, each from the last one's scene and time
    (``t_s``), their trajectories joined: the same plan, recorded from each chunk's start,
    its times the same floating-point sums (``run_chunks``), in one call.  The leader
    reaches ``scene.target`` within ``goal_radius_m`` (the target accuracy if None; 0:
    never) or across the finish line square to ``finish_normal`` (a route leg's end;
    ``gcs_ppf.planning.route``)."""
    if dt <= 0.0 or n_steps < 0 or record_every < 1 or (chunk_steps or 1) < 1:
        raise ValueError(
            "advance: dt > 0, n_steps >= 0, record_every >= 1 and chunk_steps >= 1 are required"
        )
    fleet = scene.fleet.copy()
    obstacles = scene.obstacles.copy()
    n = fleet.ids.shape[0]
    chunks = -(-n_steps // chunk_steps) if chunk_steps else 1
    k = n_steps // record_every + chunks + 1  # (only the records written are returned)
    rec_t, rec_pos, rec_pitch, rec_yaw, rec_speed, rec_state, rec_avoiding, rec_formed = (
        _room_for_records(k, n)
    )
    f, o, code = fleet, obstacles, PPF if method == "ppf" else APF
    radius = scene.limits.target_accuracy if goal_radius_m is None else float(goal_radius_m)
    finish = np.zeros(3) if finish_normal is None else np.asarray(finish_normal, dtype=float)
    if chunk_steps is None:
        steps, records, elapsed, arrived = run_fleet(
            f.pos,
            f.pitch,
            f.yaw,
            f.speed,
            f.slot,
            f.rank,
            f.active,
            o.center,
            o.radius,
            o.velocity,
            scene.target,
            scene.limits,
            float(dt),
            code,
            int(n_steps),
            int(record_every),
            rec_t,
            rec_pos,
            rec_pitch,
            rec_yaw,
            rec_speed,
            rec_state,
            rec_avoiding,
            rec_formed,
            _MATE_SEARCH[mates],
            radius,
            finish,
            scene.zones.planning_arrays,
        )
        t_s, times = t0 + elapsed, t0 + rec_t[:records]
    else:
        steps, records, t_s, arrived = run_chunks(
            f.pos,
            f.pitch,
            f.yaw,
            f.speed,
            f.slot,
            f.rank,
            f.active,
            o.center,
            o.radius,
            o.velocity,
            scene.target,
            scene.limits,
            float(dt),
            code,
            int(n_steps),
            int(record_every),
            int(chunk_steps),
            float(t0),
            rec_t,
            rec_pos,
            rec_pitch,
            rec_yaw,
            rec_speed,
            rec_state,
            rec_avoiding,
            rec_formed,
            _MATE_SEARCH[mates],
            radius,
            finish,
            scene.zones.planning_arrays,
        )
        elapsed, times = t_s - t0, rec_t[:records]
    trajectory = Trajectory(
        ids=fleet.ids.copy(),
        t=times,
        pos=rec_pos[:records],
        pitch=rec_pitch[:records],
        yaw=rec_yaw[:records],
        speed=rec_speed[:records],
        state=rec_state[:records],
        avoiding=rec_avoiding[:records],
        formed=rec_formed[:records],
    )
    after = Scene(
        fleet=fleet,
        obstacles=obstacles,
        target=scene.target,
        limits=scene.limits,
        zones=scene.zones,
    )
    return Advance(after, trajectory, bool(arrived), int(steps), float(elapsed), float(t_s))

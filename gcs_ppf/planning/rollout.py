"""Rolling the fleet forward: many steps of a planner's kernel, recorded.

Shared by both methods (``PPF`` = the paper's planner, ``APF`` = the classical baseline):
the loop, the recording and the arrival test live here once; each method contributes
only its ``*_fleet_step``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gcs_ppf.planning.apf import apf_fleet_step
from gcs_ppf.planning.ppf.kernel import KernelLimits, attitude_trig, fleet_step
from gcs_ppf.planning.ppf.neighbours import (
    MATES_ALL_PAIRS,
    mate_search_for,
    nearby_obstacles,
    nearby_teammates,
)

PPF = 0
APF = 1
NEIGHBOUR_LIST_STEPS = 25  # PPF refreshes each vehicle's nearby obstacles this often
MATE_LIST_STEPS = 25  # and its nearby teammates this often


@njit(cache=True)
def leader_arrival_fraction(
    start: np.ndarray, end: np.ndarray, target: np.ndarray, accuracy: float
) -> float:
    """Fraction s ∈ [0, 1] of the step start → end after which the leader is within the
    target accuracy, or −1 if it is not within it anywhere on the step.

    Checking the whole segment, not just its end, keeps a coarse Δt from stepping over
    the target sphere (30 m a step at 300 m/s and Δt = 0.1 s)."""
    ax = end[0] - start[0]
    ay = end[1] - start[1]
    az = end[2] - start[2]
    bx = target[0] - start[0]
    by = target[1] - start[1]
    bz = target[2] - start[2]
    a2 = ax * ax + ay * ay + az * az
    if bx * bx + by * by + bz * bz <= accuracy * accuracy:
        return 0.0
    if a2 == 0.0:
        return -1.0
    s = min(max((ax * bx + ay * by + az * bz) / a2, 0.0), 1.0)
    cx = bx - s * ax
    cy = by - s * ay
    cz = bz - s * az
    return s if cx * cx + cy * cy + cz * cz <= accuracy * accuracy else -1.0


@njit(cache=True)
def wrap_angle(a: float) -> float:
    """An angle wrapped to (−π, π] (one turn at most either way)."""
    if a > math.pi:
        return a - 2.0 * math.pi
    if a <= -math.pi:
        return a + 2.0 * math.pi
    return a


@njit(cache=True)
def cut_step_at(
    s: float,
    pos: np.ndarray,
    pitch: np.ndarray,
    yaw: np.ndarray,
    speed: np.ndarray,
    active: np.ndarray,
    prev_pos: np.ndarray,
    prev_motion: np.ndarray,
    obs_center: np.ndarray,
    obs_velocity: np.ndarray,
    dt: float,
) -> None:
    """Cut the step just taken at the fraction ``s`` of it: every active vehicle's state
    interpolated between ``prev_pos``/``prev_motion`` (speed, pitch, yaw) and now, the
    obstacles moved back by the rest of the step."""
    for i in range(pos.shape[0]):
        if not active[i]:
            continue
        for c in range(3):
            pos[i, c] = prev_pos[i, c] + s * (pos[i, c] - prev_pos[i, c])
        speed[i] = prev_motion[i, 0] + s * (speed[i] - prev_motion[i, 0])
        pitch[i] = prev_motion[i, 1] + s * (pitch[i] - prev_motion[i, 1])
        yaw[i] = wrap_angle(prev_motion[i, 2] + s * wrap_angle(yaw[i] - prev_motion[i, 2]))
    for j in range(obs_center.shape[0]):
        for c in range(3):
            obs_center[j, c] -= (1.0 - s) * obs_velocity[j, c] * dt


@njit(cache=True)
def rollout_buffers(
    pos: np.ndarray, pitch: np.ndarray, yaw: np.ndarray, obs_center: np.ndarray
) -> tuple[
    tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    np.ndarray,
    np.ndarray,
    np.ndarray,
]:
    """The working arrays of a rollout of N vehicles among M obstacles: the step's scratch
    (state, avoiding, formed, direction, local_target, next_motion), the neighbour lists
    (near_start, near_obstacles, mate_start, mates), the previous positions and motions,
    and ``trig`` (``attitude_trig`` of the start, then kept by ``fleet_step``)."""
    n = pos.shape[0]
    scratch = (
        np.ones(n, dtype=np.int8),
        np.zeros(n, dtype=np.bool_),
        np.zeros(n, dtype=np.bool_),
        np.empty((n, 3)),
        np.empty((n, 3)),
        np.empty((n, 3)),
    )
    lists = (
        np.zeros(n + 1, dtype=np.int64),
        np.empty(n * obs_center.shape[0], dtype=np.int64),
        np.zeros(n + 1, dtype=np.int64),
        np.empty(4 * n, dtype=np.int64),
    )
    trig = np.empty((n, 7))
    attitude_trig(pitch, yaw, trig)
    return scratch, lists, np.empty((n, 3)), np.empty((n, 3)), trig


@njit(cache=True)
def run_fleet(
    pos: np.ndarray, pitch: np.ndarray, yaw: np.ndarray, speed: np.ndarray, slot: np.ndarray,
    rank: np.ndarray, active: np.ndarray, obs_center: np.ndarray, obs_radius: np.ndarray,
    obs_velocity: np.ndarray, target: np.ndarray, lim: KernelLimits, dt: float, method: int,
    n_steps: int, record_every: int, rec_dt: np.ndarray, rec_pos: np.ndarray,
    rec_pitch: np.ndarray, rec_yaw: np.ndarray, rec_speed: np.ndarray, rec_state: np.ndarray,
    rec_avoiding: np.ndarray, rec_formed: np.ndarray, mate_search: int,
) -> tuple[int, int, float, bool]:  # fmt: skip
    """Run up to ``n_steps`` steps in place, stopping when the leader reaches the target.

    ``mate_search`` is how PPF finds the teammates a vehicle looks at (``nearby_teammates``:
    ``MATES_ALL_PAIRS``, ``MATES_GRID`` or ``MATES_AUTO``; the plan is the same).
    Records every ``record_every``-th step and the last one into the ``rec_*`` arrays
    (``rec_dt[k]`` is the flight time since the start of this run).  The final step is cut
    short at the point where the leader enters the target accuracy, every vehicle's
    state interpolated to that instant (``cut_step_at``).  Returns (steps taken, records
    written, elapsed flight time, whether the leader arrived).
    """
    scratch, lists, prev_pos, prev_motion, trig = rollout_buffers(pos, pitch, yaw, obs_center)
    state, avoiding, formed, direction, local_target, next_motion = scratch
    near_start, near_obstacles, mate_start, mates = lists
    mate_search = mate_search_for(mate_search, pos.shape[0])
    elapsed = 0.0
    records = 0
    for step in range(n_steps):
        prev_pos[:, :] = pos
        prev_motion[:, 0] = speed
        prev_motion[:, 1] = pitch
        prev_motion[:, 2] = yaw
        if method == PPF:
            if step % NEIGHBOUR_LIST_STEPS == 0:
                nearby_obstacles(pos, obs_center, obs_radius, obs_velocity, lim, dt,
                                 NEIGHBOUR_LIST_STEPS, near_start, near_obstacles)  # fmt: skip
            if step == 0 or (mate_search != MATES_ALL_PAIRS and step % MATE_LIST_STEPS == 0):
                mates = nearby_teammates(pos, pitch, yaw, speed, rank, active, lim, dt,
                                         MATE_LIST_STEPS, mate_search, mate_start,
                                         mates)  # fmt: skip
            fleet_step(
                pos, pitch, yaw, speed, slot, rank, active, obs_center, obs_radius,
                obs_velocity, target, lim, dt, state, avoiding, formed, direction,
                local_target, next_motion, near_start, near_obstacles, mate_start, mates, trig,
            )  # fmt: skip
        else:
            apf_fleet_step(
                pos, pitch, yaw, speed, slot, rank, active, obs_center, obs_radius,
                obs_velocity, target, lim, dt, state, avoiding, formed, direction,
                local_target, next_motion,
            )  # fmt: skip
        s = leader_arrival_fraction(prev_pos[0], pos[0], target, lim.target_accuracy)
        arrived = s >= 0.0
        if arrived:
            cut_step_at(s, pos, pitch, yaw, speed, active, prev_pos, prev_motion,
                        obs_center, obs_velocity, dt)  # fmt: skip
        elapsed += s * dt if arrived else dt
        due = arrived or (step + 1) % record_every == 0 or step == n_steps - 1
        if due and records < rec_dt.shape[0]:
            rec_dt[records] = elapsed
            rec_pos[records] = pos
            rec_pitch[records] = pitch
            rec_yaw[records] = yaw
            rec_speed[records] = speed
            rec_state[records] = state
            rec_avoiding[records] = avoiding
            rec_formed[records] = formed
            records += 1
        if arrived:
            return step + 1, records, elapsed, True
    return n_steps, records, elapsed, False

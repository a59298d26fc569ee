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
from gcs_ppf.planning.ppf.compiled import njit_without_refcounts
from gcs_ppf.planning.ppf.kernel import KernelLimits, attitude_trig, fleet_step
from gcs_ppf.planning.ppf.neighbours import (
    MATES_ALL_PAIRS,
    mate_search_for,
    nearby_obstacles,
    nearby_teammates,
    nearby_zones,
    refine_teammates,
)
from gcs_ppf.planning.ppf.primitives import TRIG_COLUMNS

PPF = 0
APF = 1
NEIGHBOUR_LIST_STEPS = 25  # PPF refreshes each vehicle's nearby obstacles this often
MATE_LIST_STEPS = NEIGHBOUR_LIST_STEPS  # and its nearby teammates (at the same steps)
MATE_REFINE_STEPS = 5  # and those of them within reach this often (a divisor of the above)


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
def finish_line_fraction(
    start: np.ndarray, end: np.ndarray, waypoint: np.ndarray, normal: np.ndarray
) -> float:
    """Fraction s ∈ [0, 1] of the step start → end at which it crosses the plane through
    ``waypoint`` square to ``normal`` (a route leg's finish line, ArduPlane's way of
    counting a waypoint passed wide as reached), or −1 if it does not cross it forwards;
    −1 always for a zero ``normal`` (no finish line: the route's target)."""
    a = 0.0
    b = 0.0
    for c in range(3):
        a += (start[c] - waypoint[c]) * normal[c]
        b += (end[c] - waypoint[c]) * normal[c]
    if normal[0] == 0.0 and normal[1] == 0.0 and normal[2] == 0.0:
        return -1.0
    if a < 0.0 <= b:
        return a / (a - b)
    return -1.0


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
    trig = np.zeros((n, TRIG_COLUMNS))
    attitude_trig(pitch, yaw, trig)
    return scratch, lists, np.empty((n, 3)), np.empty((n, 3)), trig


@njit(cache=True, inline="always")
def remember(
    pos: np.ndarray,
    pitch: np.ndarray,
    yaw: np.ndarray,
    speed: np.ndarray,
    prev_pos: np.ndarray,
    prev_motion: np.ndarray,
) -> None:
    """The state before a step: positions into ``prev_pos``, (speed, pitch, yaw) into
    ``prev_motion`` (for ``cut_step_at``)."""
    for i in range(pos.shape[0]):
        for c in range(3):
            prev_pos[i, c] = pos[i, c]
        prev_motion[i, 0] = speed[i]
        prev_motion[i, 1] = pitch[i]
        prev_motion[i, 2] = yaw[i]


@njit(cache=True, inline="always")
def record(
    k: int,
    pos: np.ndarray,
    pitch: np.ndarray,
    yaw: np.ndarray,
    speed: np.ndarray,
    state: np.ndarray,
    avoiding: np.ndarray,
    formed: np.ndarray,
    rec_pos: np.ndarray,
    rec_pitch: np.ndarray,
    rec_yaw: np.ndarray,
    rec_speed: np.ndarray,
    rec_state: np.ndarray,
    rec_avoiding: np.ndarray,
    rec_formed: np.ndarray,
) -> None:
    """The fleet's state into record ``k`` of the ``rec_*`` arrays."""
    for i in range(pos.shape[0]):
        for c in range(3):
            rec_pos[k, i, c] = pos[i, c]
        rec_pitch[k, i] = pitch[i]
        rec_yaw[k, i] = yaw[i]
        rec_speed[k, i] = speed[i]
        rec_state[k, i] = state[i]
        rec_avoiding[k, i] = avoiding[i]
        rec_formed[k, i] = formed[i]


@njit_without_refcounts
def run_steps(
    pos: np.ndarray,
    pitch: np.ndarray,
    yaw: np.ndarray,
    speed: np.ndarray,
    slot: np.ndarray,
    rank: np.ndarray,
    active: np.ndarray,
    obs_center: np.ndarray,
    obs_radius: np.ndarray,
    obs_velocity: np.ndarray,
    target: np.ndarray,
    lim: KernelLimits,
    dt: float,
    method: int,
    first: int,
    last: int,
    n_steps: int,
    record_every: int,
    records: int,
    elapsed: float,
    rec_dt: np.ndarray,
    rec_pos: np.ndarray,
    rec_pitch: np.ndarray,
    rec_yaw: np.ndarray,
    rec_speed: np.ndarray,
    rec_state: np.ndarray,
    rec_avoiding: np.ndarray,
    rec_formed: np.ndarray,
    state: np.ndarray,
    avoiding: np.ndarray,
    formed: np.ndarray,
    direction: np.ndarray,
    local_target: np.ndarray,
    next_motion: np.ndarray,
    near_start: np.ndarray,
    near_obstacles: np.ndarray,
    mate_start: np.ndarray,
    mates: np.ndarray,
    prev_pos: np.ndarray,
    prev_motion: np.ndarray,
    trig: np.ndarray,
    goal_radius: float,
    finish: np.ndarray,
    zones: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    zone_start: np.ndarray,
    near_zones: np.ndarray,
) -> tuple[int, int, float, bool]:
    """Steps ``first`` to ``last`` − 1 of ``run_fleet`` (of ``n_steps``) with the neighbour
    lists as they are, recording and stopping at the leader's arrival as ``run_fleet``
    describes; ``records`` written and ``elapsed`` flight time so far.  Returns (the step
    after the last one taken, records written, elapsed flight time, whether the leader
    arrived).

    Compiled without numba's reference counting (``njit_without_refcounts``: it allocates
    nothing, and nothing it binds outlives the call).
    """
    for step in range(first, last):
        remember(pos, pitch, yaw, speed, prev_pos, prev_motion)
        if method == PPF:
            fleet_step(
                pos,
                pitch,
                yaw,
                speed,
                slot,
                rank,
                active,
                obs_center,
                obs_radius,
                obs_velocity,
                target,
                lim,
                dt,
                state,
                avoiding,
                formed,
                direction,
                local_target,
                next_motion,
                near_start,
                near_obstacles,
                mate_start,
                mates,
                trig,
                zones,
                zone_start,
                near_zones,
            )
        else:
            apf_fleet_step(
                pos,
                pitch,
                yaw,
                speed,
                slot,
                rank,
                active,
                obs_center,
                obs_radius,
                obs_velocity,
                target,
                lim,
                dt,
                state,
                avoiding,
                formed,
                direction,
                local_target,
                next_motion,
                zones,
            )
        s = leader_arrival_fraction(prev_pos[0], pos[0], target, goal_radius)
        if s < 0.0:
            s = finish_line_fraction(prev_pos[0], pos[0], target, finish)
        arrived = s >= 0.0
        if arrived:
            cut_step_at(
                s,
                pos,
                pitch,
                yaw,
                speed,
                active,
                prev_pos,
                prev_motion,
                obs_center,
                obs_velocity,
                dt,
            )
        elapsed += s * dt if arrived else dt
        due = arrived or (step + 1) % record_every == 0 or step == n_steps - 1
        if due and records < rec_dt.shape[0]:
            rec_dt[records] = elapsed
            record(
                records,
                pos,
                pitch,
                yaw,
                speed,
                state,
                avoiding,
                formed,
                rec_pos,
                rec_pitch,
                rec_yaw,
                rec_speed,
                rec_state,
                rec_avoiding,
                rec_formed,
            )
            records += 1
        if arrived:
            return step + 1, records, elapsed, True
    return last, records, elapsed, False


@njit(cache=True)
def run_fleet(
    pos: np.ndarray,
    pitch: np.ndarray,
    yaw: np.ndarray,
    speed: np.ndarray,
    slot: np.ndarray,
    rank: np.ndarray,
    active: np.ndarray,
    obs_center: np.ndarray,
    obs_radius: np.ndarray,
    obs_velocity: np.ndarray,
    target: np.ndarray,
    lim: KernelLimits,
    dt: float,
    method: int,
    n_steps: int,
    record_every: int,
    rec_dt: np.ndarray,
    rec_pos: np.ndarray,
    rec_pitch: np.ndarray,
    rec_yaw: np.ndarray,
    rec_speed: np.ndarray,
    rec_state: np.ndarray,
    rec_avoiding: np.ndarray,
    rec_formed: np.ndarray,
    mate_search: int,
    goal_radius: float,
    finish: np.ndarray,
    zones: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> tuple[int, int, float, bool]:
    """Run up to ``n_steps`` steps in place, stopping when the leader reaches the target:
    within ``goal_radius`` of it, or across its finish line (``finish``, the normal of the
    plane through it; zeros for none: ``finish_line_fraction``).

    ``mate_search`` is how PPF finds the teammates a vehicle looks at (``nearby_teammates``:
    ``MATES_ALL_PAIRS``, ``MATES_GRID`` or ``MATES_AUTO``; the plan is the same).
    Records every ``record_every``-th step and the last one into the ``rec_*`` arrays
    (``rec_dt[k]`` is the flight time since the start of this run).  The final step is cut
    short at the point where the leader enters the target accuracy, every vehicle's
    state interpolated to that instant (``cut_step_at``).  Returns (steps taken, records
    written, elapsed flight time, whether the leader arrived).

    The neighbour lists are made here (they allocate) and the steps between two lists
    taken by ``run_steps``: every ``NEIGHBOUR_LIST_STEPS`` steps the obstacles, the zones and (the
    grid) the teammates, and every ``MATE_REFINE_STEPS`` the teammates of those within
    reach over that many steps (``refine_teammates``).
    """
    scratch, lists, prev_pos, prev_motion, trig = rollout_buffers(pos, pitch, yaw, obs_center)
    state, avoiding, formed, direction, local_target, next_motion = scratch
    near_start, near_obstacles, mate_start, mates = lists
    zone_start = np.zeros(pos.shape[0] + 1, dtype=np.int64)
    near_zones = np.empty(pos.shape[0] * zones[0].shape[0], dtype=np.int64)
    mate_search = mate_search_for(mate_search, pos.shape[0])
    refine = method == PPF and mate_search != MATES_ALL_PAIRS
    close_start, close = np.zeros(pos.shape[0] + 1, dtype=np.int64), mates.copy()
    elapsed, records, step, arrived = 0.0, 0, 0, False
    while step < n_steps and not arrived:
        last = n_steps
        if method == PPF:
            last = min(step + (MATE_REFINE_STEPS if refine else NEIGHBOUR_LIST_STEPS), n_steps)
        if method == PPF and step % NEIGHBOUR_LIST_STEPS == 0:
            nearby_obstacles(
                pos,
                obs_center,
                obs_radius,
                obs_velocity,
                lim,
                dt,
                NEIGHBOUR_LIST_STEPS,
                near_start,
                near_obstacles,
            )
            nearby_zones(
                pos,
                speed,
                zones[0],
                zones[1],
                lim,
                dt,
                NEIGHBOUR_LIST_STEPS,
                zone_start,
                near_zones,
            )
            if step == 0 or mate_search != MATES_ALL_PAIRS:
                mates = nearby_teammates(
                    pos,
                    trig,
                    speed,
                    rank,
                    active,
                    lim,
                    dt,
                    MATE_LIST_STEPS,
                    mate_search,
                    mate_start,
                    mates,
                )
            if close.shape[0] < mates.shape[0]:
                close = np.empty(mates.shape[0], dtype=np.int64)
        step_start, step_mates = mate_start, mates
        if refine:
            refine_teammates(
                pos, trig, speed, lim, dt, MATE_REFINE_STEPS, mate_start, mates, close_start, close
            )
            step_start, step_mates = close_start, close
        step, records, elapsed, arrived = run_steps(
            pos,
            pitch,
            yaw,
            speed,
            slot,
            rank,
            active,
            obs_center,
            obs_radius,
            obs_velocity,
            target,
            lim,
            dt,
            method,
            step,
            last,
            n_steps,
            record_every,
            records,
            elapsed,
            rec_dt,
            rec_pos,
            rec_pitch,
            rec_yaw,
            rec_speed,
            rec_state,
            rec_avoiding,
            rec_formed,
            state,
            avoiding,
            formed,
            direction,
            local_target,
            next_motion,
            near_start,
            near_obstacles,
            step_start,
            step_mates,
            prev_pos,
            prev_motion,
            trig,
            goal_radius,
            finish,
            zones,
            zone_start,
            near_zones,
        )
    return step, records, elapsed, arrived


@njit(cache=True)
def run_chunks(
    pos: np.ndarray,
    pitch: np.ndarray,
    yaw: np.ndarray,
    speed: np.ndarray,
    slot: np.ndarray,
    rank: np.ndarray,
    active: np.ndarray,
    obs_center: np.ndarray,
    obs_radius: np.ndarray,
    obs_velocity: np.ndarray,
    target: np.ndarray,
    lim: KernelLimits,
    dt: float,
    method: int,
    n_steps: int,
    record_every: int,
    chunk_steps: int,
    t0: float,
    rec_t: np.ndarray,
    rec_pos: np.ndarray,
    rec_pitch: np.ndarray,
    rec_yaw: np.ndarray,
    rec_speed: np.ndarray,
    rec_state: np.ndarray,
    rec_avoiding: np.ndarray,
    rec_formed: np.ndarray,
    mate_search: int,
    goal_radius: float,
    finish: np.ndarray,
    zones: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> tuple[int, int, float, bool]:
    """``run_fleet`` ``chunk_steps`` steps at a time, exactly as that many calls of it one
    after the other: each chunk records from its own start (``record_every``), its record
    times are t at its start plus the flight time since (``rec_t`` receives them), and t
    (from ``t0``) grows by each chunk's flight time, the same floating-point sums.  Returns
    (steps taken, records written, t after them, whether the leader arrived)."""
    steps, records, t, arrived = 0, 0, t0, False
    while steps < n_steps and not arrived:
        n = min(chunk_steps, n_steps - steps)
        taken, written, elapsed, arrived = run_fleet(
            pos,
            pitch,
            yaw,
            speed,
            slot,
            rank,
            active,
            obs_center,
            obs_radius,
            obs_velocity,
            target,
            lim,
            dt,
            method,
            n,
            record_every,
            rec_t[records:],
            rec_pos[records:],
            rec_pitch[records:],
            rec_yaw[records:],
            rec_speed[records:],
            rec_state[records:],
            rec_avoiding[records:],
            rec_formed[records:],
            mate_search,
            goal_radius,
            finish,
            zones,
        )
        for r in range(records, records + written):
            rec_t[r] = t + rec_t[r]
        records += written
        steps += taken
        t += elapsed
    return steps, records, t, arrived

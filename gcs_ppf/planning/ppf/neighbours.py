"""Neighbour lists for the PPF step: the obstacles and teammates each vehicle must look at.

Both are lists in CSR form (vehicle i's entries are ``items[start[i]:start[i+1]]``),
rebuilt every ``horizon_steps`` steps with a distance bound that holds for every step
until the next rebuild, so a step that reads them decides exactly as one that looks at
every obstacle and every teammate: the same candidates, in ascending index order, so even
the sums of repulsions are bit-identical.

Teammates are found either by looking at every pair (``MATES_ALL_PAIRS``) or in a uniform
grid of cells at least one bound wide, filled by a counting sort (``MATES_GRID``): a
vehicle then looks only at the 27 cells around its own.  Obstacles look at every vehicle
in small scenes, and at the vehicles in the grid cells their reach overlaps in big ones.
The step itself reads a shorter list of teammates, made every few steps from the longer
one (``refine_teammates``): over fewer steps the velocities can change less, so fewer
teammates can come within reach.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gcs_ppf.planning.ppf.primitives import (
    AVOIDANCE_TURN_ANGLE,
    CONFLICT_HORIZON_TURNS,
    INFLUENCE_STEPS,
    KernelLimits,
    airframe_limited,
    influence_radius,
)
from gcs_ppf.planning.zones import INCLUSION, zone_lower_bound

MATES_AUTO = -1  # the grid from ``GRID_MIN_VEHICLES`` vehicles on, all pairs below
MATES_ALL_PAIRS = 0  # every active teammate of higher priority, no distance bound
MATES_GRID = 1  # those within the bound, found in a uniform grid
GRID_MIN_VEHICLES = 16  # measured: equal at 10-16 vehicles, the grid 5 % faster at 20
MAX_GRID_CELLS_PER_VEHICLE = 64  # cells grow until the grid has at most this many per vehicle
OBSTACLE_GRID_MIN_PAIRS = 400  # pairs from which obstacles use the grid (faster from 20 × 20 on)


@njit(cache=True)
def obstacle_reach2(
    obs_radius: np.ndarray,
    obs_velocity: np.ndarray,
    lim: KernelLimits,
    dt: float,
    horizon_steps: int,
) -> np.ndarray:
    """The square of the farthest a vehicle can be from each obstacle's centre and come
    under its influence within ``horizon_steps`` steps, ``[M]``.

    A vehicle is influenced from at most keep_out + v_max/ω + v_max·Δt + u·T (the cheap
    bound in ``obstacle_repulsion``; one v_max/ω more for an ``airframe_limited`` one; the
    padded leader's keep-out and turn taken for every vehicle); over
    the horizon the two close by at most (v_max + u)·steps·Δt.
    """
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    turns = 2.0 if airframe_limited(lim) else 1.0  # the half turn of obstacle_repulsion
    turn_rate = omega  # the leader passing with its formation turns as that follows
    if lim.leader_keep_out_pad > 0.0:
        turn_rate = min(omega, lim.leader_turn_rate)
    m = obs_radius.shape[0]
    reach2 = np.empty(m)
    for j in range(m):
        u = math.sqrt(obs_velocity[j, 0] ** 2 + obs_velocity[j, 1] ** 2 + obs_velocity[j, 2] ** 2)
        reach = obs_radius[j] + lim.safe_distance_obstacle + lim.leader_keep_out_pad
        reach += lim.v_max / turn_rate + (turns - 1.0) * lim.v_max / omega
        reach += INFLUENCE_STEPS * lim.v_max * dt + u * AVOIDANCE_TURN_ANGLE / omega
        reach += (lim.v_max + u) * horizon_steps * dt
        reach2[j] = reach * reach
    return reach2


@njit(cache=True)
def nearby_obstacles(
    pos: np.ndarray,
    obs_center: np.ndarray,
    obs_radius: np.ndarray,
    obs_velocity: np.ndarray,
    lim: KernelLimits,
    dt: float,
    horizon_steps: int,
    near_start: np.ndarray,
    near_obstacles: np.ndarray,
) -> None:
    """The obstacles each vehicle could come under the influence of within the next
    ``horizon_steps`` steps (within ``obstacle_reach2``), so that a step need not look at
    all M.  Fills ``near_obstacles`` in CSR form: vehicle i's are
    ``near_obstacles[near_start[i]:near_start[i+1]]``, in ascending index order.  From
    ``OBSTACLE_GRID_MIN_PAIRS`` vehicle–obstacle pairs on, each obstacle looks only at the
    vehicles in the cells of a uniform grid that its reach overlaps."""
    n, m = pos.shape[0], obs_center.shape[0]
    reach2 = obstacle_reach2(obs_radius, obs_velocity, lim, dt, horizon_steps)
    if n * m < OBSTACLE_GRID_MIN_PAIRS:
        count = 0
        for i in range(n):
            near_start[i] = count
            for j in range(m):
                dx = pos[i, 0] - obs_center[j, 0]
                dy = pos[i, 1] - obs_center[j, 1]
                dz = pos[i, 2] - obs_center[j, 2]
                if dx * dx + dy * dy + dz * dz <= reach2[j]:
                    near_obstacles[count] = j
                    count += 1
        near_start[n] = count
        return
    _obstacles_grid(pos, obs_center, reach2, near_start, near_obstacles)


@njit(cache=True)
def _obstacles_grid(
    pos: np.ndarray,
    obs_center: np.ndarray,
    reach2: np.ndarray,
    near_start: np.ndarray,
    near_obstacles: np.ndarray,
) -> None:
    """``nearby_obstacles`` by a grid of the vehicles: the same lists."""
    n, m = pos.shape[0], obs_center.shape[0]
    _, low, shape, size, cell_start, in_cell = _grid(pos, math.sqrt(reach2.max()))
    pair_vehicle = np.empty(max(4 * n, 16), dtype=np.int64)
    pair_obstacle = np.empty(max(4 * n, 16), dtype=np.int64)
    pairs = 0
    counts = np.zeros(n + 1, dtype=np.int64)
    box = np.empty((3, 2), dtype=np.int64)
    for j in range(m):  # in ascending order, so that each vehicle's list is
        reach = math.sqrt(reach2[j])
        empty = False
        for c in range(3):
            lo = math.floor((obs_center[j, c] - reach - low[c]) / size)
            hi = math.floor((obs_center[j, c] + reach - low[c]) / size)
            if hi < 0 or lo >= shape[c]:
                empty = True
            box[c, 0], box[c, 1] = max(lo, 0), min(hi, shape[c] - 1)
        if empty:
            continue
        for ax in range(box[0, 0], box[0, 1] + 1):
            for ay in range(box[1, 0], box[1, 1] + 1):
                for az in range(box[2, 0], box[2, 1] + 1):
                    c = (ax * shape[1] + ay) * shape[2] + az
                    for s in range(cell_start[c], cell_start[c + 1]):
                        i = in_cell[s]
                        dx = pos[i, 0] - obs_center[j, 0]
                        dy = pos[i, 1] - obs_center[j, 1]
                        dz = pos[i, 2] - obs_center[j, 2]
                        if dx * dx + dy * dy + dz * dz <= reach2[j]:
                            pair_vehicle = _grow(pair_vehicle, pairs + 1)
                            pair_obstacle = _grow(pair_obstacle, pairs + 1)
                            pair_vehicle[pairs], pair_obstacle[pairs] = i, j
                            pairs += 1
                            counts[i + 1] += 1
    starts = np.cumsum(counts)
    near_start[:] = starts
    for p in range(pairs):  # a stable counting sort by vehicle
        i = pair_vehicle[p]
        near_obstacles[starts[i]] = pair_obstacle[p]
        starts[i] += 1


@njit(cache=True)
def nearby_zones(
    pos: np.ndarray,
    speed: np.ndarray,
    kind: np.ndarray,
    geom: np.ndarray,
    lim: KernelLimits,
    dt: float,
    horizon_steps: int,
    zone_start: np.ndarray,
    near_zones: np.ndarray,
) -> None:
    """The zones each vehicle could come under the influence of within the next
    ``horizon_steps`` steps, in CSR form as ``nearby_obstacles`` (ascending index order):
    every inclusion zone, and each exclusion zone whose bounding cylinder
    (``zone_lower_bound``) is within the farthest reach of ``zone_repulsion`` at the
    fastest speed (v/ω + the safe distance + a few steps; one v/ω more for an
    ``airframe_limited`` vehicle) plus the travel over the horizon."""
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    v = lim.v_max
    for i in range(pos.shape[0]):
        v = max(v, speed[i])
    turns = 2.0 if airframe_limited(lim) else 1.0
    reach = turns * v / omega + lim.safe_distance_obstacle + INFLUENCE_STEPS * v * dt
    reach += v * horizon_steps * dt
    count = 0
    for i in range(pos.shape[0]):
        zone_start[i] = count
        for k in range(kind.shape[0]):
            if kind[k] & INCLUSION or (
                zone_lower_bound(k, pos[i, 0], pos[i, 1], pos[i, 2], geom) <= reach
            ):
                near_zones[count] = k
                count += 1
    zone_start[pos.shape[0]] = count


@njit(cache=True)
def speed_bound(speed: float, lim: KernelLimits, dt: float, horizon_steps: int) -> float:
    """The highest speed a vehicle flying at ``speed`` can have within ``horizon_steps``
    steps: Eq. 3–5 add at most a·Δt a step, and speeds are kept within [v_min, v_max]."""
    grown = min(max(speed, lim.v_min) + lim.accel * horizon_steps * dt, lim.v_max)
    return max(speed, grown)


@njit(cache=True)
def mate_reach(vi: float, vk: float, lim: KernelLimits, dt: float, horizon_steps: int) -> float:
    """The farthest vehicle i (speed bound ``vi``) can be from teammate k (``vk``) now and
    still have it repel, or hold its course for it, within ``horizon_steps`` steps.

    ``teammate_conflict`` looks no further than R(v_i) + v_i·Δt + v_k·T (T a quarter-turn
    time), R the influence radius of the safe distance, growing with the speed; over the
    horizon the two close by at most (v_i + v_k)·steps·Δt.  A metre more covers round-off.
    """
    return mate_reach_own(vi, lim, dt, horizon_steps) + mate_reach_other(vk, lim, dt, horizon_steps)


@njit(cache=True)
def mate_reach_own(vi: float, lim: KernelLimits, dt: float, horizon_steps: int) -> float:
    """Vehicle i's part of ``mate_reach``: R(v_i) + v_i·Δt + v_i·steps·Δt, and the slack."""
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    reach = influence_radius(vi, omega, lim.safe_distance_uav) + vi * dt + vi * horizon_steps * dt
    return reach * (1.0 + 1e-9) + 1.0


@njit(cache=True)
def mate_reach_other(vk: float, lim: KernelLimits, dt: float, horizon_steps: int) -> float:
    """Teammate k's part of ``mate_reach``: v_k·T + v_k·steps·Δt, and the slack."""
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    reach = vk * AVOIDANCE_TURN_ANGLE / omega + vk * horizon_steps * dt
    return reach * (1.0 + 1e-9)


@njit(cache=True)
def miss_reach(
    vi: float, closing: float, lim: KernelLimits, dt: float, horizon_steps: int
) -> float:
    """The farthest vehicle i (speed bound ``vi``) can be from a teammate whose velocity
    relative to it stays below ``closing`` and still have it repel, or hold its course for
    it, within ``horizon_steps`` steps.

    ``teammate_conflict`` needs a closest approach within T_h (``CONFLICT_HORIZON_TURNS``
    quarter turns) of less than 2·d_s + 2·v_i·Δt + (turning, at most d_s); the miss is at
    least the distance less |w|·T_h, and the distance shrinks by at most |w|·Δt a step.
    """
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    horizon = CONFLICT_HORIZON_TURNS * AVOIDANCE_TURN_ANGLE / omega + horizon_steps * dt
    reach = 3.0 * lim.safe_distance_uav + 2.0 * vi * dt + closing * horizon
    return reach * (1.0 + 1e-9) + 1.0


@njit(cache=True)
def velocity_change(
    speed: float, bound: float, lim: KernelLimits, dt: float, horizon_steps: int
) -> float:
    """How far a vehicle's velocity vector can move within ``horizon_steps`` steps (m/s):
    its speed by a·Δt a step (or back into [v_min, v_max]), its direction by at most the
    pitch rate plus the yaw rate (Eq. 3–5), at speeds up to ``bound``."""
    t = horizon_steps * dt
    dv = max(lim.accel, lim.decel) * t + max(lim.v_min - speed, 0.0) + max(speed - lim.v_max, 0.0)
    return dv + bound * (lim.max_pitch_rate + lim.max_yaw_rate) * t


@njit(cache=True)
def _grow(items: np.ndarray, needed: int) -> np.ndarray:
    """``items`` with room for ``needed`` entries (doubled when short)."""
    if needed <= items.shape[0]:
        return items
    bigger = np.empty(max(needed, 2 * items.shape[0]), dtype=items.dtype)
    bigger[: items.shape[0]] = items
    return bigger


@njit(cache=True)
def _mates_all_pairs(
    rank: np.ndarray, active: np.ndarray, mate_start: np.ndarray, mates: np.ndarray
) -> np.ndarray:
    """Every active teammate of higher priority (lower rank), for each active vehicle."""
    n = rank.shape[0]
    count = 0
    for i in range(n):
        mate_start[i] = count
        if not active[i]:
            continue
        mates = _grow(mates, count + n)
        for k in range(n):
            if k != i and active[k] and rank[k] < rank[i]:
                mates[count] = k
                count += 1
    mate_start[n] = count
    return mates


@njit(cache=True)
def _grid(
    pos: np.ndarray, size: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray, np.ndarray]:
    """A uniform grid of ``size``-metre cells over the vehicles (grown until there are at
    most ``MAX_GRID_CELLS_PER_VEHICLE`` cells a vehicle).  Returns each vehicle's cell
    ``[N,3]``, the grid's low corner and shape (cells along x, y, z), the cell size, and the
    vehicles by cell: cell c's are ``in_cell[cell_start[c]:cell_start[c+1]]``, in ascending
    index order (a counting sort), c = (cx · shape_y + cy) · shape_z + cz."""
    n = pos.shape[0]
    low = np.empty(3)
    extent = np.empty(3)
    for c in range(3):
        low[c] = pos[:, c].min()
        extent[c] = pos[:, c].max() - low[c]
    shape = np.empty(3, dtype=np.int64)
    while True:
        for c in range(3):
            shape[c] = int(extent[c] / size) + 1
        if shape[0] * shape[1] * shape[2] <= MAX_GRID_CELLS_PER_VEHICLE * n + 27:
            break
        size *= 1.5
    cell = np.empty((n, 3), dtype=np.int64)
    for i in range(n):
        for c in range(3):
            cell[i, c] = min(int((pos[i, c] - low[c]) / size), shape[c] - 1)
    key = (cell[:, 0] * shape[1] + cell[:, 1]) * shape[2] + cell[:, 2]
    cell_start = np.zeros(shape[0] * shape[1] * shape[2] + 1, dtype=np.int64)
    for i in range(n):
        cell_start[key[i] + 1] += 1
    cell_start = np.cumsum(cell_start)
    fill = cell_start[:-1].copy()
    in_cell = np.empty(n, dtype=np.int64)
    for i in range(n):
        in_cell[fill[key[i]]] = i
        fill[key[i]] += 1
    return cell, low, shape, size, cell_start, in_cell


@njit(cache=True)
def _mate_bounds(
    trig: np.ndarray,
    speed: np.ndarray,
    lim: KernelLimits,
    dt: float,
    horizon_steps: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """Each vehicle's part of the bounds of ``_within_reach`` over ``horizon_steps`` steps:
    its ``speed_bound``, ``velocity_change``, ``mate_reach_own`` and ``mate_reach_other``
    ``[N]``, its velocity ``[N,3]`` (Eq. 5, from cos θ, sin θ, cos ψ, sin ψ in
    ``trig[N, 0:4]``, as the step keeps them: no angle is taken again), and the fleet's
    highest speed bound."""
    n = speed.shape[0]
    bound = np.empty(n)
    change = np.empty(n)
    own = np.empty(n)
    other = np.empty(n)
    vel = np.empty((n, 3))
    fastest = 0.0
    for i in range(n):
        bound[i] = speed_bound(speed[i], lim, dt, horizon_steps)
        change[i] = velocity_change(speed[i], bound[i], lim, dt, horizon_steps)
        own[i] = mate_reach_own(bound[i], lim, dt, horizon_steps)
        other[i] = mate_reach_other(bound[i], lim, dt, horizon_steps)
        vel[i, 0] = speed[i] * trig[i, 0] * trig[i, 2]
        vel[i, 1] = speed[i] * trig[i, 0] * trig[i, 3]
        vel[i, 2] = speed[i] * trig[i, 1]
        fastest = max(fastest, bound[i])
    return bound, change, own, other, vel, fastest


@njit(cache=True, inline="always")
def _within_reach(
    i: int,
    k: int,
    pos: np.ndarray,
    bound: np.ndarray,
    change: np.ndarray,
    own: np.ndarray,
    other: np.ndarray,
    vel: np.ndarray,
    lim: KernelLimits,
    dt: float,
    horizon_steps: int,
) -> bool:
    """Whether teammate k is within vehicle i's ``mate_reach`` and ``miss_reach`` over
    ``horizon_steps`` steps (the per-vehicle parts from ``_mate_bounds``)."""
    dx = pos[i, 0] - pos[k, 0]
    dy = pos[i, 1] - pos[k, 1]
    dz = pos[i, 2] - pos[k, 2]
    d2 = dx * dx + dy * dy + dz * dz
    reach = own[i] + other[k]  # mate_reach
    if d2 > reach * reach:
        return False
    wx = vel[k, 0] - vel[i, 0]
    wy = vel[k, 1] - vel[i, 1]
    wz = vel[k, 2] - vel[i, 2]
    closing = math.sqrt(wx * wx + wy * wy + wz * wz) + change[i] + change[k]
    reach = miss_reach(bound[i], closing, lim, dt, horizon_steps)
    return bool(d2 <= reach * reach)


@njit(cache=True)
def _by_priority(rank: np.ndarray, cell_start: np.ndarray, in_cell: np.ndarray) -> np.ndarray:
    """``in_cell`` with each cell's vehicles in order of priority (ascending rank; by index
    among equals): an insertion sort of each cell."""
    ordered = in_cell.copy()
    for c in range(cell_start.shape[0] - 1):
        for s in range(cell_start[c] + 1, cell_start[c + 1]):
            k = ordered[s]
            b = s
            while b > cell_start[c] and rank[ordered[b - 1]] > rank[k]:
                ordered[b] = ordered[b - 1]
                b -= 1
            ordered[b] = k
    return ordered


@njit(cache=True)
def _mates_grid(
    pos: np.ndarray,
    trig: np.ndarray,
    speed: np.ndarray,
    rank: np.ndarray,
    active: np.ndarray,
    lim: KernelLimits,
    dt: float,
    horizon_steps: int,
    mate_start: np.ndarray,
    mates: np.ndarray,
) -> np.ndarray:
    """The active teammates of higher priority ``_within_reach``, found in a uniform grid
    of cells one largest ``mate_reach`` wide: vehicle i looks at the vehicles of the 27
    cells round its own in order of priority (``_by_priority``) up to its own, never at
    one of lower priority; its list is then sorted by index (insertion)."""
    n = pos.shape[0]
    bound, change, own, other, vel, fastest = _mate_bounds(trig, speed, lim, dt, horizon_steps)
    widest = mate_reach_own(fastest, lim, dt, horizon_steps)
    size = widest + mate_reach_other(fastest, lim, dt, horizon_steps)
    cell, _, shape, _, cell_start, in_cell = _grid(pos, size)
    by_priority = _by_priority(rank, cell_start, in_cell)
    found = np.empty(n, dtype=np.int64)
    count = 0
    for i in range(n):
        mate_start[i] = count
        if not active[i]:
            continue
        m = 0
        for ax in range(max(cell[i, 0] - 1, 0), min(cell[i, 0] + 2, shape[0])):
            for ay in range(max(cell[i, 1] - 1, 0), min(cell[i, 1] + 2, shape[1])):
                for az in range(max(cell[i, 2] - 1, 0), min(cell[i, 2] + 2, shape[2])):
                    c = (ax * shape[1] + ay) * shape[2] + az
                    for s in range(cell_start[c], cell_start[c + 1]):
                        k = by_priority[s]
                        if rank[k] >= rank[i]:  # (i itself, and every one after it)
                            break
                        if active[k] and _within_reach(
                            i, k, pos, bound, change, own, other, vel, lim, dt, horizon_steps
                        ):
                            found[m] = k
                            m += 1
        mates = _grow(mates, count + m)
        for a in range(m):  # insertion sort: ascending index order
            k = found[a]
            b = count + a
            while b > count and mates[b - 1] > k:
                mates[b] = mates[b - 1]
                b -= 1
            mates[b] = k
        count += m
    mate_start[n] = count
    return mates


@njit(cache=True)
def refine_teammates(
    pos: np.ndarray,
    trig: np.ndarray,
    speed: np.ndarray,
    lim: KernelLimits,
    dt: float,
    horizon_steps: int,
    mate_start: np.ndarray,
    mates: np.ndarray,
    near_start: np.ndarray,
    near: np.ndarray,
) -> None:
    """The teammates of the lists ``mates[mate_start[i]:mate_start[i+1]]`` (``nearby_teammates``)
    that are ``_within_reach`` over the next ``horizon_steps`` steps, into ``near`` (room
    for ``mate_start[N]``) in CSR form (``near_start[N+1]``), in the same order
    (``trig`` as for ``nearby_teammates``).

    A list built for a longer horizon that covers these steps (``MATE_REFINE_STEPS``
    divides ``NEIGHBOUR_LIST_STEPS`` in ``rollout``) holds every teammate that can matter
    in them, so the shorter list does too, and a step decides with it exactly as with the
    longer one; it is shorter because the velocities can change less over fewer steps (in
    the formation of 500, 7.5 of 23.7 teammates a vehicle over 5 steps)."""
    bound, change, own, other, vel, _ = _mate_bounds(trig, speed, lim, dt, horizon_steps)
    count = 0
    for i in range(pos.shape[0]):
        near_start[i] = count
        for c in range(mate_start[i], mate_start[i + 1]):
            k = mates[c]
            if _within_reach(i, k, pos, bound, change, own, other, vel, lim, dt, horizon_steps):
                near[count] = k
                count += 1
    near_start[pos.shape[0]] = count


@njit(cache=True)
def mate_search_for(search: int, n_vehicles: int) -> int:
    """``search`` with ``MATES_AUTO`` resolved by the fleet's size."""
    if search != MATES_AUTO:
        return search
    return MATES_GRID if n_vehicles >= GRID_MIN_VEHICLES else MATES_ALL_PAIRS


@njit(cache=True)
def nearby_teammates(
    pos: np.ndarray,
    trig: np.ndarray,
    speed: np.ndarray,
    rank: np.ndarray,
    active: np.ndarray,
    lim: KernelLimits,
    dt: float,
    horizon_steps: int,
    search: int,
    mate_start: np.ndarray,
    mates: np.ndarray,
) -> np.ndarray:
    """The teammates each vehicle must look at for conflicts (Eq. 12–13,
    ``teammate_conflicts``) in the next ``horizon_steps`` steps: active, of higher priority
    (lower rank), and for ``MATES_GRID`` within ``mate_reach`` and ``miss_reach`` (the
    influence radius, and the closest approach at the relative speed it can reach; see
    ``teammate_conflict``) (``MATES_AUTO``: chosen by
    the fleet's size).  ``trig[N, 0:4]`` holds each vehicle's cos θ, sin θ, cos ψ, sin ψ
    (``attitude_trig``).  Fills ``mate_start[N+1]`` and returns the list (``mates``, or a
    larger array when it had no room): vehicle i's mates are
    ``mates[mate_start[i]:mate_start[i+1]]``, in ascending index order."""
    search = mate_search_for(search, pos.shape[0])
    if search == MATES_GRID and pos.shape[0] > 1:
        return _mates_grid(
            pos, trig, speed, rank, active, lim, dt, horizon_steps, mate_start, mates
        )
    return _mates_all_pairs(rank, active, mate_start, mates)

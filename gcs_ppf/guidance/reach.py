"""Whom each vehicle yields to in the run-time assurance, for the whole fleet at once: the
pairs of ``assurance._yields`` found in a uniform grid (the planner's,
``gcs_ppf.planning.ppf.neighbours``), decided in one compiled pass.

Pure, ``@njit`` (numba).  ``assurance`` asked every pair in Python (``overtaking``,
``within_reach``): 10,000 pairs a tick at 100 vehicles, 110 ms of a 250 ms tick.  The
decisions here are the same ones: a pair whose figures come within ``BAND`` (relative) of a
threshold, where this pass's arithmetic could round otherwise than numpy's dot products and
``math.dist``, is handed back undecided (``UNDECIDED``), and ``assurance`` asks its own
predicates for it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# the planner's grid itself (its module is left as it is: its kernels stay in numba's cache)
from gcs_ppf.planning.ppf.neighbours import _grid as uniform_grid
from gcs_ppf.planning.scene import FloatArray, IntArray

YIELDS, UNDECIDED = 1, 2
"""A pair's status in ``yields``' lists: it yields, or too near a threshold to say here."""
BAND = 1e-9
"""Relative nearness to a threshold within which a pair is left to ``assurance``'s own
predicates (their arithmetic and this pass's differ by a few units in the last place)."""


@njit(cache=True)
def _sign(a: float, b: float, c: float) -> int:
    """The sign of a + b + c (three products), 0 when it is within ``BAND`` of their size."""
    s = a + b + c
    if abs(s) <= BAND * (abs(a) + abs(b) + abs(c)):
        return 0
    return 1 if s > 0.0 else -1


@njit(cache=True)
def _pair(
    i: int,
    j: int,
    pos: FloatArray,
    vel: FloatArray,
    speed: FloatArray,
    escape: FloatArray,
    hold_s: float,
    safe_uav: float,
) -> int:
    """Whether vehicle ``i`` yields to ``j`` (``YIELDS``), does not (0), or cannot be told
    here (``UNDECIDED``): ``j`` before it or overtaken by it (``assurance.overtaking``), and
    within reach (``assurance.within_reach``)."""
    gx, gy, gz = pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1], pos[j, 2] - pos[i, 2]
    undecided = False
    if j > i:  # overtaking: j ahead, the same way, the gap closing
        for s in (
            _sign(gx * vel[i, 0], gy * vel[i, 1], gz * vel[i, 2]),
            _sign(vel[i, 0] * vel[j, 0], vel[i, 1] * vel[j, 1], vel[i, 2] * vel[j, 2]),
            _sign(
                gx * (vel[i, 0] - vel[j, 0]),
                gy * (vel[i, 1] - vel[j, 1]),
                gz * (vel[i, 2] - vel[j, 2]),
            ),
        ):
            if s < 0:
                return 0
            if s == 0:
                undecided = True
    horizon = hold_s + max(escape[i], escape[j])
    reach = (speed[i] + speed[j]) * horizon + safe_uav
    gap = math.sqrt(gx * gx + gy * gy + gz * gz)
    if gap > reach * (1.0 + BAND):
        return 0
    if gap >= reach * (1.0 - BAND):
        undecided = True
    return UNDECIDED if undecided else YIELDS


@njit(cache=True)
def yields(
    pos: FloatArray,
    vel: FloatArray,
    speed: FloatArray,
    escape: FloatArray,
    hold_s: float,
    safe_uav: float,
) -> tuple[IntArray, IntArray, IntArray]:
    """Whom each of N vehicles (in priority order: ``pos`` [N,3] m, ``vel`` [N,3] m/s,
    ``speed`` [N] m/s, ``escape`` [N] s, ``vehicle_motion.escape_s``) yields to, holding its
    command ``hold_s`` then escaping, with ``safe_uav`` (m) between them: vehicle i's are
    ``items[start[i]:start[i+1]]`` in ascending order, each with its ``status``
    (``YIELDS`` or ``UNDECIDED``).  Only the vehicles in the 27 cells round a vehicle's own
    are looked at, in a grid of cells as wide as the farthest reach of any two."""
    n = pos.shape[0]
    start = np.zeros(n + 1, dtype=np.int64)
    items = np.empty(max(n * 4, 16), dtype=np.int64)
    status = np.empty(items.shape[0], dtype=np.int64)
    if n == 0:
        return start, items[:0], status[:0]
    widest = 2.0 * speed.max() * (hold_s + escape.max()) + safe_uav
    cell, _, shape, _, cell_start, in_cell = uniform_grid(pos, max(widest * (1.0 + BAND), 1.0))
    found = np.empty(n, dtype=np.int64)
    count = 0
    for i in range(n):
        start[i] = count
        m = 0
        for ax in range(max(cell[i, 0] - 1, 0), min(cell[i, 0] + 2, shape[0])):
            for ay in range(max(cell[i, 1] - 1, 0), min(cell[i, 1] + 2, shape[1])):
                for az in range(max(cell[i, 2] - 1, 0), min(cell[i, 2] + 2, shape[2])):
                    c = (ax * shape[1] + ay) * shape[2] + az
                    for s in range(cell_start[c], cell_start[c + 1]):
                        j = in_cell[s]
                        if j != i:
                            found[m] = j
                            m += 1
        ordered = np.sort(found[:m])
        if count + m > items.shape[0]:
            size = max(2 * items.shape[0], count + m)
            items, status = _grown(items, size), _grown(status, size)
        for a in range(m):
            j = ordered[a]
            verdict = _pair(i, j, pos, vel, speed, escape, hold_s, safe_uav)
            if verdict:
                items[count] = j
                status[count] = verdict
                count += 1
    start[n] = count
    return start, items[:count], status[:count]


@njit(cache=True)
def _grown(a: IntArray, size: int) -> IntArray:
    out = np.empty(size, dtype=np.int64)
    out[: a.shape[0]] = a
    return out

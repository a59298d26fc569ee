"""Where a vehicle holds once the service stops planning for it (completion, abort, failure):
a loiter circle, at a radius it can fly, that cuts no obstacle's keep-out and is reached
without crossing one.

Pure. Flown closed loop, vehicles left circling a point straight ahead of them flew through
an obstacle after the run had ended (issue 10: Table 3 at 10×, 4 of 6 runs). Candidates are
tried nearest the vehicle's heading first, then further out; the first circle whose ring (at the
radius asked and at the wider one ArduPlane flies, radius / η) and whose approach (the
straight line from the vehicle to the ring) keep the safe distance wins.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gcs_ppf.guidance.airframe import TURN_EFFICIENCY
from gcs_ppf.planning.scene import FloatArray, Obstacles

#: Bearings tried, off the vehicle's heading (radians), nearest first.
BEARINGS = tuple(math.radians(b) for b in (0, 30, -30, 60, -60, 90, -90, 120, -120, 150, -150, 180))
#: Distances of the circle's centre tried, in loiter radii beyond the first ``ahead_m``.
REACH_STEPS = (0.0, 2.0, 4.0, 8.0)
#: Points sampled along the approach.
APPROACH_SAMPLES = 24


@dataclass(frozen=True, slots=True)
class Hold:
    """A loiter circle: centre (ICS x, y), height, radius; and its smallest clearance to an
    obstacle's surface along the ring and the approach (inf without obstacles)."""

    x_m: float
    y_m: float
    z_m: float
    radius_m: float
    clearance_m: float


def ring_clearance(x: float, y: float, z: float, r: float, obstacles: Obstacles) -> float:
    """Smallest distance from the horizontal circle (centre x, y at height z, radius r) to
    any obstacle's surface."""
    if obstacles.radius.shape[0] == 0:
        return math.inf
    c = obstacles.center
    horizontal = np.hypot(c[:, 0] - x, c[:, 1] - y)
    gap = np.hypot(horizontal - r, c[:, 2] - z) - obstacles.radius
    return float(gap.min())


def path_clearance(a: FloatArray, b: FloatArray, obstacles: Obstacles) -> float:
    """Smallest distance from the segment a → b to any obstacle's surface."""
    if obstacles.radius.shape[0] == 0:
        return math.inf
    ab = b - a
    rel = obstacles.center - a
    s = np.clip((rel @ ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0)
    closest = a + s[:, None] * ab
    return float((np.linalg.norm(obstacles.center - closest, axis=1) - obstacles.radius).min())


def holding_circle(
    pos_m: FloatArray,
    yaw_rad: float,
    z_m: float,
    radius_m: float,
    ahead_m: float,
    obstacles: Obstacles,
    keep_out_m: float,
) -> Hold:
    """The loiter circle for a vehicle at ``pos_m`` heading ``yaw_rad``: centred ``ahead_m``
    (or further) off its nose, as near the heading as keeps ``keep_out_m`` from every
    obstacle along the ring and the way there; if none does, the one with most clearance."""
    best: Hold | None = None
    for step in REACH_STEPS:
        d = ahead_m + step * radius_m
        for bearing in BEARINGS:
            heading = yaw_rad + bearing
            x = float(pos_m[0]) + d * math.cos(heading)
            y = float(pos_m[1]) + d * math.sin(heading)
            entry = np.array(
                [x - radius_m * math.cos(heading), y - radius_m * math.sin(heading), z_m]
            )
            clear = min(
                ring_clearance(x, y, z_m, radius_m, obstacles),
                ring_clearance(x, y, z_m, radius_m / TURN_EFFICIENCY, obstacles),  # flown wider
                path_clearance(np.asarray(pos_m, dtype=float), entry, obstacles),
            )
            hold = Hold(x, y, z_m, radius_m, clear)
            if clear >= keep_out_m:
                return hold
            if best is None or clear > best.clearance_m:
                best = hold
    assert best is not None
    return best

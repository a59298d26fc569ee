"""The leader's route: its legs, and when the leader has flown one.

A mission's route (``Mission.route``) is the waypoints the leader flies through before its
target.  Leg k ends at waypoint k (the last leg at the target).  A leg is flown when the
leader passes within the waypoint's acceptance radius or, as ArduPlane counts a waypoint
passed wide, crosses its finish line: the vertical plane through the waypoint square to
the leg.  The target has no finish line: it is reached within the target accuracy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gcs_ppf.mission import Mission
from gcs_ppf.planning.scene import FloatArray


@dataclass(frozen=True)
class Leg:
    """One leg of the route: from ``start_m`` to ``end_m`` (ICS), reached within
    ``radius_m`` or across the plane through ``end_m`` square to ``finish_normal``
    (horizontal unit vector along the leg; zeros for the target's leg)."""

    index: int
    start_m: FloatArray
    end_m: FloatArray
    radius_m: float
    finish_normal: FloatArray

    @property
    def final(self) -> bool:
        return not bool(np.any(self.finish_normal))


def legs(mission: Mission) -> list[Leg]:
    """The route's legs in order, from the leader's start; one leg without a route."""
    points = [np.array(w.position, dtype=float) for w in mission.route]
    radii = [w.acceptance_radius for w in mission.route]
    points.append(np.array(mission.target, dtype=float))
    radii.append(mission.limits.target_accuracy)
    out: list[Leg] = []
    start = np.array(mission.leader.position, dtype=float)
    for k, (end, radius) in enumerate(zip(points, radii, strict=True)):
        final = k == len(points) - 1
        out.append(Leg(k, start, end, radius, np.zeros(3) if final else _along(start, end)))
        start = end
    return out


def _along(start: FloatArray, end: FloatArray) -> FloatArray:
    """The horizontal unit vector from ``start`` to ``end`` (zeros if one is above the other:
    such a leg ends within its radius only)."""
    d = np.array([end[0] - start[0], end[1] - start[1], 0.0])
    n = math.hypot(d[0], d[1])
    return d / n if n > 0.0 else np.zeros(3)


def leg_flown(leg: Leg, previous_m: FloatArray | None, position_m: FloatArray) -> bool:
    """Whether the leader, from ``previous_m`` (None: not known) to ``position_m``, came
    within the leg's radius of its end or crossed its finish line.  The whole segment
    counts: telemetry at 10 Hz can step over a 10 m sphere."""
    end = leg.end_m
    if previous_m is None:
        return bool(np.linalg.norm(position_m - end) <= leg.radius_m)
    seg = position_m - previous_m
    length2 = float(seg @ seg)
    s = 0.0 if length2 == 0.0 else min(max(float((end - previous_m) @ seg) / length2, 0.0), 1.0)
    if np.linalg.norm(previous_m + s * seg - end) <= leg.radius_m:
        return True
    if leg.final:
        return False
    n = leg.finish_normal
    return bool(float((previous_m - end) @ n) < 0.0 <= float((position_m - end) @ n))

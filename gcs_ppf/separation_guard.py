"""A vertical resolution of predicted vehicle–vehicle conflicts, outside the planner.

Flown closed loop, an aircraft lags its PPF plan, and the plan's teammate rule (a closest
point of approach within a quarter turn) can be cut: the integration tests measured
wingmen 40–46 m from the leader while their plans kept some 127 m.  Like TCAS, this looks
only at where the vehicles are and how they fly *now* (telemetry, straight-line motion)
and, for a pair predicted to pass closer than ``distance_m`` within ``horizon_s``, gives
the vehicle of lower priority a vertical resolution: its guided altitude moves
``resolution_m`` away from the other's (up if it is higher; down if lower, but no lower
than the ground's keep-out, and never towards the other).  Horizontal guidance stays
the plan's, so obstacles are still avoided as planned.  Pure: arrays in, arrays out.
"""

from __future__ import annotations

import numpy as np

from gcs_ppf.scene import FloatArray, Scene


def velocities(scene: Scene) -> FloatArray:
    """ICS velocities [N,3] of the fleet (Eq. 5)."""
    f = scene.fleet
    cp = np.cos(f.pitch)
    out: FloatArray = f.speed[:, None] * np.stack(
        [cp * np.cos(f.yaw), cp * np.sin(f.yaw), np.sin(f.pitch)], axis=1
    )
    return out


def closest_approach(d: FloatArray, w: FloatArray, horizon_s: float) -> float:
    """Smallest distance within ``horizon_s`` of two points at offset ``d`` moving apart at
    relative velocity ``w`` (straight lines)."""
    w2 = float(w @ w)
    t = 0.0 if w2 == 0.0 else min(max(-float(d @ w) / w2, 0.0), horizon_s)
    return float(np.linalg.norm(d + w * t))


def resolve(
    scene: Scene,
    guided: FloatArray,
    *,
    distance_m: float,
    horizon_s: float,
    resolution_m: float,
    release_m: float = 50.0,
    previous: list[bool] | None = None,
) -> tuple[FloatArray, list[bool]]:
    """The guided points [N,3] with vertical resolutions applied, and which vehicles got one.

    A vehicle resolves against every active vehicle of higher priority (lower rank), as in
    the planner, and against any it is overtaking (ahead of it and slower): as in the rules
    of the air, the overtaking aircraft gives way too, for the one ahead cannot see it come.
    A resolution in force (``previous``, the last tick's answer) holds until the predicted
    miss exceeds ``distance_m + release_m``, so that it does not flicker on and off as the
    vehicle climbs away and the plan brings it back.
    """
    fleet = scene.fleet
    lim = scene.limits
    vel = velocities(scene)
    out = guided.copy()
    resolving = [False] * fleet.pos.shape[0]
    floor = lim.ground + lim.safe_distance_obstacle
    for i in range(fleet.pos.shape[0]):
        if not fleet.active[i]:
            continue
        for k in range(fleet.pos.shape[0]):
            if k == i or not fleet.active[k]:
                continue
            d = fleet.pos[i] - fleet.pos[k]
            overtaking = float(d @ vel[i]) < 0.0 and fleet.speed[i] > fleet.speed[k]
            if fleet.rank[k] >= fleet.rank[i] and not overtaking:
                continue
            held = previous is not None and i < len(previous) and previous[i]
            threshold = distance_m + (release_m if held else 0.0)
            if closest_approach(d, vel[i] - vel[k], horizon_s) >= threshold:
                continue
            z = float(fleet.pos[i, 2])
            if z >= fleet.pos[k, 2]:
                out[i, 2] = z + resolution_m
            else:  # down, but not into the ground's keep-out (and never towards the other)
                out[i, 2] = min(z, max(z - resolution_m, floor))
            resolving[i] = True
            break
    return out, resolving

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

The distances, the horizon and the resolutions may be per vehicle; the service sizes
them from each airframe (``gcs_ppf.guidance.airframe.guard_tuning``): an ArduPlane climbs and sinks
no faster than TECS_CLMB_MAX / TECS_SINK_MAX (5 m/s by default), so it is asked for only
what it can climb or sink within the horizon, and the margins are what it flies during its
response lag.  The fixed figures (150 m, 4 s, 50 m) were tuned at the paper's 100–300 m/s.
"""

from __future__ import annotations

import numpy as np

from gcs_ppf.planning.scene import FloatArray, Scene

PerVehicle = float | FloatArray
"""A figure for every vehicle, or one [N] per vehicle in scene order."""


def velocities(scene: Scene) -> FloatArray:
    """ICS velocities [N,3] of the fleet (Eq. 5)."""
    f = scene.fleet
    cp = np.cos(f.pitch)
    out: FloatArray = f.speed[:, None] * np.stack(
        [cp * np.cos(f.yaw), cp * np.sin(f.yaw), np.sin(f.pitch)], axis=1
    )
    return out


def closest_approach(d: FloatArray, w: FloatArray, horizon_s: float) -> FloatArray:
    """Smallest distance within ``horizon_s`` of points at offsets ``d`` [..., 3] moving
    at relative velocities ``w`` [..., 3] (straight lines); shape [...]."""
    w2 = (w**2).sum(-1)
    t = np.clip(-(d * w).sum(-1) / np.where(w2 > 0.0, w2, 1.0), 0.0, horizon_s)
    out: FloatArray = np.linalg.norm(d + w * np.where(w2 > 0.0, t, 0.0)[..., None], axis=-1)
    return out


def resolve(
    scene: Scene,
    guided: FloatArray,
    *,
    distance_m: PerVehicle,
    horizon_s: float,
    resolution_m: PerVehicle,
    release_m: PerVehicle = 50.0,
    previous: list[bool] | None = None,
    resolution_down_m: PerVehicle | None = None,
    in_formation: list[bool] | None = None,
) -> tuple[FloatArray, list[bool]]:
    """The guided points [N,3] with vertical resolutions applied, and which vehicles got one.

    A vehicle resolves against every active vehicle of higher priority (lower rank), as in
    the planner, and against any it is overtaking (ahead of it and slower): as in the rules
    of the air, the overtaking aircraft gives way too, for the one ahead cannot see it come.
    A resolution in force (``previous``, the last tick's answer) holds until the predicted
    miss exceeds ``distance_m + release_m``, so that it does not flicker on and off as the
    vehicle climbs away and the plan brings it back.  ``distance_m`` and ``release_m``
    are those of the vehicle that gives way; it moves ``resolution_m`` up, or
    ``resolution_down_m`` (default: the same) down.  Two vehicles both ``in_formation``
    (the leader, and wingmen within ``formation_tolerance_m`` of their slots) are left to
    the planner, as TCAS is inhibited in formation flight: their slots keep them apart, and
    straight-line predictions of wingmen turning into their slots conflicted falsely
    (flown on Table 2's level scene: 150 m resolutions broke the formation, worst wingman
    15.6–16.9 m at best in 3 of 5 runs against 5.1–7.3 m in the others).
    """
    fleet = scene.fleet
    lim = scene.limits
    n = fleet.pos.shape[0]
    vel = velocities(scene)
    d = fleet.pos[:, None] - fleet.pos[None]  # [i, k]: i's offset from k
    overtaking = ((d * vel[:, None]).sum(-1) < 0.0) & (fleet.speed[:, None] > fleet.speed[None])
    gives_way = (fleet.rank[None] < fleet.rank[:, None]) | overtaking
    pairs = gives_way & fleet.active[:, None] & fleet.active[None] & ~np.eye(n, dtype=bool)
    if in_formation is not None:
        flying_formation = np.array(in_formation[:n], dtype=bool)
        pairs &= ~(flying_formation[:, None] & flying_formation[None])
    i_of, k_of = np.nonzero(pairs)  # the closest approach of these pairs only
    miss = np.full((n, n), np.inf)
    miss[i_of, k_of] = closest_approach(d[i_of, k_of], vel[i_of] - vel[k_of], horizon_s)
    held = np.zeros(n, dtype=bool)
    if previous is not None:
        held[: min(n, len(previous))] = previous[:n]
    distance = np.broadcast_to(np.asarray(distance_m, dtype=float), (n,))
    release = np.broadcast_to(np.asarray(release_m, dtype=float), (n,))
    up = np.broadcast_to(np.asarray(resolution_m, dtype=float), (n,))
    down = (
        up
        if resolution_down_m is None
        else np.broadcast_to(np.asarray(resolution_down_m, dtype=float), (n,))
    )
    conflict = pairs & (miss < (distance + np.where(held, release, 0.0))[:, None])
    out = guided.copy()
    floor = lim.ground + lim.safe_distance_obstacle
    for i in np.flatnonzero(conflict.any(axis=1)):
        k = int(np.argmax(conflict[i]))  # the first conflicting vehicle
        z = float(fleet.pos[i, 2])
        if z >= fleet.pos[k, 2]:
            out[i, 2] = z + up[i]
        else:  # down, but not into the ground's keep-out (and never towards the other)
            out[i, 2] = min(z, max(z - down[i], floor))
    return out, [bool(c) for c in conflict.any(axis=1)]


def formation_tolerance_m(slots: FloatArray, safe_distance_m: float) -> float:
    """How far from their slots two wingmen (or a wingman and the leader, at the origin of
    the slots) can be and still be at least ``safe_distance_m`` apart: half of what the
    closest pair of slots has beyond the safe distance (0 if none)."""
    points = np.vstack([np.zeros((1, 3)), np.asarray(slots, dtype=float).reshape(-1, 3)])
    gaps = np.linalg.norm(points[:, None] - points[None], axis=-1)
    gaps[np.arange(len(points)), np.arange(len(points))] = np.inf
    return max(0.0, (float(gaps.min()) - safe_distance_m) / 2.0)

"""Figures of a planned flight (CONVENTIONS §4), computed from the trajectory alone.

Nothing here trusts the planner: local target points are recomputed from the leader's
recorded attitude (Eq. 6, with ``gcs_ppf.frames``), obstacle positions from their initial
state and velocity, rates from differences of consecutive records.  This is the
independent check of the planner's safety and kinematic claims.

Smoothness (PPF against APF) is measured by

* ``heading_change_deg_per_km``: the total absolute change of the flight direction, summed
  over every step and every vehicle, per kilometre flown by the formation.  A path that
  turns only where it must scores low; oscillation about a moving target point, U-turns
  and instantaneous heading jumps at the start score high.  It does not depend on Δt for a
  path that is smooth at the step scale.
* ``max_step_turn_deg``: the largest change of direction in one step (a fixed wing can
  turn at most ω·Δt).
* ``wingman_offset_rms_m``: root mean square of the wingmen's distance from their local
  target points over the second half of the flight, when a formation should be held.
* ``wingman_hold_heading_change_deg_per_km``: the heading change per km of the wingmen
  over the same half: how much they weave about their local target points (Fig. 6).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gcs_ppf.planning.planner import Trajectory
from gcs_ppf.planning.scene import FloatArray, Obstacles
from gcs_ppf.planning.zones import Zones, no_zones, zone_clearances

CONTACT_TOLERANCE_M = 1e-9


@dataclass(frozen=True)
class FlightContext:
    """What the metrics need besides the trajectory: the mission's geometry and limits."""

    target: FloatArray
    slot: FloatArray  # [N,3], vehicle order as in the trajectory (leader first)
    obstacles: Obstacles  # at t = 0
    target_accuracy: float
    collision_radius: float
    ground: float | None = None  # ICS z of the ground, None: free space
    zones: Zones = field(default_factory=no_zones)  # cylinders and polygons: obstacles too


def direction_vectors(pitch: FloatArray, yaw: FloatArray) -> FloatArray:
    """Unit flight directions [..., 3] for pitch and yaw arrays (Eq. 5 divided by v)."""
    cp = np.cos(pitch)
    return np.stack([cp * np.cos(yaw), cp * np.sin(yaw), np.sin(pitch)], axis=-1)


def local_target_points(trajectory: Trajectory, slot: FloatArray) -> FloatArray:
    """G_i(t) [K,N,3] of every vehicle (Eq. 6); the leader's row is its own position."""
    th = trajectory.pitch[:, 0]
    ps = trajectory.yaw[:, 0]
    ct, st, cy, sy = np.cos(th), np.sin(th), np.cos(ps), np.sin(ps)
    sx, sy_, sz = slot[:, 0][None], slot[:, 1][None], slot[:, 2][None]
    px = ct[:, None] * sx - st[:, None] * sz  # corrected B_vf(θ) (erratum 1)
    pz = st[:, None] * sx + ct[:, None] * sz
    gx = cy[:, None] * px - sy[:, None] * sy_  # A_vf(ψ) (Eq. 7)
    gy = sy[:, None] * px + cy[:, None] * sy_
    return np.stack([gx, gy, pz], axis=-1) + trajectory.pos[:, :1, :]


def _contacts(distance: FloatArray, threshold: float) -> FloatArray:
    """Number of times each column enters ``distance < threshold`` (a contact)."""
    inside = distance < threshold - CONTACT_TOLERANCE_M
    starts = inside[:1].astype(int) + np.logical_and(inside[1:], ~inside[:-1]).sum(axis=0)
    return np.asarray(starts, dtype=float).reshape(-1)


def _none_if_nan(x: float) -> float | None:
    return None if math.isnan(x) else float(x)


@dataclass(frozen=True)
class Safety:
    """Separation and clearance of each vehicle over the whole flight, [N] each: the
    nearest teammate (centre to centre), obstacle surface and ground (inf: none), and the
    contacts counted (a contact is entering the collision distance)."""

    separation: FloatArray
    clearance: FloatArray
    nearest: list[str | None]
    """Which keep-out each vehicle's ``clearance`` is to: ``"obstacles[j]"`` or
    ``"zones[k]"`` (the mission document's lists, 0-based); None: none."""
    ground_clearance: FloatArray
    pair_contacts: FloatArray  # [N*N], each pair twice
    vehicle_contacts: FloatArray  # with teammates
    obstacle_contacts: FloatArray  # with obstacles and the ground


def safety(trajectory: Trajectory, context: FlightContext) -> Safety:
    """Separation between vehicles and clearance to obstacle surfaces and the ground."""
    tr = trajectory
    k, n = tr.t.shape[0], tr.ids.shape[0]
    gaps = np.linalg.norm(tr.pos[:, :, None, :] - tr.pos[:, None, :, :], axis=-1)
    gaps[:, np.arange(n), np.arange(n)] = np.inf
    pair_contacts = _contacts(gaps.reshape(k, n * n), 2 * context.collision_radius)
    vehicle_contacts = pair_contacts.reshape(n, n).sum(axis=1) / 1.0
    obs = context.obstacles
    m = obs.radius.shape[0]
    if m:
        centres = obs.center[None] + tr.t[:, None, None] * obs.velocity[None]  # [K,M,3]
        clear = (
            np.linalg.norm(tr.pos[:, :, None, :] - centres[:, None], axis=-1)
            - obs.radius[None, None]
        )  # [K,N,M]
        obstacle_contacts = _contacts(clear.reshape(k, n * m), context.collision_radius)
        obstacle_contacts_per_vehicle = obstacle_contacts.reshape(n, m).sum(axis=1)
        per_obstacle = clear.min(axis=0)  # [N,M]
        clearance = per_obstacle.min(axis=1)
        nearest: list[str | None] = [f"obstacles[{j}]" for j in per_obstacle.argmin(axis=1)]
    else:
        obstacle_contacts_per_vehicle = np.zeros(n)
        clearance = np.full(n, np.inf)
        nearest = [None] * n
    z = len(context.zones)
    if z:  # the distance to each zone's nearest surface point, free side positive
        clear_z = zone_clearances(tr.pos.reshape(k * n, 3), context.zones).reshape(k, n * z)
        obstacle_contacts_per_vehicle = obstacle_contacts_per_vehicle + _contacts(
            clear_z, context.collision_radius
        ).reshape(n, z).sum(axis=1)
        per_zone = clear_z.reshape(k, n, z).min(axis=0)  # [N,Z]
        nearer = per_zone.min(axis=1) < clearance
        nearest = [
            f"zones[{int(per_zone[i].argmin())}]" if nearer[i] else nearest[i] for i in range(n)
        ]
        clearance = np.minimum(clearance, per_zone.min(axis=1))
    separation = gaps.min(axis=(0, 2)) if n > 1 else np.full(n, np.inf)
    if context.ground is not None:  # the ground is an obstacle too
        height = tr.pos[:, :, 2] - context.ground  # [K,N]
        obstacle_contacts_per_vehicle = obstacle_contacts_per_vehicle + _contacts(
            height, context.collision_radius
        )
        ground_clearance = height.min(axis=0)
    else:
        ground_clearance = np.full(n, np.inf)
    return Safety(
        separation=separation,
        clearance=clearance,
        nearest=nearest,
        ground_clearance=ground_clearance,
        pair_contacts=pair_contacts,
        vehicle_contacts=vehicle_contacts,
        obstacle_contacts=obstacle_contacts_per_vehicle,
    )


def _extreme(values: FloatArray, fn: Any, n: int, empty: float = 0.0) -> FloatArray:
    """``fn`` over the records of each vehicle; ``empty`` for every vehicle of no records."""
    out: FloatArray = fn(values, axis=0) if values.shape[0] else np.full(n, empty)
    return out


def kinematics(trajectory: Trajectory) -> dict[str, FloatArray]:
    """Each vehicle's extreme pitch and yaw rates, speeds, acceleration and deceleration [N],
    from differences of consecutive records."""
    tr = trajectory
    n = tr.ids.shape[0]
    dt = np.diff(tr.t)
    dt_safe = np.where(dt > 0, dt, np.inf)[:, None]
    pitch_rate = np.abs(np.diff(tr.pitch, axis=0)) / dt_safe
    yaw_step = np.angle(np.exp(1j * np.diff(tr.yaw, axis=0)))
    yaw_rate = np.abs(yaw_step) / dt_safe
    accel = np.diff(tr.speed, axis=0) / dt_safe
    return {
        "max_pitch_rate_rad_s": _extreme(pitch_rate, np.max, n),
        "max_yaw_rate_rad_s": _extreme(yaw_rate, np.max, n),
        "min_speed_m_s": tr.speed.min(axis=0),
        "max_speed_m_s": tr.speed.max(axis=0),
        "max_accel_m_s2": np.maximum(_extreme(accel, np.max, n), 0.0),
        "max_decel_m_s2": np.maximum(-_extreme(accel, np.min, n), 0.0),
    }


def step_turns_deg(trajectory: Trajectory) -> FloatArray:
    """[K-1,N] the change of flight direction over each step, degrees."""
    u = direction_vectors(trajectory.pitch, trajectory.yaw)
    turn: FloatArray = np.degrees(np.arccos(np.clip((u[1:] * u[:-1]).sum(axis=-1), -1.0, 1.0)))
    return turn


def path_km(trajectory: Trajectory) -> FloatArray:
    """[N] the length of each vehicle's path, km."""
    km: FloatArray = np.linalg.norm(np.diff(trajectory.pos, axis=0), axis=-1).sum(axis=0) / 1000.0
    return km


def second_half(t: FloatArray) -> NDArray[np.bool_]:
    """[K] the records of the second half of the flight, when a formation should be held."""
    half: NDArray[np.bool_] = t >= t[-1] / 2
    return half


def smoothness(
    trajectory: Trajectory, turn: FloatArray, km: FloatArray, offsets: FloatArray
) -> dict[str, float | None]:
    """The fleet's smoothness figures (see the module's docstring); ``turn`` [K-1,N] from
    ``step_turns_deg``, ``km`` [N] from ``path_km``, ``offsets`` [K,N] from the local
    target points."""
    tr = trajectory
    n = tr.ids.shape[0]
    half = second_half(tr.t)
    hold = half[1:] & half[:-1]  # steps within the second half
    hold_turn = turn[hold][:, 1:].sum()
    hold_km = np.linalg.norm(np.diff(tr.pos, axis=0)[hold][:, 1:], axis=-1).sum() / 1000.0
    return {
        "heading_change_deg_per_km": float(turn.sum() / max(km.sum(), 1e-9)),
        "max_step_turn_deg": float(turn.max()) if turn.size else 0.0,
        "wingman_offset_rms_m": _none_if_nan(
            float(np.sqrt((offsets[half][:, 1:] ** 2).mean())) if n > 1 else math.nan
        ),
        "wingman_hold_heading_change_deg_per_km": _none_if_nan(
            float(hold_turn / hold_km) if n > 1 and hold_km > 0 else math.nan
        ),
    }


def per_vehicle_rows(
    trajectory: Trajectory,
    per: dict[str, FloatArray],
    in_place: NDArray[np.bool_],
    nearest: list[str | None],
) -> dict[str, dict[str, Any]]:
    """Each vehicle's figures by its id: its role, ``per``'s values (None for infinite,
    collisions as an int; no local target offset for the leader), for a wingman the first
    time it was in place (``in_place`` [K,N]), and its nearest keep-out (``nearest``,
    ``Safety.nearest``)."""
    tr = trajectory
    rows: dict[str, dict[str, Any]] = {}
    for i, vid in enumerate(tr.ids.tolist()):
        row: dict[str, Any] = {"role": "leader" if i == 0 else "wingman"}
        for key, values in per.items():
            if i == 0 and key == "local_target_offset_rms_m":
                continue
            v = float(values[i])
            row[key] = int(v) if key == "collisions" else (None if math.isinf(v) else v)
        if i > 0:
            first = np.argmax(in_place[:, i])
            row["formation_time_s"] = float(tr.t[first]) if in_place[:, i].any() else None
        row["nearest_keep_out"] = nearest[i]
        rows[str(vid)] = row
    return rows


def formation_time(t: FloatArray, in_place: NDArray[np.bool_]) -> float | None:
    """The first time every wingman is within the target accuracy of its local target
    point (``in_place`` [K,N]); a leader alone is in formation from the start."""
    k, n = in_place.shape
    all_in_place = in_place[:, 1:].all(axis=1) if n > 1 else np.ones(k, dtype=bool)
    return float(t[np.argmax(all_in_place)]) if all_in_place.any() else None


def formation_share(t: FloatArray, in_place: NDArray[np.bool_]) -> float | None:
    """The share of the flight after the formation first formed (``formation_time``) with
    every wingman within the target accuracy of its local target point, each record
    counting for the time to the next; None if it never formed."""
    k, n = in_place.shape
    together = np.asarray(in_place[:, 1:].all(axis=1) if n > 1 else np.ones(k), dtype=bool)
    if not together.any() or k < 2:
        return None
    first = int(np.argmax(together))
    dt = np.diff(t)[first:]
    if dt.sum() <= 0.0:
        return 1.0
    return float((dt * together[first:-1]).sum() / dt.sum())


def compute_metrics(
    trajectory: Trajectory,
    context: FlightContext,
    *,
    planning_wall_time_s: float | None = None,
) -> dict[str, Any]:
    """CONVENTIONS §4 metrics plus smoothness figures, fleet-wide and per vehicle."""
    tr = trajectory
    t = tr.t
    n = tr.ids.shape[0]
    leader_gap = float(np.linalg.norm(tr.pos[-1, 0] - context.target))
    reached = leader_gap <= context.target_accuracy + 1e-6
    offsets = np.linalg.norm(local_target_points(tr, context.slot) - tr.pos, axis=-1)
    in_place = offsets <= context.target_accuracy + 1e-9
    safe = safety(tr, context)
    turn = step_turns_deg(tr)
    km = path_km(tr)
    per = {
        **kinematics(tr),
        "min_separation_m": safe.separation,
        "min_obstacle_clearance_m": safe.clearance,
        "min_ground_clearance_m": safe.ground_clearance,
        "collisions": safe.vehicle_contacts + safe.obstacle_contacts,
        "path_length_m": km * 1000.0,
        "heading_change_deg_per_km": turn.sum(axis=0) / np.maximum(km, 1e-9),
        "max_step_turn_deg": _extreme(turn, np.max, n),
        "local_target_offset_rms_m": np.sqrt((offsets[second_half(t)] ** 2).mean(axis=0)),
    }
    flight = float(t[-1] - t[0])
    wall = planning_wall_time_s
    has_obstacles = context.obstacles.radius.shape[0] > 0 or len(context.zones) > 0
    return {
        "reached": bool(reached),
        "flight_time_s": float(t[-1]) if reached else None,
        "formation_time_s": formation_time(t, in_place),
        "formation_share_after_forming": formation_share(t, in_place),
        "min_separation_m": float(safe.separation.min()) if n > 1 else None,
        "min_obstacle_clearance_m": float(safe.clearance.min()) if has_obstacles else None,
        "min_ground_clearance_m": (
            float(safe.ground_clearance.min()) if context.ground is not None else None
        ),
        "collisions": int(safe.pair_contacts.sum() / 2 + safe.obstacle_contacts.sum()),
        "max_pitch_rate_rad_s": float(per["max_pitch_rate_rad_s"].max()),
        "max_yaw_rate_rad_s": float(per["max_yaw_rate_rad_s"].max()),
        "min_speed_m_s": float(per["min_speed_m_s"].min()),
        "max_speed_m_s": float(per["max_speed_m_s"].max()),
        "max_accel_m_s2": float(per["max_accel_m_s2"].max()),
        "max_decel_m_s2": float(per["max_decel_m_s2"].max()),
        "planning_wall_time_s": wall,
        "real_time_factor": (flight / wall) if wall else None,
        "simulated_time_s": flight,
        "leader_distance_to_target_m": leader_gap,
        "smoothness": smoothness(tr, turn, km, offsets),
        "per_vehicle": per_vehicle_rows(tr, per, in_place, safe.nearest),
    }

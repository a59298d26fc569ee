"""The classical artificial-potential-field (APF) formation planner: the paper's baseline.

This is the method the paper compares PPF against (its Ref. 23, Chen et al.): every
vehicle moves along the gradient of an attractive potential towards its goal plus the
repulsive potentials of obstacles and higher-priority teammates (Khatib's form, acting
within an influence distance of the surface).  Its heading follows the field *at once*:
there is no turn-rate limit, no initial-heading constraint and no local-minimum rule.
Speeds stay within [v_min, v_max] and the acceleration limits, so that the two methods
differ where the paper says they differ.

* the leader flies at its initial speed towards the target;
* a wingman is attracted to its local target point G_i (Eq. 6), at the leader's speed
  plus a speed proportional to its distance from G_i (``SPEED_GAIN``), so that it catches
  up and then follows.

Same array layout and signature as ``gcs_ppf.planning.ppf.kernel.fleet_step``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gcs_ppf.planning.ppf.kernel import S1_FOLLOW, KernelLimits, influence_radius, move, slot_to_ics
from gcs_ppf.planning.ppf.zone_repulsion import surface_influence_radius
from gcs_ppf.planning.zones import INCLUSION, zone_distance, zone_lower_bound

SPEED_GAIN = 1.0  # 1/s: wingman speed = leader speed + gain × distance to G_i


@njit(cache=True)
def khatib_repulsion(clearance: float, safe: float, reach: float) -> float:
    """Magnitude of Khatib's repulsive gradient η (1/ρ − 1/ρ₀)/ρ² at surface distance ρ,
    zero beyond ρ₀ = ``reach``; η makes it equal the unit attraction at ρ = ``safe``."""
    if clearance >= reach:
        return 0.0
    rho = max(clearance, 1e-3)
    eta = safe * safe / (1.0 / safe - 1.0 / reach)
    return eta * (1.0 / rho - 1.0 / reach) / (rho * rho)


@njit(cache=True, inline="always")
def apf_targets(
    pos: np.ndarray,
    pitch: np.ndarray,
    yaw: np.ndarray,
    slot: np.ndarray,
    direction: np.ndarray,
    local_target: np.ndarray,
) -> None:
    """The wingmen's local target points G_i (Eq. 6–8) and every flight direction (Eq. 5)."""
    lcp, lsp = math.cos(pitch[0]), math.sin(pitch[0])
    lcy, lsy = math.cos(yaw[0]), math.sin(yaw[0])
    for i in range(pos.shape[0]):
        gx, gy, gz = slot_to_ics(slot[i, 0], slot[i, 1], slot[i, 2], lcp, lsp, lcy, lsy)
        local_target[i, 0] = pos[0, 0] + gx
        local_target[i, 1] = pos[0, 1] + gy
        local_target[i, 2] = pos[0, 2] + gz
        cp = math.cos(pitch[i])
        direction[i, 0] = cp * math.cos(yaw[i])
        direction[i, 1] = cp * math.sin(yaw[i])
        direction[i, 2] = math.sin(pitch[i])


@njit(cache=True, inline="always")
def apf_repulsion(
    i: int,
    fx: float,
    fy: float,
    fz: float,
    pos: np.ndarray,
    speed: np.ndarray,
    rank: np.ndarray,
    active: np.ndarray,
    obs_center: np.ndarray,
    obs_radius: np.ndarray,
    lim: KernelLimits,
) -> tuple[float, float, float, bool]:
    """The field (fx, fy, fz) on vehicle i with Khatib's repulsive gradients added, from the
    obstacles and from its active teammates of higher priority (lower rank); returns (the
    field, whether anything repels)."""
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
    vi = speed[i]
    repelled = False
    for j in range(obs_center.shape[0]):
        dx = px - obs_center[j, 0]
        dy = py - obs_center[j, 1]
        dz = pz - obs_center[j, 2]
        d = math.sqrt(dx * dx + dy * dy + dz * dz)
        reach = (
            influence_radius(vi, omega, obs_radius[j] + lim.safe_distance_obstacle) - obs_radius[j]
        )
        mag = khatib_repulsion(d - obs_radius[j], lim.safe_distance_obstacle, reach)
        if mag > 0.0 and d > 0.0:
            repelled = True
            fx += mag * dx / d
            fy += mag * dy / d
            fz += mag * dz / d
    for k in range(pos.shape[0]):
        if k == i or not active[k] or rank[k] >= rank[i]:
            continue
        dx = px - pos[k, 0]
        dy = py - pos[k, 1]
        dz = pz - pos[k, 2]
        d = math.sqrt(dx * dx + dy * dy + dz * dz)
        reach = influence_radius(vi, omega, lim.safe_distance_uav)
        mag = khatib_repulsion(d, lim.safe_distance_uav, reach)
        if mag > 0.0 and d > 0.0:
            repelled = True
            fx += mag * dx / d
            fy += mag * dy / d
            fz += mag * dz / d
    return fx, fy, fz, repelled


@njit(cache=True, inline="always")
def apf_zone_repulsion(
    i: int,
    fx: float,
    fy: float,
    fz: float,
    pos: np.ndarray,
    speed: np.ndarray,
    zones: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    lim: KernelLimits,
) -> tuple[float, float, float, bool]:
    """The field (fx, fy, fz) on vehicle i with Khatib's gradient from every zone added,
    by the distance to its nearest surface point and along the normal there
    (``gcs_ppf.planning.zones.zone_distance``; the reach from the surface as PPF's,
    ``surface_influence_radius``); returns (the field, whether a zone repels)."""
    kind, geom, vstart, verts = zones[0], zones[1], zones[2], zones[3]  # (not the hulls)
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
    reach = surface_influence_radius(speed[i], omega, lim.safe_distance_obstacle)
    repelled = False
    for k in range(kind.shape[0]):
        if not kind[k] & INCLUSION and zone_lower_bound(k, px, py, pz, geom) >= reach:
            continue
        d, nx, ny, nz = zone_distance(k, px, py, pz, kind, geom, vstart, verts)
        mag = khatib_repulsion(d, lim.safe_distance_obstacle, reach)
        if mag > 0.0:
            repelled = True
            fx, fy, fz = fx + mag * nx, fy + mag * ny, fz + mag * nz
    return fx, fy, fz, repelled


@njit(cache=True, inline="always")
def apf_motion(
    i: int,
    fx: float,
    fy: float,
    fz: float,
    dist: float,
    pitch: np.ndarray,
    yaw: np.ndarray,
    speed: np.ndarray,
    lim: KernelLimits,
    dt: float,
) -> tuple[float, float, float]:
    """The new (speed, pitch, yaw): the heading follows the field at once (no turn-rate
    limit); the leader cruises at its initial speed, a wingman flies at the leader's speed
    plus a term in proportion to its distance from G_i; speed and acceleration limits hold."""
    horizontal = math.sqrt(fx * fx + fy * fy)
    if horizontal > 0.0 or fz != 0.0:
        th = math.atan2(fz, horizontal)
        ps = math.atan2(fy, fx) if horizontal > 0.0 else yaw[i]
    else:
        th, ps = pitch[i], yaw[i]
    vi = speed[i]
    v_cmd = vi if i == 0 else speed[0] + SPEED_GAIN * dist
    v_cmd = min(max(v_cmd, lim.v_min), lim.v_max)
    if v_cmd > vi:
        v_new = min(v_cmd, vi + lim.accel * dt)
    else:
        v_new = max(v_cmd, vi - lim.decel * dt)
    return v_new, th, ps


@njit(cache=True)
def apf_fleet_step(
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
    state: np.ndarray,
    avoiding: np.ndarray,
    formed: np.ndarray,
    direction: np.ndarray,
    local_target: np.ndarray,
    next_motion: np.ndarray,
    zones: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> None:
    """Advance the fleet one step Δt in place by the classical APF method: the unit
    attraction towards the target (the leader) or G_i (a wingman) plus the repulsions
    (the zones' by ``apf_zone_repulsion``)."""
    apf_targets(pos, pitch, yaw, slot, direction, local_target)
    for i in range(pos.shape[0]):
        formed[i] = False
        state[i] = S1_FOLLOW
        if not active[i]:
            continue
        goal = target if i == 0 else local_target[i]
        gx, gy, gz = goal[0] - pos[i, 0], goal[1] - pos[i, 1], goal[2] - pos[i, 2]
        dist = math.sqrt(gx * gx + gy * gy + gz * gz)
        formed[i] = i > 0 and dist <= lim.target_accuracy
        fx, fy, fz = 0.0, 0.0, 0.0
        if dist > 0.0:
            fx, fy, fz = gx / dist, gy / dist, gz / dist  # unit attraction
        fx, fy, fz, avoiding[i] = apf_repulsion(
            i, fx, fy, fz, pos, speed, rank, active, obs_center, obs_radius, lim
        )
        fx, fy, fz, by_zone = apf_zone_repulsion(i, fx, fy, fz, pos, speed, zones, lim)
        avoiding[i] = avoiding[i] or by_zone
        next_motion[i, 0], next_motion[i, 1], next_motion[i, 2] = apf_motion(
            i, fx, fy, fz, dist, pitch, yaw, speed, lim, dt
        )
    move(pos, pitch, yaw, speed, active, next_motion, obs_center, obs_velocity, dt)

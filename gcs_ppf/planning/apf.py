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
) -> None:
    """Advance the fleet one step Δt in place by the classical APF method."""
    n = pos.shape[0]
    m = obs_center.shape[0]
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    lcp, lsp = math.cos(pitch[0]), math.sin(pitch[0])
    lcy, lsy = math.cos(yaw[0]), math.sin(yaw[0])
    for i in range(n):
        gx, gy, gz = slot_to_ics(slot[i, 0], slot[i, 1], slot[i, 2], lcp, lsp, lcy, lsy)
        local_target[i, 0] = pos[0, 0] + gx
        local_target[i, 1] = pos[0, 1] + gy
        local_target[i, 2] = pos[0, 2] + gz
        cp = math.cos(pitch[i])
        direction[i, 0] = cp * math.cos(yaw[i])
        direction[i, 1] = cp * math.sin(yaw[i])
        direction[i, 2] = math.sin(pitch[i])

    for i in range(n):
        formed[i] = False
        state[i] = S1_FOLLOW
        if not active[i]:
            continue
        px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
        vi = speed[i]
        if i == 0:
            gx, gy, gz = target[0] - px, target[1] - py, target[2] - pz
        else:
            gx = local_target[i, 0] - px
            gy = local_target[i, 1] - py
            gz = local_target[i, 2] - pz
        dist = math.sqrt(gx * gx + gy * gy + gz * gz)
        formed[i] = i > 0 and dist <= lim.target_accuracy
        fx, fy, fz = 0.0, 0.0, 0.0
        if dist > 0.0:
            fx, fy, fz = gx / dist, gy / dist, gz / dist  # unit attraction

        repelled = False
        for j in range(m):
            dx = px - obs_center[j, 0]
            dy = py - obs_center[j, 1]
            dz = pz - obs_center[j, 2]
            d = math.sqrt(dx * dx + dy * dy + dz * dz)
            reach = (
                influence_radius(vi, omega, obs_radius[j] + lim.safe_distance_obstacle)
                - obs_radius[j]
            )
            mag = khatib_repulsion(d - obs_radius[j], lim.safe_distance_obstacle, reach)
            if mag > 0.0 and d > 0.0:
                repelled = True
                fx += mag * dx / d
                fy += mag * dy / d
                fz += mag * dz / d
        for k in range(n):
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
        avoiding[i] = repelled

        # The heading follows the field at once (no turn-rate limit).
        horizontal = math.sqrt(fx * fx + fy * fy)
        if horizontal > 0.0 or fz != 0.0:
            next_motion[i, 1] = math.atan2(fz, horizontal)
            next_motion[i, 2] = math.atan2(fy, fx) if horizontal > 0.0 else yaw[i]
        else:
            next_motion[i, 1] = pitch[i]
            next_motion[i, 2] = yaw[i]

        # Speed: the leader cruises at its initial speed; a wingman at the leader's speed
        # plus a term in proportion to its distance from G_i.  Speed and acceleration
        # limits hold.
        v_cmd = vi if i == 0 else speed[0] + SPEED_GAIN * dist
        v_cmd = min(max(v_cmd, lim.v_min), lim.v_max)
        if v_cmd > vi:
            v_new = min(v_cmd, vi + lim.accel * dt)
        else:
            v_new = max(v_cmd, vi - lim.decel * dt)
        next_motion[i, 0] = v_new

    move(pos, pitch, yaw, speed, active, next_motion, obs_center, obs_velocity, dt)

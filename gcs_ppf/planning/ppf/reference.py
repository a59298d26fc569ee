"""A plain-numpy reference of one PPF step, vectorised over the fleet.

The same equations as ``gcs_ppf.planning.ppf.kernel.fleet_step`` written with whole-array numpy
operations: slower (see the README's speed table) but short, and independent enough of
the compiled kernel to check it in tests.  Same arguments; returns new arrays
(pos, pitch, yaw, speed, state) instead of updating in place.
"""

from __future__ import annotations

import math

import numpy as np

from gcs_ppf.planning.ppf.kernel import (
    AVOIDANCE_TURN_ANGLE,
    CONFLICT_HORIZON_TURNS,
    EPSILON_1,
    INFLUENCE_STEPS,
    LOCAL_MINIMUM_ANGLE,
    MAX_FOLLOW_PITCH,
    S1_FOLLOW,
    S2_LOCAL_MINIMUM,
    S3_FORMATION,
    SIDEWAYS_EPS,
    KernelLimits,
    airframe_limited,
    limit_climb,
)
from gcs_ppf.planning.scene import BoolArray, FloatArray, IntArray

Step = tuple[FloatArray, FloatArray, FloatArray, FloatArray, IntArray]


def _unit(v: FloatArray) -> FloatArray:
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    unit: FloatArray = np.divide(v, norm, out=np.zeros_like(v), where=norm > 0)
    return unit


def reference_step(
    pos: FloatArray, pitch: FloatArray, yaw: FloatArray, speed: FloatArray,
    slot: FloatArray, rank: IntArray, active: BoolArray, obs_center: FloatArray,
    obs_radius: FloatArray, obs_velocity: FloatArray, target: FloatArray,
    lim: KernelLimits, dt: float,
) -> Step:  # fmt: skip
    """One step Δt of the whole fleet (Eq. 3–24), in numpy."""
    n = pos.shape[0]
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    cp, sp, cy, sy = np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    u = np.stack([cp * cy, cp * sy, sp], axis=1)  # flight directions (Eq. 5)
    vel = speed[:, None] * u

    # Eq. 6–8 (corrected): local target points, formed, and whether the leader waits.
    sx, sy_, sz = slot.T
    px_ = cp[0] * sx - sp[0] * sz
    g = np.stack([cy[0] * px_ - sy[0] * sy_, sy[0] * px_ + cy[0] * sy_, sp[0] * sx + cp[0] * sz], 1)
    g = g + pos[0]
    to_g = g - pos
    wingman = active & (np.arange(n) > 0)
    formed = wingman & ((to_g**2).sum(1) <= lim.target_accuracy**2)
    along = to_g @ u[0]
    same_way = u @ u[0] > 0.0
    leader_waits = bool(np.any(wingman & ~formed & ((along >= 0.0) | ~same_way)))

    # Eq. 10–13: obstacles inside the influence radius repel with ε₁.
    d_obs = pos[:, None, :] - obs_center[None]  # [N,M,3]
    dist = np.linalg.norm(d_obs, axis=-1)
    u_obs = np.linalg.norm(obs_velocity, axis=-1)
    closing = np.maximum((d_obs * obs_velocity[None]).sum(-1) / np.where(dist > 0, dist, 1), 0)
    rho = (speed / omega)[:, None]
    keep = (obs_radius + lim.safe_distance_obstacle)[None]
    radius = np.sqrt((keep + rho) ** 2 - rho**2) + INFLUENCE_STEPS * (speed * dt)[:, None]
    radius = radius + closing * AVOIDANCE_TURN_ANGLE / omega
    if airframe_limited(lim):
        radius = radius + rho  # room for a half turn (the kernel's half_turn)
    inside = (dist <= radius) & (dist > 0)
    rep = EPSILON_1 * (_unit(d_obs) * inside[..., None]).sum(1)
    moving = (inside & (u_obs[None] > 0)).any(1)

    # Teammates of higher priority: conflicts by closest point of approach.
    d_m = pos[:, None, :] - pos[None]  # [i,k,3]: from mate k to vehicle i
    w = vel[None] - vel[:, None]  # mate k relative to vehicle i
    approach = (w * d_m).sum(-1)
    w2 = (w**2).sum(-1)
    horizon = CONFLICT_HORIZON_TURNS * AVOIDANCE_TURN_ANGLE / omega
    t_cpa = np.minimum(np.divide(approach, w2, out=np.zeros_like(approach), where=w2 > 0), horizon)
    miss2 = (d_m**2).sum(-1) - 2 * approach * t_cpa + w2 * t_cpa**2
    turning = 0.5 * (speed[:, None] + speed[None]) * omega * t_cpa**2
    margin = 2 * speed[:, None] * dt + np.minimum(turning, lim.safe_distance_uav)
    d2 = (d_m**2).sum(-1)
    mate_radius = (
        np.sqrt((lim.safe_distance_uav + speed / omega) ** 2 - (speed / omega) ** 2) + speed * dt
    )[:, None] + speed[None] * AVOIDANCE_TURN_ANGLE / omega
    threshold = lim.safe_distance_uav + margin
    near = (
        (rank[None] < rank[:, None]) & active[None] & (approach > 0) & (w2 > 0)
        & (miss2 < (threshold + lim.safe_distance_uav) ** 2)
        & (d2 <= mate_radius**2) & (d2 > 0)
    )  # fmt: skip
    threat = near & (miss2 < threshold**2)
    hold_course = (near & ~threat).any(1)
    miss_vec = d_m - w * t_cpa[..., None]
    miss = np.linalg.norm(miss_vec, axis=-1)
    push = np.where((miss > 1e-6 * np.sqrt(d2))[..., None], _unit(miss_vec), _unit(d_m))
    obstacles_rep = rep
    rep = rep + EPSILON_1 * (push * threat[..., None]).sum(1)
    # Obstacles first: drop the teammates' push against the obstacles' (the kernel's
    # obstacles_first).
    o2 = (obstacles_rep**2).sum(1)
    into = np.divide(((rep - obstacles_rep) * obstacles_rep).sum(1), o2, out=np.zeros(n),
                     where=o2 > 0)  # fmt: skip
    rep = rep - np.minimum(into, 0.0)[:, None] * obstacles_rep
    moving |= threat.any(1)
    repelled = (rep != 0).any(1)

    # Eq. 14–15: attraction (unit) unless repelled.
    aim = g + (speed[0] / omega) * u[0]
    aim[0] = target
    to_aim = aim - pos
    horizontal = np.hypot(to_aim[:, 0], to_aim[:, 1])
    heading = np.where(
        (horizontal > 0)[:, None],
        to_aim[:, :2] / np.where(horizontal > 0, horizontal, 1.0)[:, None],
        np.stack([cy, sy], axis=1),
    )
    elevation = np.clip(np.arctan2(to_aim[:, 2], horizontal), -MAX_FOLLOW_PITCH, MAX_FOLLOW_PITCH)
    follow = np.concatenate(
        [np.cos(elevation)[:, None] * heading, np.sin(elevation)[:, None]], axis=1
    )
    # Hold course only where following would turn back into the conflict.
    held = (push * (near & ~threat)[..., None]).sum(1)
    hold = hold_course & ((follow * held).sum(1) < (u * held).sum(1))  # it would turn back
    field = np.where(repelled[:, None], rep, np.where(hold[:, None], u, follow))
    field = np.where((np.linalg.norm(field, axis=1) > 0)[:, None], field, u)

    # Eq. 16–18 into the VCS.
    bx = cy * field[:, 0] + sy * field[:, 1]
    fvx = cp * bx + sp * field[:, 2]
    fvy = -sy * field[:, 0] + cy * field[:, 1]
    fvz = -sp * bx + cp * field[:, 2]
    along_field = fvx.copy()
    state = np.full(n, S1_FOLLOW)

    # Eq. 20: local minimum → F_add along +z_v.
    norm = np.sqrt(fvx**2 + fvy**2 + fvz**2)
    s2 = repelled & (fvx < 0) & (np.hypot(fvy, fvz) <= norm * math.sin(LOCAL_MINIMUM_ANGLE))
    fvz = fvz + np.where(s2, EPSILON_1, 0.0)
    state[s2] = S2_LOCAL_MINIMUM
    norm = np.sqrt(fvx**2 + fvy**2 + fvz**2)

    # Static obstacles: turn only until no longer closing (projection onto the tangent plane).
    project = repelled & ~moving
    k = np.divide(fvx, norm**2, out=np.zeros_like(fvx), where=norm > 0)
    closing_in = project & (fvx < 0)
    hold = project & (fvx >= 0)
    fvx, fvy, fvz = (
        np.where(closing_in, 1 - k * fvx, np.where(hold, 1.0, fvx)),
        np.where(closing_in, -k * fvy, np.where(hold, 0.0, fvy)),
        np.where(closing_in, -k * fvz, np.where(hold, 0.0, fvz)),
    )

    # No descent that could not level out above the ground's keep-out: pulling up at
    # ω_θ on an arc of radius v/ω_θ loses ρ(1 − cos γ) (the kernel's lowest_climb).
    height = pos[:, 2] - lim.ground - lim.safe_distance_obstacle - INFLUENCE_STEPS * speed * dt
    quarter_turn = AVOIDANCE_TURN_ANGLE / lim.max_pitch_rate
    rho_up = np.minimum(speed + lim.accel * quarter_turn, lim.v_max) / lim.max_pitch_rate
    r = np.minimum(height / rho_up, 1.0)
    lowest = np.where(
        r >= 0.0,
        -np.sqrt(1.0 - (1.0 - np.maximum(r, 0.0)) ** 2),
        np.minimum(-r, math.sin(MAX_FOLLOW_PITCH)),
    )

    # No steeper than MAX_AVOID_PITCH or the airframe (the kernel's limit_climb, by vehicle).
    px_ = cp * fvx - sp * fvz  # VCS → ICS
    d = np.stack([cy * px_ - sy * fvy, sy * px_ + cy * fvy, sp * fvx + cp * fvz], axis=1)
    for i in range(n):
        d[i] = limit_climb(
            d[i, 0],
            d[i, 1],
            d[i, 2],
            rep[i, 0],
            rep[i, 1],
            rep[i, 2],
            bool(closing_in[i]),
            cy[i],
            sy[i],
            float(lowest[i]),
            lim,
        )
    bx = cy * d[:, 0] + sy * d[:, 1]  # ICS → VCS
    fvx, fvy, fvz = cp * bx + sp * d[:, 2], -sy * d[:, 0] + cy * d[:, 1], -sp * bx + cp * d[:, 2]

    # Eq. 19 (erratum 2), saturated.
    elevation = np.arctan2(fvz, np.hypot(fvx, fvy))
    behind = np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1])) - pitch
    ics = (fvx < 0) | (np.abs(pitch) > MAX_FOLLOW_PITCH) | (lowest > -1.0)
    ics |= airframe_limited(lim)
    elevation = np.where(ics, behind, elevation)
    wanted = np.sqrt(fvx**2 + fvy**2 + fvz**2)
    azimuth = np.where(np.abs(fvy) > SIDEWAYS_EPS * wanted, np.arctan2(fvy, fvx), 0.0)
    azimuth = np.where((fvx < 0) & (azimuth == 0.0), math.pi, azimuth)
    f_pitch = np.clip(elevation / (lim.max_pitch_rate * dt), -1, 1)
    f_yaw = np.clip(azimuth / (lim.max_yaw_rate * dt), -1, 1)
    # Never turn further towards a repelling obstacle when the other sense does not
    # (the kernel's away_from_obstacles).
    o = obstacles_rep
    now = (u * o).sum(1)
    th = pitch + f_pitch * lim.max_pitch_rate * dt
    turn = f_yaw * lim.max_yaw_rate * dt

    def towards(psi: FloatArray) -> FloatArray:
        along: FloatArray = np.cos(th) * (np.cos(psi) * o[:, 0] + np.sin(psi) * o[:, 1])
        along = along + np.sin(th) * o[:, 2]
        return along

    after, other = towards(yaw + turn), towards(yaw - turn)
    reverse = (now < 0) & (f_yaw != 0) & (after < now) & (other > after)
    f_yaw = np.where(reverse, -f_yaw, f_yaw)
    f_speed = np.sign(along_field)

    # Eq. 21–24: the leader waits; wingmen brake to arrive at the leader's speed.
    if leader_waits:
        f_speed[0] = -1.0
        state[0] = S3_FORMATION
    follow = wingman & ~repelled & (along_field > 0)
    gap = np.linalg.norm(to_g, axis=1)
    v_ahead = np.sqrt(speed[0] ** 2 + 2 * lim.decel * gap)
    v_behind = np.sqrt(np.maximum(speed[0] ** 2 + 2 * lim.accel * along, 0.0))
    v_cmd = np.where(along >= 0, v_ahead, v_behind)
    brake = follow & (along >= 0) & ~formed & (speed >= v_cmd)
    state[brake] = S3_FORMATION
    a_cmd = np.where(v_cmd >= speed, lim.accel, lim.decel)
    f_speed = np.where(follow, np.clip((v_cmd - speed) / (a_cmd * dt), -1, 1), f_speed)

    # Eq. 3–5.
    a_l = np.where(f_speed > 0, lim.accel, lim.decel)
    new_speed = np.clip(speed + f_speed * a_l * dt, lim.v_min, lim.v_max)
    new_pitch = np.clip(pitch + f_pitch * lim.max_pitch_rate * dt, -math.pi / 2, math.pi / 2)
    new_yaw = yaw + f_yaw * lim.max_yaw_rate * dt
    new_yaw = np.where(new_yaw > math.pi, new_yaw - 2 * math.pi, new_yaw)
    new_yaw = np.where(new_yaw <= -math.pi, new_yaw + 2 * math.pi, new_yaw)
    keep_old = ~active
    new_speed[keep_old], new_pitch[keep_old], new_yaw[keep_old] = (
        speed[keep_old],
        pitch[keep_old],
        yaw[keep_old],
    )
    step = new_speed[:, None] * np.stack(
        [np.cos(new_pitch) * np.cos(new_yaw), np.cos(new_pitch) * np.sin(new_yaw),
         np.sin(new_pitch)], axis=1)  # fmt: skip
    new_pos = pos + np.where(active[:, None], step * dt, 0.0)
    return new_pos, new_pitch, new_yaw, new_speed, state.astype(np.int64)

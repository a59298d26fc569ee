"""Online planning: from the vehicles' telemetry to each vehicle's guided point and speed.

Pure: the service hands in the mission, the latest state of each vehicle (already in the
ICS) and the obstacles as they are now; this runs PPF forward from there and picks, for
each vehicle, the point of its planned path ``lookahead_s`` ahead (a plane that reaches its
guided point circles it, so the point must stay ahead) and the speed the plan asks for.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from gcs_ppf.frames import local_target_point
from gcs_ppf.geodesy import velocity_ned_to_enu
from gcs_ppf.mission import Mission
from gcs_ppf.planner import advance
from gcs_ppf.scene import FloatArray, Obstacles, Scene, scene_from_mission

STATE_NAMES = {1: "s1", 2: "s2", 3: "s3"}


@dataclass(frozen=True)
class VehicleState:
    """A vehicle as the planner sees it: ICS position (m), flight-path pitch and yaw (rad,
    from the velocity, not the attitude: a real aircraft flies at an angle of attack)."""

    pos_m: tuple[float, float, float]
    pitch_rad: float
    yaw_rad: float
    speed_m_s: float


def state_from_velocity(
    pos_m: tuple[float, float, float], vn_m_s: float, ve_m_s: float, vd_m_s: float
) -> VehicleState:
    """VehicleState from an ICS position and a NED velocity (GLOBAL_POSITION_INT)."""
    ve, vn, vu = velocity_ned_to_enu(vn_m_s, ve_m_s, vd_m_s)
    horizontal = math.hypot(ve, vn)
    return VehicleState(
        pos_m=pos_m,
        pitch_rad=math.atan2(vu, horizontal),
        yaw_rad=math.atan2(vn, ve),
        speed_m_s=math.sqrt(horizontal**2 + vu**2),
    )


@dataclass(frozen=True)
class Guidance:
    """What one planning tick decided, per vehicle in scene order (leader first)."""

    ids: list[int]
    guided_point_m: FloatArray  # [N,3] ICS
    speed_m_s: FloatArray  # [N]
    state: list[str]  # PPF state of the first planned step
    avoiding: list[bool]
    formed: list[bool]
    local_target_distance_m: list[float | None]  # None for the leader
    leader_arrives_within_lookahead: bool


def scene_now(
    mission: Mission,
    states: dict[int, VehicleState],
    active_ids: set[int],
    obstacles: Obstacles,
) -> Scene:
    """The mission's scene with the vehicles where telemetry says they are."""
    base = scene_from_mission(mission)
    fleet = base.fleet.copy()
    lim = base.limits
    for i, vid in enumerate(fleet.ids.tolist()):
        s = states.get(vid)
        fleet.active[i] = s is not None and vid in active_ids
        if s is None:
            continue
        fleet.pos[i] = s.pos_m
        fleet.pitch[i] = max(-math.pi / 2, min(math.pi / 2, s.pitch_rad))
        fleet.yaw[i] = s.yaw_rad
        fleet.speed[i] = min(max(s.speed_m_s, lim.v_min), lim.v_max)
    return replace(base, fleet=fleet, obstacles=obstacles)


def guidance(scene: Scene, *, lookahead_s: float, dt: float, speed_lead_s: float = 0.5) -> Guidance:
    """Run PPF ``lookahead_s`` ahead from ``scene`` and read off each vehicle's guided
    point (its planned position then) and speed (its planned speed ``speed_lead_s`` on)."""
    steps = max(1, round(lookahead_s / dt))
    run = advance(scene, dt, steps)
    tr = run.trajectory
    k_speed = min(len(tr) - 1, max(0, round(speed_lead_s / dt) - 1))
    fleet = scene.fleet
    ids = fleet.ids.tolist()
    guided = tr.pos[-1].copy()
    guided[~fleet.active] = fleet.pos[~fleet.active]
    if run.arrived:
        guided[0] = scene.target
    gaps = [
        float(np.linalg.norm(
            local_target_point(fleet.pos[0], float(fleet.pitch[0]), float(fleet.yaw[0]),
                               fleet.slot[i]) - fleet.pos[i]
        ))
        for i in range(1, len(ids))
    ]  # fmt: skip
    return Guidance(
        ids=ids,
        guided_point_m=guided,
        speed_m_s=tr.speed[k_speed].copy(),
        state=[STATE_NAMES[int(s)] for s in tr.state[0]],
        avoiding=[bool(a) for a in tr.avoiding[0]],
        formed=[bool(f) for f in tr.formed[0]],
        local_target_distance_m=[None, *gaps],
        leader_arrives_within_lookahead=run.arrived,
    )


def separations(positions: FloatArray) -> float | None:
    """Smallest centre-to-centre distance among the given [N,3] positions."""
    n = positions.shape[0]
    if n < 2:
        return None
    gaps = np.linalg.norm(positions[:, None] - positions[None], axis=-1)
    gaps[np.arange(n), np.arange(n)] = np.inf
    return float(gaps.min())


def clearance(positions: FloatArray, obstacles: Obstacles) -> float | None:
    """Smallest distance from the given positions to any obstacle surface."""
    if obstacles.radius.shape[0] == 0 or positions.shape[0] == 0:
        return None
    d = np.linalg.norm(positions[:, None] - obstacles.center[None], axis=-1) - obstacles.radius
    return float(d.min())

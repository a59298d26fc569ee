"""The planner's view of a mission: the fleet and the obstacles as plain arrays.

Vehicles are stored leader first (index 0, as the kernel expects), then the wingmen in
priority order.  ``rank`` orders avoidance: a vehicle avoids every active vehicle of lower
rank and is ignored by them (the leader has rank 0 unless a mission says otherwise).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from gcs_ppf.mission import Limits, Mission, Vehicle
from gcs_ppf.planning.ppf.kernel import KernelLimits
from gcs_ppf.planning.turns import formation_turn_limits
from gcs_ppf.planning.zones import Zones, no_zones, zones_from_mission

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class Fleet:
    """State of N vehicles (structure of arrays, SI units, ICS).

    ids[N] MAVLink system ids; pos[N,3] m; pitch[N], yaw[N] rad; speed[N] m/s;
    slot[N,3] m in the leader's VCS; rank[N] avoidance priority; active[N].
    """

    ids: IntArray
    pos: FloatArray
    pitch: FloatArray
    yaw: FloatArray
    speed: FloatArray
    slot: FloatArray
    rank: IntArray
    active: BoolArray

    def copy(self) -> Fleet:
        a = np.array
        return Fleet(
            a(self.ids),
            a(self.pos),
            a(self.pitch),
            a(self.yaw),
            a(self.speed),
            a(self.slot),
            a(self.rank),
            a(self.active),
        )

    def index_of(self, vehicle_id: int) -> int:
        hits = np.flatnonzero(self.ids == vehicle_id)
        if hits.size == 0:
            raise KeyError(vehicle_id)
        return int(hits[0])


@dataclass(frozen=True)
class Obstacles:
    """M spheres: center[M,3] m, radius[M] m, velocity[M,3] m/s."""

    center: FloatArray
    radius: FloatArray
    velocity: FloatArray

    def copy(self) -> Obstacles:
        return Obstacles(self.center.copy(), self.radius.copy(), self.velocity.copy())

    def at(self, elapsed_s: float) -> Obstacles:
        """The obstacles after ``elapsed_s`` seconds of constant-velocity motion."""
        return replace(self, center=self.center + self.velocity * elapsed_s)


@dataclass(frozen=True)
class Scene:
    """Everything the planner needs: fleet, obstacles, leader target and limits, and the
    zones (static cylinders and polygons, ``gcs_ppf.planning.zones``; none by default)."""

    fleet: Fleet
    obstacles: Obstacles
    target: FloatArray
    limits: KernelLimits
    zones: Zones = field(default_factory=no_zones)


def kernel_limits(limits: Limits, ground: float | None = None) -> KernelLimits:
    """The kernel's limits; ``ground`` None (the paper's free space) becomes −∞."""
    return KernelLimits(
        v_min=limits.v_min,
        v_max=limits.v_max,
        accel=limits.accel,
        decel=limits.decel,
        max_pitch_rate=limits.max_pitch_rate,
        max_yaw_rate=limits.max_yaw_rate,
        target_accuracy=limits.target_accuracy,
        safe_distance_uav=limits.safe_distance_uav,
        safe_distance_obstacle=limits.safe_distance_obstacle,
        ground=-math.inf if ground is None else ground,
    )


def priority_key(v: Vehicle) -> tuple[int, int, int]:
    """Avoidance order (lowest first): ``priority``, by default the leader first, then the
    wingmen by id."""
    default = 0 if v.role == "leader" else v.id
    return (v.priority if v.priority is not None else default, v.role != "leader", v.id)


def obstacles_from_mission(mission: Mission) -> Obstacles:
    m = len(mission.obstacles)
    return Obstacles(
        center=np.array([o.center for o in mission.obstacles], dtype=float).reshape(m, 3),
        radius=np.array([o.radius for o in mission.obstacles], dtype=float).reshape(m),
        velocity=np.array([o.velocity for o in mission.obstacles], dtype=float).reshape(m, 3),
    )


def with_margins(scene: Scene, obstacle_margin_m: float, teammate_margin_m: float) -> Scene:
    """The scene with both safe distances widened: the obstacles' by ``obstacle_margin_m``,
    the teammates' by ``teammate_margin_m`` (the closed loop's planning margins,
    ``gcs_ppf.guidance.online.scene_now``)."""
    lim = scene.limits
    return replace(
        scene,
        limits=lim._replace(
            safe_distance_uav=lim.safe_distance_uav + teammate_margin_m,
            safe_distance_obstacle=lim.safe_distance_obstacle + obstacle_margin_m,
        ),
    )


def scene_from_mission(mission: Mission) -> Scene:
    """Arrays of a validated mission: leader at index 0, wingmen by priority; the leader's
    turns those its formation follows if the mission holds them (``gcs_ppf.planning.turns``).
    The target is the mission's: the shells fly a route leg by leg
    (``gcs_ppf.planning.route``)."""
    by_priority = sorted(mission.vehicles, key=priority_key)
    rank_of = {v.id: r for r, v in enumerate(by_priority)}
    ordered = [mission.leader] + [v for v in by_priority if v.role != "leader"]
    lim = mission.limits
    fleet = Fleet(
        ids=np.array([v.id for v in ordered], dtype=np.int64),
        pos=np.array([v.position for v in ordered], dtype=float),
        pitch=np.array([v.pitch for v in ordered], dtype=float),
        yaw=np.array([v.yaw for v in ordered], dtype=float),
        speed=np.array([lim.v_init if v.speed is None else v.speed for v in ordered]),
        slot=np.array([v.slot or (0.0, 0.0, 0.0) for v in ordered], dtype=float),
        rank=np.array([rank_of[v.id] for v in ordered], dtype=np.int64),
        active=np.ones(len(ordered), dtype=bool),
    )
    whole = mission.obstacle_passage == "formation"
    limits = kernel_limits(lim, mission.ground)._replace(
        course_frame=mission.formation_frame == "course",
        leader_keep_out_pad=float(np.linalg.norm(fleet.slot, axis=1).max()) if whole else 0.0,
    )
    if mission.holds_turns:
        limits = formation_turn_limits(limits, fleet.slot[1:])
    return Scene(
        fleet=fleet,
        obstacles=obstacles_from_mission(mission),
        target=np.array(mission.target, dtype=float),
        limits=limits,
        zones=zones_from_mission(mission),
    )

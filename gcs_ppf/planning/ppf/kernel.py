"""One time step of the whole fleet: the paper's algorithm (Eq. 3–24), compiled by numba.

Plain arrays in, plain arrays out; no I/O, no clock.  ``fleet_step`` is the paper's
algorithm for one step; the equation groups it uses are numba functions of their own,
one module per group:

* ``unit_velocities``       Eq. 5 over v: each vehicle's flight direction (here)
* ``formation_targets``     Eq. 6–8 (local target points G_i), Eq. 24's condition (``formation``)
* ``obstacle_repulsion``    Eq. 10–13: ε₁ from every obstacle whose influence radius we are in
  (``repulsion``)
* ``teammate_conflicts``    Eq. 12–13 with teammates of higher priority as moving obstacles
  (``repulsion``)
* ``teammates_first``       a teammate conflict before the obstacles while they leave room
  (``repulsion``)
* ``yielding_back``         Eq. 12–13 the other way round: giving way back to a teammate of
  lower priority that has not solved a conflict alone (``repulsion``)
* ``attraction``            Eq. 14–15: towards the target point while nothing repels
  (``formation``)
* ``escape_local_minimum``  Eq. 20: state s2, F_add along +z_v (``steering``)
* ``slide_along_obstacles`` Eq. 19's wanted direction around static obstacles (``steering``)
* ``flight_path_limited``   the wanted direction within the flight-path and ground limits
  (``steering``)
* ``trend_matrix``          Eq. 19: pitch and yaw entries of f, erratum 2 (``steering``)
* ``steer``                 Eq. 16–20 in order: from the field to f_θ, f_ψ (``steering``)
* ``speed_trend``           Eq. 19's f_l with Eq. 21–24 (wingman braking, leader waiting)
  (``formation``)
* ``kinematics``            Eq. 3–5: the new speed, pitch and yaw (here)
* ``fly``                   Eq. 5: one step of flight (here)

The small formulas these are built from (frames, influence radius, saturated trend,
braking speed, flight-path limits) are in ``gcs_ppf.planning.ppf.primitives``.  The equation
groups are inlined into ``fleet_step`` by numba (``inline="always"``): left to LLVM, the
calls were not inlined and the step ran about twice as slow.  ``fleet_step`` is compiled
without numba's reference counting (``njit_without_refcounts``): every array an inlined
group binds cost two atomic operations, 40 % of a five-vehicle step.

Fleet layout (structure of arrays, N vehicles, M obstacles):
``pos[N,3]`` ICS metres, ``pitch[N]``, ``yaw[N]`` radians, ``speed[N]`` m/s,
``slot[N,3]`` the wingman's place in the leader's VCS (zeros for the leader, index 0),
``rank[N]`` avoidance priority (a vehicle avoids every active vehicle of lower rank),
``active[N]`` (inactive vehicles are neither moved nor avoided),
``obs_center[M,3]``, ``obs_radius[M]``, ``obs_velocity[M,3]``.

Design choices where the paper is silent or cannot be used as printed are documented
next to the code that makes them; docs/planner.md summarises them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gcs_ppf.planning.ppf.compiled import njit_without_refcounts
from gcs_ppf.planning.ppf.formation import (
    attraction,
    crossing_point,
    formation_targets,
    formation_turn_rate,
    just_reaching,
    slot_point_speed,
    speed_trend,
)
from gcs_ppf.planning.ppf.primitives import (
    AVOIDANCE_TURN_ANGLE,
    CONFLICT_HORIZON_TURNS,
    EPSILON_1,
    EPSILON_3,
    HAND_BACK_TURNS,
    INFLUENCE_STEPS,
    LOCAL_MINIMUM_ANGLE,
    MAX_AVOID_PITCH,
    MAX_FOLLOW_PITCH,
    S1_FOLLOW,
    S2_LOCAL_MINIMUM,
    S3_FORMATION,
    SIDEWAYS_EPS,
    YIELD_BACK_TURNS,
    KernelLimits,
    airframe_limited,
    away_from_obstacles,
    braking_speed,
    catching_up_speed,
    falling_back_speed,
    follow_direction,
    from_vcs,
    influence_radius,
    leader_limits,
    leader_speed_share,
    limit_climb,
    lowest_climb,
    obstacles_first,
    passing_limits,
    reaching_turn_rate,
    roll_in_lead,
    slot_to_ics,
    to_vcs,
    trend,
    turn_missed_ahead,
    turning_speed,
    way_clear,
)
from gcs_ppf.planning.ppf.repulsion import (
    obstacle_repulsion,
    teammate_conflict,
    teammate_conflicts,
    teammates_first,
    yielding_back,
)
from gcs_ppf.planning.ppf.steering import (
    escape_local_minimum,
    flight_path_limited,
    slide_along_obstacles,
    steer,
    trend_matrix,
)
from gcs_ppf.planning.ppf.zone_repulsion import zone_repulsion

__all__ = [
    "AVOIDANCE_TURN_ANGLE",
    "CONFLICT_HORIZON_TURNS",
    "EPSILON_1",
    "EPSILON_3",
    "HAND_BACK_TURNS",
    "INFLUENCE_STEPS",
    "LOCAL_MINIMUM_ANGLE",
    "MAX_AVOID_PITCH",
    "MAX_FOLLOW_PITCH",
    "S1_FOLLOW",
    "S2_LOCAL_MINIMUM",
    "S3_FORMATION",
    "SIDEWAYS_EPS",
    "YIELD_BACK_TURNS",
    "KernelLimits",
    "airframe_limited",
    "attitude_trig",
    "attraction",
    "away_from_obstacles",
    "braking_speed",
    "catching_up_speed",
    "crossing_point",
    "escape_local_minimum",
    "falling_back_speed",
    "fleet_step",
    "flight_path_limited",
    "fly",
    "follow_direction",
    "formation_frame",
    "formation_targets",
    "from_vcs",
    "influence_radius",
    "kinematics",
    "leader_limits",
    "leader_speed_share",
    "limit_climb",
    "lowest_climb",
    "move",
    "move_obstacles",
    "obstacle_repulsion",
    "obstacles_first",
    "passing_limits",
    "reaching_turn_rate",
    "roll_in_lead",
    "slide_along_obstacles",
    "slot_to_ics",
    "speed_trend",
    "steer",
    "teammate_conflict",
    "teammate_conflicts",
    "teammates_first",
    "to_vcs",
    "trend",
    "trend_matrix",
    "turn_missed_ahead",
    "turning_speed",
    "unit_velocities",
    "way_clear",
    "yielding_back",
]


@njit(cache=True)
def attitude_trig(pitch: np.ndarray, yaw: np.ndarray, trig: np.ndarray) -> None:
    """cos θ, sin θ, cos ψ, sin ψ of every vehicle into ``trig[N, 0:4]``."""
    for i in range(pitch.shape[0]):
        trig[i, 0], trig[i, 1] = math.cos(pitch[i]), math.sin(pitch[i])
        trig[i, 2], trig[i, 3] = math.cos(yaw[i]), math.sin(yaw[i])


@njit(cache=True, inline="always")
def unit_velocities(speed: np.ndarray, trig: np.ndarray, direction: np.ndarray) -> None:
    """Each vehicle's flight direction, Eq. 5 divided by v, into ``direction[N,3]``, and its
    velocity (Eq. 5) into ``trig[N, 4:7]``, from cos/sin of pitch and yaw in ``trig[N, 0:4]``."""
    for i in range(speed.shape[0]):
        cp, sp, cy, sy = trig[i, 0], trig[i, 1], trig[i, 2], trig[i, 3]
        direction[i, 0] = cp * cy
        direction[i, 1] = cp * sy
        direction[i, 2] = sp
        for c in range(3):
            trig[i, 4 + c] = speed[i] * direction[i, c]


@njit(cache=True, inline="always")
def kinematics(
    speed: float,
    pitch: float,
    yaw: float,
    f_speed: float,
    f_pitch: float,
    f_yaw: float,
    lim: KernelLimits,
    dt: float,
) -> tuple[float, float, float]:
    """The new (speed, pitch, yaw) from the trend matrix f (Eq. 3–5):
    V(t) = V(t′) + f·Δt·a, speed within [v_min, v_max], pitch within [−π/2, π/2] (Eq. 1),
    yaw wrapped to (−π, π]."""
    a_l = lim.accel if f_speed > 0.0 else lim.decel
    v_new = min(max(speed + f_speed * a_l * dt, lim.v_min), lim.v_max)
    th = pitch + f_pitch * lim.max_pitch_rate * dt
    th = min(max(th, -0.5 * math.pi), 0.5 * math.pi)
    ps = yaw + f_yaw * lim.max_yaw_rate * dt
    if ps > math.pi:
        ps -= 2.0 * math.pi
    elif ps <= -math.pi:
        ps += 2.0 * math.pi
    return v_new, th, ps


@njit(cache=True, inline="always")
def fly(
    i: int,
    pos: np.ndarray,
    pitch: np.ndarray,
    yaw: np.ndarray,
    speed: np.ndarray,
    next_motion: np.ndarray,
    dt: float,
) -> tuple[float, float, float, float]:
    """Vehicle i takes the new (speed, pitch, yaw) of ``next_motion`` and flies one step
    (Eq. 5); returns cos θ, sin θ, cos ψ, sin ψ of its new attitude."""
    speed[i] = next_motion[i, 0]
    pitch[i] = next_motion[i, 1]
    yaw[i] = next_motion[i, 2]
    cp, sp = math.cos(pitch[i]), math.sin(pitch[i])
    cy, sy = math.cos(yaw[i]), math.sin(yaw[i])
    pos[i, 0] += speed[i] * cp * cy * dt
    pos[i, 1] += speed[i] * cp * sy * dt
    pos[i, 2] += speed[i] * sp * dt
    return cp, sp, cy, sy


@njit(cache=True)
def move_obstacles(obs_center: np.ndarray, obs_velocity: np.ndarray, dt: float) -> None:
    """Every obstacle moves one step at its constant velocity."""
    for j in range(obs_center.shape[0]):
        for c in range(3):
            obs_center[j, c] += obs_velocity[j, c] * dt


@njit(cache=True)
def move(
    pos: np.ndarray,
    pitch: np.ndarray,
    yaw: np.ndarray,
    speed: np.ndarray,
    active: np.ndarray,
    next_motion: np.ndarray,
    obs_center: np.ndarray,
    obs_velocity: np.ndarray,
    dt: float,
) -> None:
    """Take the new (speed, pitch, yaw) of ``next_motion`` and fly one step (Eq. 5);
    move the obstacles at their constant velocity."""
    for i in range(pos.shape[0]):
        if active[i]:
            fly(i, pos, pitch, yaw, speed, next_motion, dt)
    move_obstacles(obs_center, obs_velocity, dt)


FRAME_TARGET_TURNS = 4.0
"""``formation_frame`` keeps the leader's VCS within this many of its turn radii of its
target, where the way to the target swings round as the leader passes it."""


@njit(cache=True, inline="always")
def formation_frame(
    pos: np.ndarray,
    speed: np.ndarray,
    active: np.ndarray,
    trig: np.ndarray,
    direction: np.ndarray,
    target: np.ndarray,
    obs_center: np.ndarray,
    obs_radius: np.ndarray,
    obs_velocity: np.ndarray,
    near_start: np.ndarray,
    near_obstacles: np.ndarray,
    zones: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    zone_start: np.ndarray,
    near_zones: np.ndarray,
    lim: KernelLimits,
    dt: float,
) -> tuple[float, float, float, float]:
    """cos θ₀, sin θ₀, cos ψ₀, sin ψ₀ of the frame the wingmen's slots are placed in
    (Eq. 6–8): the leader's velocity frame (its VCS); with ``lim.course_frame``, while
    obstacles or zones repel the leader and its target is further than
    ``FRAME_TARGET_TURNS`` turn radii, level and along its way to its target (the paper is
    silent).  Round the sphere on the line-abreast missions' way the leader swung 30–45°
    aside and back, its slots 141 m off swung with it, and the wingmen chasing them were
    flung to the far side of the formation (a wingman 245 m from its slot for 40 s);
    planned offline with the closed loop's 50 m obstacle margin and the ground, in
    formation 48 % of the flight after forming, 71 % on the course.  The formation is
    still judged in the leader's VCS (``metrics``): where the leader turns round large
    obstacles for long (Table 3) the course frame is not its formation, hence an option.
    Flown on real ArduPlane it did not raise the line abreast's share (docs/planner.md).
    """
    frame = (trig[0, 0], trig[0, 1], trig[0, 2], trig[0, 3])
    if not lim.course_frame or not active[0]:
        return frame
    ox, oy, oz, _, _, _ = obstacle_repulsion(
        0,
        pos,
        speed,
        direction,
        obs_center,
        obs_radius,
        obs_velocity,
        near_start,
        near_obstacles,
        lim,
        dt,
        target,
    )
    zx, zy, zz = zone_repulsion(0, pos, speed, direction, zones, zone_start, near_zones, lim, dt)
    if ox == 0.0 and oy == 0.0 and oz == 0.0 and zx == 0.0 and zy == 0.0 and zz == 0.0:
        return frame
    hx, hy = target[0] - pos[0, 0], target[1] - pos[0, 1]
    h = math.sqrt(hx * hx + hy * hy)
    if h < FRAME_TARGET_TURNS * speed[0] / min(lim.max_pitch_rate, lim.max_yaw_rate):
        return frame
    return 1.0, 0.0, hx / h, hy / h


@njit_without_refcounts
def fleet_step(
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
    near_start: np.ndarray,
    near_obstacles: np.ndarray,
    mate_start: np.ndarray,
    mates: np.ndarray,
    trig: np.ndarray,
    zones: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    zone_start: np.ndarray,
    near_zones: np.ndarray,
) -> None:
    """Advance the fleet one step Δt in place: the paper's algorithm (Eq. 3–24).

    ``state[N]`` receives each vehicle's PPF state (1, 2, 3), ``avoiding[N]`` whether an
    obstacle or teammate repels it, ``formed[N]`` whether a wingman is within the target
    accuracy of its local target point, ``local_target[N,3]`` the wingmen's local target
    points G_i (Eq. 6).  ``direction[N,3]`` and ``next_motion[N,3]`` are scratch space.
    Vehicle i considers only the obstacles ``near_obstacles[near_start[i]:near_start[i+1]]``
    (see ``nearby_obstacles``), and only the teammates ``mates[mate_start[i]:mate_start[i+1]]``
    (see ``nearby_teammates``; every active teammate of higher priority for all pairs).
    ``trig[N,11]`` holds cos θ, sin θ, cos ψ, sin ψ of every vehicle on entry
    (``attitude_trig``) and of its new attitude on return; its last columns are scratch
    (the velocities, and who gives way back: ``yielding_back``).
    Every vehicle decides from the fleet's state at the start of the step (``rank`` through
    the teammate lists).  Obstacles are moved at the end of the step.  ``zones`` (the
    arrays of ``gcs_ppf.planning.zones``) repel as obstacles do (``zone_repulsion``), each
    vehicle looking at ``near_zones[zone_start[i]:zone_start[i+1]]`` (``nearby_zones``).
    """
    unit_velocities(speed, trig, direction)  # Eq. 5
    frame = formation_frame(
        pos,
        speed,
        active,
        trig,
        direction,
        target,
        obs_center,
        obs_radius,
        obs_velocity,
        near_start,
        near_obstacles,
        zones,
        zone_start,
        near_zones,
        lim,
        dt,
    )
    wait_speed = formation_targets(
        pos, slot, active, trig, direction, lim, local_target, formed, frame
    )
    yielding_back(pos, speed, trig, active, mate_start, mates, formed, lim, dt)  # Eq. 12–13
    ux, uy, uz = direction[0, 0], direction[0, 1], direction[0, 2]  # the leader's direction
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    reaching = reaching_turn_rate(
        pos[0, 0], pos[0, 1], trig[0, 2], trig[0, 3], speed[0], lim, target[0], target[1]
    )
    leader_lim = leader_limits(lim, reaching)
    for i in range(pos.shape[0]):
        if not active[i]:
            continue
        cp, sp, cy, sy = trig[i, 0], trig[i, 1], trig[i, 2], trig[i, 3]
        # Attraction (Eq. 14): the way to the target point, passing teammates.
        g = target if i == 0 else local_target[i]
        turn_rate = 0.0  # the leader's, in a held turn (decided first, i = 0)
        if i > 0 and active[0] and lim.leader_turn_rate < math.inf:
            turn = next_motion[0, 2] - yaw[0]
            turn_rate = (turn - 2.0 * math.pi * round(turn / (2.0 * math.pi))) / dt
        # Its reach among teammates: R(v_i) of the safe distance (Eq. 10–11) and a step.
        own_reach = influence_radius(speed[i], omega, lim.safe_distance_uav) + speed[i] * dt
        fx, fy, fz, ax, ay, az = attraction(
            i,
            g[0],
            g[1],
            g[2],
            ux,
            uy,
            uz,
            pos,
            speed,
            mate_start,
            mates,
            own_reach,
            lim,
            dt,
            cy,
            sy,
            turn_rate,
        )
        # Repulsion (Eq. 12–13): the obstacles', then the teammates' of higher priority,
        # never pushing the vehicle into an obstacle (``obstacles_first``) unless it has
        # room to give way to the teammates first (``teammates_first``).
        ox, oy, oz, moving_obstacle, room, formation_turn = obstacle_repulsion(
            i,
            pos,
            speed,
            direction,
            obs_center,
            obs_radius,
            obs_velocity,
            near_start,
            near_obstacles,
            lim,
            dt,
            target,
        )
        zx, zy, zz = zone_repulsion(
            i, pos, speed, direction, zones, zone_start, near_zones, lim, dt
        )
        ox, oy, oz = ox + zx, oy + zy, oz + zz
        room = room and zx == 0.0 and zy == 0.0 and zz == 0.0
        px, py, pz, mate, hold_course = teammate_conflicts(
            i,
            0.0,
            0.0,
            0.0,
            fx,
            fy,
            fz,
            pos,
            speed,
            trig,
            mate_start,
            mates,
            formed,
            own_reach,
            lim,
            dt,
        )
        rx, ry, rz, ox, oy, oz = teammates_first(px, py, pz, mate, ox, oy, oz, room)
        repelled = rx != 0.0 or ry != 0.0 or rz != 0.0
        avoiding[i] = repelled
        # A leader passing static obstacles with its whole formation (``leader_keep_out_pad``)
        # turns and cruises as its formation follows.
        whole = (
            i == 0
            and lim.leader_keep_out_pad > 0.0
            and formation_turn
            and not (mate or moving_obstacle)
            and zx == 0.0
            and zy == 0.0
            and zz == 0.0
        )
        # The field (Eq. 15): the repulsion alone while repelled (Eq. 14: |F_g| = 0).
        if repelled:
            fx, fy, fz = rx, ry, rz
        elif hold_course:
            fx, fy, fz = direction[i, 0], direction[i, 1], direction[i, 2]
        # Trend matrix f (Eq. 16–20): pitch and yaw; speed (Eq. 21–24); kinematics (Eq. 3–5),
        # the leader following its target within ``leader_limits``.
        own_lim = leader_lim if i == 0 and not repelled else lim
        if repelled and whole:
            own_lim = passing_limits(leader_lim)
        f_pitch, f_yaw, along_field, s = steer(
            fx,
            fy,
            fz,
            rx,
            ry,
            rz,
            ox,
            oy,
            oz,
            moving_obstacle or mate,
            pos[i, 2],
            speed[i],
            pitch[i],
            yaw[i],
            cp,
            sp,
            cy,
            sy,
            own_lim,
            dt,
        )
        if i == 0 and not repelled and lim.leader_turn_rate < math.inf:  # eased turns
            heading_left = math.atan2(cy * fy - sy * fx, cy * fx + sy * fy)
            f_yaw = (
                formation_turn_rate(
                    f_yaw * own_lim.max_yaw_rate,
                    heading_left,
                    pos,
                    speed,
                    active,
                    local_target,
                    ux,
                    uy,
                    lim,
                    just_reaching(reaching, lim),
                )
                / own_lim.max_yaw_rate
            )
        slot_speed = speed[0]
        if i > 0 and active[0] and lim.leader_turn_rate < math.inf:  # a held turn
            slot_speed = slot_point_speed(
                speed[0],
                ux,
                uy,
                uz,
                turn_rate,
                local_target[i, 0] - pos[0, 0],
                local_target[i, 1] - pos[0, 1],
            )
        f_speed, state[i] = speed_trend(
            i,
            along_field,
            repelled and not whole,
            wait_speed,
            pos,
            speed,
            ax,
            ay,
            az,
            direction,
            formed,
            lim,
            dt,
            s,
            slot_speed,
            repelled and not mate and not moving_obstacle,
        )
        next_motion[i, 0], next_motion[i, 1], next_motion[i, 2] = kinematics(
            speed[i], pitch[i], yaw[i], f_speed, f_pitch, f_yaw, own_lim, dt
        )
    for i in range(pos.shape[0]):  # Eq. 5: every vehicle flies its new motion
        if active[i]:
            trig[i, 0], trig[i, 1], trig[i, 2], trig[i, 3] = fly(
                i, pos, pitch, yaw, speed, next_motion, dt
            )
    move_obstacles(obs_center, obs_velocity, dt)

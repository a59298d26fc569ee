"""Online planning: from the vehicles' telemetry to each vehicle's guided point and speed.

Pure: the service hands in the mission, the latest state of each vehicle (already in the
ICS) and the obstacles as they are now; this runs PPF forward from there and picks, for
each vehicle, a guided point ahead on its planned heading (see ``guidance``) and the speed
the plan asks for.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from gcs_ppf.frames import local_target_point
from gcs_ppf.geodesy import velocity_ned_to_enu
from gcs_ppf.guidance.airframe import OnlineLimits
from gcs_ppf.mission import Mission
from gcs_ppf.planning.planner import STATE_NAMES, Trajectory, advance
from gcs_ppf.planning.ppf.kernel import KernelLimits
from gcs_ppf.planning.scene import FloatArray, Obstacles, Scene, scene_from_mission, with_margins
from gcs_ppf.planning.turns import formation_turn_limits, held_speed_range
from gcs_ppf.planning.zones import Zones, zone_clearances


@dataclass(frozen=True)
class VehicleState:
    """A vehicle as the planner sees it: ICS position (m), flight-path pitch and yaw (rad,
    from the velocity, not the attitude: a real aircraft flies at an angle of attack)."""

    pos_m: tuple[float, float, float]
    pitch_rad: float
    yaw_rad: float
    speed_m_s: float
    yaw_rate_rad_s: float = 0.0
    """How fast its course turns (+: left), from the velocities it reports."""
    climb_rate_m_s: float | None = None
    """Its vertical speed (m/s, + up) as reported (the pitch may be from an average);
    None: the one the pitch gives."""
    course_ahead_rad: float = 0.0
    """How far the course it is planned from is ahead of the course it flies (rad, +: left;
    ``speed_reference.reference_course``): a leader's slots are laid out from the course
    it flies (``scene_now``)."""


def state_from_velocity(
    pos_m: tuple[float, float, float],
    vn_m_s: float,
    ve_m_s: float,
    vd_m_s: float,
    age_s: float = 0.0,
    turn_rate_rad_s: float = 0.0,
    flight_path_vd_m_s: float | None = None,
) -> VehicleState:
    """VehicleState from an ICS position and a NED velocity (GLOBAL_POSITION_INT), carried
    ``age_s`` seconds on along that velocity, turning at ``turn_rate_rad_s`` (+: left); its
    flight-path pitch from ``flight_path_vd_m_s`` (an averaged vertical speed) when given.

    Each vehicle's position arrives at its own moment within the stream's period; planned
    as if simultaneous, the formation's geometry is off by up to v × period (20 m at 200 m/s
    and 10 Hz), more than the target accuracy.  Carrying every position on to the tick's
    moment puts them at one instant.  A vehicle in a turn is carried on along its arc: a
    straight line from a 0.5 rad/s turn at 300 m/s is 75 m off after one second.
    """
    ve, vn, vu = velocity_ned_to_enu(vn_m_s, ve_m_s, vd_m_s)
    horizontal = math.hypot(ve, vn)
    x, y, z = pos_m
    yaw = math.atan2(vn, ve)
    turned = turn_rate_rad_s * age_s
    if abs(turned) < 1e-6:
        dx, dy = ve * age_s, vn * age_s
    else:
        r = horizontal / turn_rate_rad_s
        dx = r * (math.sin(yaw + turned) - math.sin(yaw))
        dy = r * (math.cos(yaw) - math.cos(yaw + turned))
    return VehicleState(
        pos_m=(x + dx, y + dy, z + vu * age_s),
        pitch_rad=math.atan2(vu if flight_path_vd_m_s is None else -flight_path_vd_m_s, horizontal),
        yaw_rad=math.atan2(math.sin(yaw + turned), math.cos(yaw + turned)),
        speed_m_s=math.sqrt(horizontal**2 + vu**2),
        yaw_rate_rad_s=turn_rate_rad_s,
        climb_rate_m_s=vu,
    )


@dataclass(frozen=True)
class Guidance:
    """What one planning tick decided, per vehicle in scene order (leader first).

    Two ways to fly it (``gcs_ppf.service.settings.Settings.guidance``): to the guided point, or on
    the course with the guided point's altitude, approached at the climb rate.
    """

    ids: list[int]
    guided_point_m: FloatArray  # [N,3] ICS; z is the planned altitude
    speed_m_s: FloatArray  # [N] planned speed lead_s on
    course_rad: FloatArray  # [N] ICS yaw to fly now
    turn_rate_rad_s: FloatArray  # [N] planned yaw rate there (+: left), for feed-forward
    climb_rate_m_s: FloatArray  # [N] vertical speed towards the altitude (inf: all it can)
    state: list[str]  # PPF state of the first planned step
    avoiding: list[bool]
    formed: list[bool]
    local_target_distance_m: list[float | None]  # None for the leader
    leader_arrives_within_lookahead: bool
    resolving: list[bool] = field(default_factory=list)  # vertical conflict resolution
    speed_ahead_m_s: FloatArray | None = None  # [N] planned speed speed_lead_s on
    speed_plan_t_s: FloatArray | None = None  # [K] 0 and the plan's record times
    speed_plan_m_s: FloatArray | None = None  # [K,N] the planned speeds then (the start's first)
    climb_plan_m_s: FloatArray | None = None  # [K,N] the planned vertical speeds then (+: up)
    course_plan_rad: FloatArray | None = None  # [K,N] the planned courses then (ICS yaw)
    leader_speed_range_m_s: tuple[float, float] | None = None  # every slot follows the turns


def scene_now(
    mission: Mission,
    states: dict[int, VehicleState],
    active_ids: set[int],
    obstacles: Obstacles,
    margin_m: float = 0.0,
    home_ground_m: float | None = None,
    envelope: OnlineLimits | None = None,
    teammate_margin_m: float | None = None,
) -> Scene:
    """The mission's scene with the vehicles where telemetry says they are.

    ``margin_m`` widens both safe distances: flown closed loop, an aircraft lags its plan
    (and the leader leaves PPF for its final approach), so the plan keeps a margin for it;
    ``teammate_margin_m``, when given, widens the teammates' one instead.
    The ground is the mission's, or else ``home_ground_m`` (ICS z of the ground under the
    vehicles' homes, see ``home_ground``): real aircraft do not fly in free space.
    ``envelope`` (``gcs_ppf.guidance.airframe.online_limits``, from the vehicles' parameters)
    tightens the speed range, the turn rate and the flight-path angles (pitch limits and
    TECS rates) to what the airframes fly.  A speed
    range that does not meet the mission's is the airframes' (they fly what they can).
    """
    teammates = margin_m if teammate_margin_m is None else teammate_margin_m
    base = with_margins(scene_from_mission(mission), margin_m, teammates)
    ground = mission.ground if mission.ground is not None else home_ground_m
    base = replace(
        base, limits=base.limits._replace(ground=-math.inf if ground is None else ground)
    )
    if envelope is not None:
        base = replace(base, limits=_within_envelope(base.limits, envelope))
        if mission.holds_turns:  # the turns the formation follows, in the airframes' range
            base = replace(base, limits=formation_turn_limits(base.limits, base.fleet.slot[1:]))
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
    leader = states.get(int(fleet.ids[0]))
    if leader is not None and leader.course_ahead_rad != 0.0:
        fleet = replace(fleet, slot=_slots_turned(fleet.slot, -leader.course_ahead_rad))
    return replace(base, fleet=fleet, obstacles=obstacles)


def _slots_turned(slot: FloatArray, angle_rad: float) -> FloatArray:
    """[N,3] the slots (leader's VCS) turned by ``angle_rad`` about its vertical (+: left):
    laid out from a leader planned ``-angle_rad`` ahead of the course it flies, they stand
    where the course flown puts them (Eq. 6, to first order in its pitch)."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    turned = slot.copy()
    turned[:, 0] = c * slot[:, 0] - s * slot[:, 1]
    turned[:, 1] = s * slot[:, 0] + c * slot[:, 1]
    return turned


def _within_envelope(lim: KernelLimits, env: OnlineLimits) -> KernelLimits:
    v_min = lim.v_min if env.v_min is None else max(lim.v_min, env.v_min)
    v_max = lim.v_max if env.v_max is None else min(lim.v_max, env.v_max)
    if v_min > v_max:  # the mission asks what the airframes cannot fly
        v_min = lim.v_min if env.v_min is None else env.v_min
        v_max = lim.v_max if env.v_max is None else env.v_max
        v_min = min(v_min, v_max)

    def tighter(a: float, b: float | None) -> float:
        return a if b is None else min(a, b)

    return lim._replace(
        v_min=v_min,
        v_max=v_max,
        max_yaw_rate=tighter(lim.max_yaw_rate, env.max_yaw_rate),
        max_climb_angle=tighter(lim.max_climb_angle, env.max_climb_angle),
        max_dive_angle=tighter(lim.max_dive_angle, env.max_dive_angle),
    )


def home_ground(heights: list[tuple[float, float]]) -> float | None:
    """ICS z of the ground from (ICS z, height above home) of each vehicle: the highest of
    their homes (ArduPlane's relative altitude is above home; the terrain is taken as flat
    there, which is what ArduPlane itself assumes without terrain data)."""
    return max((z - above_home for z, above_home in heights), default=None)


FINAL_APPROACH_TURN_RADII = 5.0  # within this many turn radii, with the target ahead …
FINAL_APPROACH_ANGLE = math.pi / 3  # … within this angle off the nose: fly at it
GO_AROUND_TURN_RADII = 3.0  # closer, with the target off to the side: fly away first


def leader_approach(scene: Scene) -> str:
    """How the leader closes on its target: ``"plan"`` (PPF), ``"final"`` (line of sight
    through the target, at its altitude) or ``"go_around"`` (straight on).

    Offline the leader meets its target on the first pass.  Flown closed loop it can pass
    it high or wide (the aircraft lags the plan), and PPF would then circle the target on
    the tightest turn for ever: the target sits inside the turn circle.  A fixed-wing pilot
    goes around: away to a few turn radii, then back in line, altitude settled meanwhile.
    """
    fleet = scene.fleet
    omega = min(scene.limits.max_pitch_rate, scene.limits.max_yaw_rate)
    turn_radius = fleet.speed[0] / omega
    to_target = scene.target - fleet.pos[0]
    distance = math.hypot(to_target[0], to_target[1])
    off_nose = abs(math.remainder(math.atan2(to_target[1], to_target[0]) - fleet.yaw[0], math.tau))
    if distance < FINAL_APPROACH_TURN_RADII * turn_radius and off_nose <= FINAL_APPROACH_ANGLE:
        return "final"
    if distance < GO_AROUND_TURN_RADII * turn_radius:
        return "go_around"
    return "plan"


def guidance(
    scene: Scene,
    *,
    lookahead_s: float,
    dt: float,
    carrot_m: float = 1500.0,
    lead_s: float = 0.5,
    climb_rate_floor_m_s: float = 1.0,
    turn_window_s: float = 0.5,
    speed_lead_s: float = 1.0,
    final_leg: bool = True,
) -> Guidance:
    """Run PPF ``lookahead_s`` ahead from ``scene`` and read off, for each vehicle, its speed,
    course and climb rate as planned ``lead_s`` on, its speed ``speed_lead_s`` on, and its
    guided point.

    The speed to command is the one ``speed_lead_s`` on (1 s, the autopilot's speed
    response): the planned change within ``lead_s`` can be smaller than the change worth
    commanding, so a plan replanned every tick from the measured speed would never be flown
    faster or slower; but the speed ``lookahead_s`` (3 s) on overshoots — flown on Table 2's
    level scene a wingman passed its slot by 180 m while the leader sped up (the formation
    formed in 2 of 4 runs; 4 of 4 at 1 s, worst wingman 2.4–8.0 m at best).  The service
    now plans each tick from the speeds the previous plan reached (``speed_plan_t_s``,
    ``speed_plan_m_s``; ``gcs_ppf.guidance.speed_reference``), so the plan's speed changes are
    flown whatever the deadband, and commands the plan's speed a quarter second on.

    The guided point is the planned position ``lookahead_s`` ahead carried ``carrot_m``
    further along the planned heading, at the planned altitude.  A fixed wing in GUIDED flies
    to its point and circles it once near (ArduPlane's loiter), so a point only a few seconds
    ahead would be circled; far out on the planned heading it steers the aircraft onto the
    plan instead, and the leader flies through its target rather than circling it.  Flown
    as course and altitude instead, the vehicle turns when the plan turns rather than when
    the direction to a far point does: pursuing the point, the formation never formed
    closed loop (the worst wingman came to 38.8–41.0 m of its slot at best); flying the
    course it forms (``tests/integration``).  The climb rate is the planned vertical speed
    plus ``climb_rate_floor_m_s``, so a level plan still corrects a small altitude error;
    the leader on its final approach or go-around climbs as it can.  The planned turn
    rate there is the yaw change over ``turn_window_s`` centred on it (the saturated sign
    of Eq. 19 can alternate between full and partial steps), 0 for the leader flying the
    line of sight or going around.
    """
    # A route's waypoint (``final_leg`` False) is flown through: the look-ahead does not
    # stop at it, and the leader has no final approach to it.
    run = advance(
        scene, dt, max(1, round(lookahead_s / dt)), goal_radius_m=None if final_leg else 0.0
    )
    tr = run.trajectory
    k_lead = _record_at(len(tr), lead_s, dt)
    aim = _planned_aim(scene, tr, k_lead, climb_rate_floor_m_s, turn_window_s)
    climb_plan = np.concatenate(
        [scene.fleet.speed[None] * np.sin(scene.fleet.pitch[None]), tr.speed * np.sin(tr.pitch)]
    )
    sighted = _leader_closes(scene, aim, run.arrived) if final_leg else None
    if sighted is not None:  # on the line of sight, the leader climbs along it
        climb_plan[:, 0] = sighted
        aim.climb_rate_m_s[0] = abs(sighted) + climb_rate_floor_m_s
    return Guidance(
        ids=scene.fleet.ids.tolist(),
        guided_point_m=_guided_points(scene, aim, carrot_m),
        speed_m_s=tr.speed[k_lead].copy(),
        course_rad=aim.course_rad,
        turn_rate_rad_s=aim.turn_rate_rad_s,
        climb_rate_m_s=aim.climb_rate_m_s,
        state=[STATE_NAMES[int(s)] for s in tr.state[0]],
        avoiding=[bool(a) for a in tr.avoiding[0]],
        formed=[bool(f) for f in tr.formed[0]],
        local_target_distance_m=[None, *_slot_distances_m(scene)],
        leader_arrives_within_lookahead=run.arrived,
        speed_ahead_m_s=tr.speed[_record_at(len(tr), speed_lead_s, dt)].copy(),
        speed_plan_t_s=np.concatenate([[0.0], tr.t]),
        speed_plan_m_s=np.concatenate([scene.fleet.speed[None], tr.speed]),
        climb_plan_m_s=climb_plan,
        course_plan_rad=np.concatenate([scene.fleet.yaw[None], tr.yaw]),
        leader_speed_range_m_s=held_speed_range(scene.fleet.slot[1:], scene.limits),
    )


@dataclass
class _Aim:
    """What ``guidance`` reads off the plan for each vehicle [N] (ICS), before the leader's
    final approach or go-around replaces its own."""

    ahead_m: FloatArray  # [N,3] planned position lookahead_s on
    yaw_rad: FloatArray  # [N] planned heading lookahead_s on: the guided point's bearing
    course_rad: FloatArray  # [N] planned heading lead_s on
    climb_rate_m_s: FloatArray  # [N]
    turn_rate_rad_s: FloatArray  # [N]


def _record_at(n_records: int, t_s: float, dt: float) -> int:
    """The plan's record ``t_s`` on (record k is after step k + 1), within the plan."""
    return min(n_records - 1, max(0, round(t_s / dt) - 1))


def _planned_aim(
    scene: Scene, tr: Trajectory, k_lead: int, climb_rate_floor_m_s: float, turn_window_s: float
) -> _Aim:
    """Position and heading at the plan's end; course, climb rate (the planned vertical
    speed plus ``climb_rate_floor_m_s``) and turn rate at record ``k_lead``."""
    return _Aim(
        ahead_m=tr.pos[-1].copy(),
        yaw_rad=tr.yaw[-1].copy(),
        course_rad=tr.yaw[k_lead].copy(),
        climb_rate_m_s=np.abs(tr.speed[k_lead] * np.sin(tr.pitch[k_lead])) + climb_rate_floor_m_s,
        turn_rate_rad_s=planned_turn_rate(scene.fleet.yaw, tr.t, tr.yaw, k_lead, turn_window_s),
    )


def _leader_closes(scene: Scene, aim: _Aim, arrived: bool) -> float | None:
    """The leader's aim replaced (in place) on its final approach (``leader_approach``), or
    when the plan arrives: through the target on the line of sight, returning the vertical
    speed along it; on a go-around: straight on at the target's altitude, climbing as it
    can (None).  Either way it does not turn.

    Climbing as it can on the final approach too, the leader swung from the plan's 35° to
    46° in the last 8 s of Table 2 and its slots, in its climbing frame, swung 30–90 m
    away from the wingmen flying the plan's climb."""
    fleet = scene.fleet
    approach = leader_approach(scene)
    sighted: float | None = None
    if arrived or approach == "final":  # through the target, on the line of sight
        aim.ahead_m[0] = scene.target
        to_target = scene.target - fleet.pos[0]
        aim.yaw_rad[0] = aim.course_rad[0] = math.atan2(to_target[1], to_target[0])
        distance = float(np.linalg.norm(to_target))
        sighted = 0.0 if distance == 0.0 else float(fleet.speed[0] * to_target[2] / distance)
    elif approach == "go_around":  # straight on at the target's altitude, then come back
        aim.ahead_m[0] = (fleet.pos[0, 0], fleet.pos[0, 1], scene.target[2])
        aim.yaw_rad[0] = aim.course_rad[0] = fleet.yaw[0]
    else:
        return None
    aim.climb_rate_m_s[0] = math.inf
    aim.turn_rate_rad_s[0] = 0.0
    return sighted


def _guided_points(scene: Scene, aim: _Aim, carrot_m: float) -> FloatArray:
    """[N,3] each aim carried ``carrot_m`` on along its heading; an inactive vehicle's is
    where it is."""
    yaw = aim.yaw_rad
    heading = np.stack([np.cos(yaw), np.sin(yaw), np.zeros_like(yaw)], axis=1)
    guided = aim.ahead_m + carrot_m * heading
    fleet = scene.fleet
    guided[~fleet.active] = fleet.pos[~fleet.active]
    return guided


def _slot_distances_m(scene: Scene) -> list[float]:
    """Each wingman's distance from its slot behind the leader now (its local target).

    By ``math.dist``, the same to the bit on every machine: numpy's norm sums by the SIMD
    the processor has, and the recorded ticks' plans (``tests/data/ticks``) differed in
    the last bit on a processor without AVX-512."""
    fleet = scene.fleet
    return [
        math.dist(
            local_target_point(
                fleet.pos[0], float(fleet.pitch[0]), float(fleet.yaw[0]), fleet.slot[i]
            ).tolist(),
            fleet.pos[i].tolist(),
        )
        for i in range(1, len(fleet.ids))
    ]


_WARM_UP_MISSION = {
    "target": [3000.0, 0.0, 300.0],
    "vehicles": [
        {"id": 1, "role": "leader", "position": [0.0, 0.0, 300.0], "pitch": 0.0, "yaw": 0.0},
        {
            "id": 2,
            "role": "wingman",
            "position": [0.0, -300.0, 300.0],
            "pitch": 0.0,
            "yaw": 0.0,
            "slot": [-300.0, -300.0, 0.0],
        },
    ],
    "obstacles": [{"center": [1500.0, 800.0, 300.0], "radius": 200.0}],
}


def warm_up(dt: float) -> None:
    """Load the planner's compiled kernel (numba's cache, or compile it) with the types a
    tick plans with, so that no run's first tick pays for it: measured on this repository's
    2-core machine the first ``guidance`` call took 0.33 s idle and ~0.7 s busy, while every
    vehicle flew on its launch commands (6.5 s of vehicle time at a SITL's 10×) and the
    telemetry queued behind it."""
    mission = Mission.model_validate(_WARM_UP_MISSION)
    base = scene_from_mission(mission)
    states = {
        int(vid): VehicleState(tuple(base.fleet.pos[i]), 0.0, 0.0, 150.0)
        for i, vid in enumerate(base.fleet.ids)
    }
    scene = scene_now(mission, states, set(states), base.obstacles, 100.0, 0.0)
    guidance(scene, lookahead_s=10 * dt, dt=dt)


def planned_turn_rate(
    yaw0: FloatArray, t: FloatArray, yaw: FloatArray, k: int, window_s: float
) -> FloatArray:
    """Yaw rate [N] (rad/s) of a plan around its record ``k``: the wrapped yaw change over
    ``window_s`` centred there (clipped to the plan, whose records ``t`` [K], ``yaw`` [K,N]
    follow the start ``yaw0`` [N] at t = 0; records after the leader's arrival repeat its
    time: a window without a time span has no turn)."""
    times = np.concatenate([[0.0], t])
    yaws = np.concatenate([yaw0[None], yaw])
    j = k + 1  # record k is after step k + 1
    half = window_s / 2.0 + 1e-9  # the records' own times count in
    lo = int(np.searchsorted(times, times[j] - half, side="left"))
    hi = int(np.searchsorted(times, times[j] + half, side="right")) - 1
    lo, hi = max(0, min(lo, j)), min(len(times) - 1, max(hi, j))
    if times[hi] <= times[lo]:
        return np.zeros_like(yaw0)
    change = np.remainder(yaws[hi] - yaws[lo] + np.pi, 2.0 * np.pi) - np.pi
    out: FloatArray = change / (times[hi] - times[lo])
    return out


def separations(positions: FloatArray) -> float | None:
    """Smallest centre-to-centre distance among the given [N,3] positions."""
    n = positions.shape[0]
    if n < 2:
        return None
    gaps = np.linalg.norm(positions[:, None] - positions[None], axis=-1)
    gaps[np.arange(n), np.arange(n)] = np.inf
    return float(gaps.min())


def clearance(
    positions: FloatArray, obstacles: Obstacles, zones: Zones | None = None
) -> float | None:
    """Smallest distance from the given positions to any obstacle surface, or any zone's
    (``zones``: on its free side; negative inside an exclusion zone or outside an
    inclusion zone); None: nothing to be clear of."""
    found = [d for _, d in nearest_keep_outs(positions, obstacles, zones) if d is not None]
    return min(found) if found else None


def nearest_keep_outs(
    positions: FloatArray, obstacles: Obstacles, zones: Zones | None = None
) -> list[tuple[str | None, float | None]]:
    """For each position ([N,3]) the keep-out nearest to it, as the mission document
    lists it (``"obstacles[j]"`` or ``"zones[k]"``, 0-based; the offline metrics'
    ``nearest_keep_out``), and the distance to its surface (as ``clearance``); (None,
    None): nothing to be clear of."""
    n = positions.shape[0]
    best = np.full(n, np.inf)
    names: list[str | None] = [None] * n
    if obstacles.radius.shape[0]:
        d = np.linalg.norm(positions[:, None] - obstacles.center[None], axis=-1) - obstacles.radius
        best = d.min(axis=1)
        names = [f"obstacles[{j}]" for j in d.argmin(axis=1).tolist()]
    if zones is not None and len(zones):
        z = zone_clearances(positions, zones)
        nearer = z.min(axis=1) < best
        for i in np.flatnonzero(nearer).tolist():
            names[i] = f"zones[{int(z[i].argmin())}]"
        best = np.minimum(best, z.min(axis=1))
    return [
        (name, None if math.isinf(d) else float(d))
        for name, d in zip(names, best.tolist(), strict=True)
    ]

"""One tick's plan, pure: the envelope the fleet flies in now, the online scene, the PPF
guidance and the separation guard's resolutions, with margins for the lag the tick measured.

The service (``gcs_ppf.service.flight``) gathers the states and sends the commands; this is what
it decides in between, with no I/O and no clock.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from gcs_ppf.guidance import separation_guard
from gcs_ppf.guidance.airframe import Airframe, guard_tuning, tick_envelope
from gcs_ppf.guidance.online import Guidance, VehicleState, guidance, scene_now
from gcs_ppf.guidance.speed_reference import follows_speed_plan
from gcs_ppf.mission import Mission
from gcs_ppf.planning.route import Leg, leader_target
from gcs_ppf.planning.scene import Obstacles


def formation_tolerance(mission: Mission) -> float:
    """``separation_guard.formation_tolerance_m`` of the mission's slots."""
    slots = tuple(tuple(v.slot) for v in mission.vehicles if v.slot is not None)
    return _formation_tolerance(slots, mission.limits.safe_distance_uav)


@functools.lru_cache(maxsize=8)
def _formation_tolerance(slots: tuple[tuple[float, ...], ...], safe_distance_m: float) -> float:
    """Once a mission, not twice a tick: every pair of slots (2 × 1.6 ms a tick at 250)."""
    points = np.array(slots, dtype=float).reshape(-1, 3)
    return separation_guard.formation_tolerance_m(points, safe_distance_m)


def in_formation(g: Guidance, tolerance_m: float) -> list[bool]:
    """The leader, and each wingman within ``tolerance_m`` of its local target point."""
    return [
        i == 0 or (d is not None and d <= tolerance_m)
        for i, d in enumerate(g.local_target_distance_m)
    ]


def traffic_radius_m(mission: Mission) -> float:
    """The radius of a sphere standing for an uncontrolled vehicle: its keep-out (radius +
    safe_distance_obstacle) is then the teammates' safe distance (at least the vehicle)."""
    lim = mission.limits
    return max(lim.safe_distance_uav - lim.safe_distance_obstacle, lim.collision_radius)


@dataclass(frozen=True)
class Tuning:
    """The service settings the plan depends on (``gcs_ppf.service.settings.Settings``)."""

    lookahead_s: float
    planner_dt_s: float
    carrot_m: float
    planning_margin_m: float | None
    guard_horizon_s: float | None
    guard_margin_m: float | None
    guard_resolution_m: float | None

    @classmethod
    def of(cls, settings: Any) -> Tuning:
        return cls(**{f.name: getattr(settings, f.name) for f in fields(cls)})


def teammate_margin_m(mission: Mission, planning_margin_m: float) -> float:
    """The planning margin on the teammates' safe distance: none where the vehicles fly
    the plan's speed changes (ArduPlane's scale, ``speed_reference.follows_speed_plan``),
    the whole margin elsewhere.

    At ArduPlane's scale the margin (v_max × the response lag, 40–60 m at 28 m/s) put a
    line-abreast formation's slots, 141 m apart, inside each neighbour's conflict band
    (Eq. 12–13 with the turning allowance): on real ArduPlane the wingmen never came
    nearer their slots than 20–38 m (session 5), and offline with the margin added to the
    safe distances neither line-abreast mission formed (172–178 s of flight; with 10 m or
    less on the teammates' they form at 15.1 s and 29.6 s).  Teammates lag their plans
    alike, and their separation closed loop is kept by the run-time assurance (their
    predicted response) and the separation guard (its own speed × lag margin); obstacles
    keep the whole margin.  At the paper's speeds the margin stays on both, as the
    campaigns measured it, but never more than a quarter of what the closest two slots have
    beyond twice the safe distance: two wingmen joining them count each other a conflict
    within the safe distance and the margin, and as much again for a turn (Eq. 12–13 with
    the turning allowance).  Table 3's slots are 141 m from the leader and from each other:
    with the whole 100 m on its 50 m no wingman could ever be planned into its slot, and
    with half of what they have beyond the safe distance (45.7 m) neither Table 3 nor a grid
    of slots 150 m apart formed, planned as the closed loop plans them
    (``gcs_ppf.offline.margin_effect``); with 10.4 m and 12.5 m both do."""
    lim = mission.limits
    if follows_speed_plan(lim.accel, lim.decel):
        return 0.0
    beyond_twice = 2.0 * formation_tolerance(mission) - lim.safe_distance_uav
    return min(planning_margin_m, max(0.0, beyond_twice / 4.0))


def plan(
    mission: Mission,
    states: dict[int, VehicleState],
    active: set[int],
    obstacles: Obstacles,
    ground_z_m: float | None,
    airframes: dict[int, Airframe],
    tuning: Tuning,
    lagging_s: float,
    previous: Guidance | None,
    leg: Leg | None = None,
) -> tuple[Guidance, list[Airframe]]:
    """The guidance for the ``active`` vehicles, and their airframes in its order, the
    leader flying the route's ``leg`` (None: straight to the target; a leg that ends in a
    loiter, round its circle; by its turn point, if it has one: ``route.leader_target``).

    ``lagging_s`` (the telemetry interval and the measured lag, vehicle seconds) is what the
    planning margin and the guard's margins must cover (``gcs_ppf.guidance.airframe``)."""
    lim = mission.limits
    envelope = tick_envelope(
        list(airframes.values()),
        [states[i].speed_m_s for i in active],
        lim.v_min,
        lim.v_max,
        lim.accel,
        tuning.lookahead_s,
        lagging_s,
        tuning.planning_margin_m,
    )
    margin = envelope.planning_margin_m
    scene = scene_now(
        mission,
        states,
        active,
        obstacles,
        margin,
        ground_z_m,
        envelope=envelope.limits,
        teammate_margin_m=teammate_margin_m(mission, margin),
    )
    if leg is not None:
        leader = states.get(mission.leader.id)
        position = None if leader is None else np.array(leader.pos_m, dtype=float)
        scene = replace(scene, target=leader_target(leg, position))
    g = guidance(
        scene,
        lookahead_s=tuning.lookahead_s,
        dt=tuning.planner_dt_s,
        carrot_m=tuning.carrot_m,
        final_leg=leg is None or (leg.final and leg.turn_point_m is None),
    )
    ordered = [airframes.get(vid, Airframe()) for vid in g.ids]
    if tuning.guard_horizon_s == 0.0:
        return g, ordered
    guard = guard_tuning(
        ordered,
        scene.fleet.speed.tolist(),
        lim.safe_distance_uav,
        lagging_s,
        horizon_s=tuning.guard_horizon_s,
        margin_m=tuning.guard_margin_m,
        resolution_m=tuning.guard_resolution_m,
    )
    points, resolving = separation_guard.resolve(
        scene,
        g.guided_point_m,
        distance_m=lim.safe_distance_uav + guard.margin_m,
        horizon_s=guard.horizon_s,
        resolution_m=guard.resolution_up_m,
        resolution_down_m=guard.resolution_down_m,
        release_m=guard.margin_m,
        previous=previous.resolving if previous is not None else None,
        in_formation=in_formation(g, formation_tolerance(mission)),
    )
    return replace(g, guided_point_m=points, resolving=resolving), ordered

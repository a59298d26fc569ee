"""Random scenes of a family, drawn from a seed, each one reproducible on its own.

One generator, ``mission_document``, draws a scene of a ``SceneSpec`` through ``Draws``: a
number in a range, a count in a range, and ``require``, a condition the scene must meet or
be drawn again. Sweeps draw from numpy (``draw_scene``): scene ``index`` of seed ``seed``
has its own stream, the ``index``-th child of ``SeedSequence(seed)``, so it is the same
scene whichever worker draws it and however many scenes the sweep has. The property tests
draw the same families through hypothesis (``tests/property/scenes.py``), which shrinks a
failing scene to a simple one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np
from pydantic import TypeAdapter, ValidationError

from gcs_ppf.mission import (
    Limits,
    Mission,
    Origin,
    Zone,
    describe_validation_error,
    zone_clearance,
    zone_footprint,
)
from gcs_ppf.offline.sweep.spec import Box, SceneSpec, pull_up_margin_m
from gcs_ppf.planning.ppf.primitives import influence_radius

Point = tuple[float, float, float]
INFLUENCE_MARGIN_M = 30.0
"""Added to an obstacle's influence radius at v_max where scenes keep starts, the target and
other obstacles out of it: a few steps of travel at v_max, rounded up."""
MAX_ATTEMPTS = 1000
ZONE = TypeAdapter[Zone](Zone)
ICS_ORIGIN = Origin(lat=0.0, lon=0.0, alt=0.0)
"""(The footprints of zones drawn in the ICS do not depend on the origin.)"""
"""Draws of one scene before a family is declared unable to make it."""


class Draws(Protocol):
    """Where a scene's random numbers come from."""

    def uniform(self, low: float, high: float) -> float:
        """A number in [low, high]."""
        ...

    def integer(self, low: int, high: int) -> int:
        """A count in [low, high], both included."""
        ...

    def require(self, condition: bool) -> None:
        """Give up this scene unless ``condition`` holds (it is drawn again)."""
        ...


class Rejected(Exception):
    """The numbers drawn so far make no scene of the family: draw it again."""


class SceneError(ValueError):
    """A family that cannot make a scene (its ranges leave no room for one)."""


class GeneratorDraws:
    """``Draws`` from a numpy ``Generator``; ``require`` rejects the scene."""

    def __init__(self, rng: np.random.Generator) -> None:
        self._rng = rng

    def uniform(self, low: float, high: float) -> float:
        return float(self._rng.uniform(low, high))

    def integer(self, low: int, high: int) -> int:
        return int(self._rng.integers(low, high, endpoint=True))

    def require(self, condition: bool) -> None:
        if not condition:
            raise Rejected


def scene_rng(seed: int, index: int) -> np.random.Generator:
    """The stream of scene ``index`` of the sweep seeded ``seed``: the same as
    ``SeedSequence(seed).spawn(n)[index]`` for any n > index."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(index,)))


def influence_at_v_max(limits: Limits, radius_m: float) -> float:
    """How far from an obstacle's centre a vehicle at v_max starts to avoid it (the planner's
    influence radius, CONVENTIONS §2 erratum 4), plus ``INFLUENCE_MARGIN_M``."""
    omega = min(limits.max_pitch_rate, limits.max_yaw_rate)
    keep_out = radius_m + limits.safe_distance_obstacle
    return float(influence_radius(limits.v_max, omega, keep_out)) + INFLUENCE_MARGIN_M


def zone_influence_at_v_max(limits: Limits, dt: float) -> float:
    """How far from a zone's surface a vehicle at v_max starts to avoid it (the planner's
    ``surface_influence_radius`` and a few steps of travel)."""
    omega = min(limits.max_pitch_rate, limits.max_yaw_rate)
    return limits.v_max / omega + limits.safe_distance_obstacle + 3.0 * limits.v_max * dt


def v_slots(wingmen: int, spacing_m: float) -> list[Point]:
    """Slots of a V behind the leader (leader's VCS), in rows of two, left first."""
    slots = []
    for k in range(wingmen):
        row, side = divmod(k, 2)
        slots.append(
            (-spacing_m * (row + 1), spacing_m * (row + 1) * (1 if side == 0 else -1), 0.0)
        )
    return slots


def _point(draws: Draws, box: Box) -> Point:
    (cx, cy, cz), (hx, hy, hz) = box.center_m, box.half_size_m
    return (
        draws.uniform(-hx, hx) + cx,
        draws.uniform(-hy, hy) + cy,
        draws.uniform(-hz, hz) + cz,
    )


def _obstacles(
    draws: Draws, spec: SceneSpec, count: tuple[int, int], keep_clear: Sequence[Point]
) -> list[dict[str, Any]]:
    """Obstacles of ``spec`` whose influence sphere at v_max holds none of ``keep_clear``
    and, with ``placement = "apart"``, overlaps no other's (those are left out)."""
    apart = spec.obstacles.placement == "apart"
    placed: list[dict[str, Any]] = []
    for _ in range(draws.integer(*count)):
        centre = _point(draws, spec.obstacles.box)
        radius = draws.uniform(*spec.obstacles.radius_m)
        reach = influence_at_v_max(spec.limits, radius)
        if any(math.dist(centre, p) < reach for p in keep_clear):
            continue
        if apart and any(
            math.dist(centre, o["center"]) < reach + influence_at_v_max(spec.limits, o["radius"])
            for o in placed
        ):
            continue
        placed.append({"center": centre, "radius": radius})
    return placed


def _u_shape(cx: float, cy: float, half: float, heading: float) -> list[list[float]]:
    """A U of ``half`` metres' half-width about (cx, cy), its opening towards ``heading``
    (rad), its walls a fifth of its width thick."""
    t = 0.4 * half
    local = [
        (-half, -half),
        (half, -half),
        (half, -half + t),
        (-half + t, -half + t),
        (-half + t, half - t),
        (half, half - t),
        (half, half),
        (-half, half),
    ]
    c, s = math.cos(heading), math.sin(heading)
    return [[cx + u * c - v * s, cy + u * s + v * c] for u, v in local]


def _zones(
    draws: Draws,
    spec: SceneSpec,
    spheres: Sequence[dict[str, Any]],
    leader_start: Point,
    keep_clear: Sequence[Point],
) -> list[dict[str, Any]]:
    """Each sphere turned into a zone inside it (``ZoneSpec``); the scene is drawn again
    unless every point of ``keep_clear`` lies outside each zone's influence at v_max and
    the zones' influence regions are apart."""
    assert spec.zones is not None
    zones: list[dict[str, Any]] = []
    for o in spheres:
        half = o["radius"] / math.sqrt(2.0)  # a cylinder this wide fits in the sphere
        cx, cy, cz = o["center"]
        band = {"floor": cz - half, "ceiling": cz + half}
        if spec.zones.shape == "pocket":
            heading = math.atan2(leader_start[1] - cy, leader_start[0] - cx)
            zones.append({"kind": "polygon", "vertices": _u_shape(cx, cy, half, heading), **band})
        elif draws.integer(0, 1):
            zones.append({"kind": "cylinder", "center": [cx, cy], "radius": half, **band})
        else:
            gaps = [draws.uniform(0.5, 1.0) for _ in range(draws.integer(3, 8))]
            total, angle, vertices = sum(gaps), 0.0, []
            for g in gaps:
                r = half * draws.uniform(0.6, 1.0)
                vertices.append([cx + r * math.cos(angle), cy + r * math.sin(angle)])
                angle += 2.0 * math.pi * g / total
            zones.append({"kind": "polygon", "vertices": vertices, **band})
    reach = zone_influence_at_v_max(spec.limits, spec.planner.dt)
    circles = []  # each footprint's centre and the radius round it that holds it
    for z in zones:
        model = ZONE.validate_python(z)
        footprint = zone_footprint(model, ICS_ORIGIN)
        draws.require(all(zone_clearance(model, footprint, p) > reach for p in keep_clear))
        if z["kind"] == "cylinder":
            circles.append((footprint[0], z["radius"]))
        else:
            centre = tuple(np.mean(footprint, axis=0))
            circles.append((centre, max(math.dist(centre, p) for p in footprint)))
    for a, (ca, ra) in enumerate(circles):
        for cb, rb in circles[:a]:
            draws.require(math.dist(ca, cb) - ra - rb > 2.0 * reach)
    return zones


def mission_document(spec: SceneSpec, draws: Draws) -> dict[str, Any]:
    """A random scene of ``spec`` as a mission document (CONVENTIONS §3).

    The order of the draws is part of the families' definition (the property tests'
    hypothesis strategies make the same draws in the same order, and a hypothesis seed
    gives the scenes it gave before the families moved here): wingmen, starts, target, slot
    spacing, apart obstacles (a count of none for overlapping ones), each vehicle's pitch,
    yaw and speed, the ground, overlapping obstacles, obstacle velocities, the zones that
    take the obstacles' places (``ZoneSpec``).
    """
    fleet, lim = spec.fleet, spec.limits
    wingmen = draws.integer(*fleet.wingmen)
    starts = [_point(draws, fleet.start_box) for _ in range(wingmen + 1)]
    for a in range(len(starts)):
        for b in range(a):
            draws.require(math.dist(starts[a], starts[b]) >= fleet.start_gap_m)
    target = _point(draws, spec.target_box)
    slots = v_slots(wingmen, draws.uniform(*fleet.slot_spacing_m))
    points = [*starts, target]
    apart = spec.obstacles.placement == "apart"  # else drawn after the fleet; here, none
    obstacles = _obstacles(draws, spec, spec.obstacles.count if apart else (0, 0), points)
    vehicles = [
        {
            "id": k + 1,
            "role": "leader" if k == 0 else "wingman",
            "position": starts[k],
            "pitch": draws.uniform(*fleet.pitch_rad),
            "yaw": draws.uniform(*fleet.yaw_rad),
            "speed": draws.uniform(*spec.initial_speed_m_s),
            **({"slot": slots[k - 1]} if k else {}),
        }
        for k in range(wingmen + 1)
    ]
    doc: dict[str, Any] = {
        "name": spec.name,
        "limits": lim.model_dump(),
        "planner": spec.planner.model_dump(),
        "target": target,
        "vehicles": vehicles,
        "obstacle_passage": spec.obstacle_passage,
    }
    if spec.ground is not None:
        lowest = min(p[2] for p in points)
        depth = draws.uniform(*spec.ground.depth_m)
        doc["ground"] = lowest - lim.safe_distance_obstacle - pull_up_margin_m(spec) - depth
    if not apart:
        obstacles = _obstacles(draws, spec, spec.obstacles.count, points)
    if spec.obstacles.speed_m_s[1] > 0.0:
        for o in obstacles:
            speed = draws.uniform(*spec.obstacles.speed_m_s)
            heading = draws.uniform(-math.pi, math.pi)
            o["velocity"] = (speed * math.cos(heading), speed * math.sin(heading), 0.0)
    doc["obstacles"] = obstacles
    if spec.zones is not None:
        doc["obstacles"], doc["zones"] = [], _zones(draws, spec, obstacles, starts[0], points)
    return doc


def draw_scene(spec: SceneSpec, seed: int, index: int) -> Mission:
    """Scene ``index`` of ``spec`` in the sweep seeded ``seed``, drawn again (from the same
    stream) until it is a valid mission, at most ``MAX_ATTEMPTS`` times."""
    draws = GeneratorDraws(scene_rng(seed, index))
    problem = ""
    for _ in range(MAX_ATTEMPTS):
        try:
            doc = mission_document(spec, draws)
        except Rejected:
            continue
        try:
            return Mission.model_validate({**doc, "name": f"{spec.name} {index} (seed {seed})"})
        except ValidationError as exc:
            problem = f": {describe_validation_error(exc)[0]}"
    raise SceneError(
        f"{spec.name}: no valid scene in {MAX_ATTEMPTS} draws (seed {seed}, scene {index}){problem}"
    )

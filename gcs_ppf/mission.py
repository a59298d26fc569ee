"""The mission document (CONVENTIONS §3), validated at the boundary.

One document describes a formation mission: the geodetic origin of the local ENU frame
(the paper's ICS), the performance envelope (Table 1 of the paper as defaults), the planner
settings, the leader's target and the vehicles with their formation slots, and spherical
obstacles that may move at constant velocity.  All coordinates are ICS metres relative to
``origin``; all angles radians; all speeds m/s.

Every error names the field it is about, e.g. ``vehicles[2].slot``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    model_validator,
)

Vec3 = tuple[float, float, float]
Vec2 = tuple[float, float]
PositiveFloat = Annotated[float, Field(gt=0.0)]

FloatArray = NDArray[np.float64]


class _Strict(BaseModel):
    """Base of every mission model: unknown keys and non-finite numbers are errors."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)


class Origin(_Strict):
    """Geodetic origin of the local ENU frame (WGS-84, degrees and metres AMSL)."""

    lat: float = Field(ge=-90.0, le=90.0)
    lon: float = Field(ge=-180.0, le=180.0)
    alt: float = 0.0


class Limits(_Strict):
    """Performance envelope of the vehicles; the defaults are Table 1 of the paper.

    ``max_pitch_rate`` and ``max_yaw_rate`` are the maximum angular velocities ω_max
    (Table 1 prints them under a_θ, a_ψ: CONVENTIONS §2 erratum 5).
    """

    collision_radius: PositiveFloat = 25.0
    v_init: PositiveFloat = 100.0
    v_min: PositiveFloat = 100.0
    v_max: PositiveFloat = 300.0
    accel: PositiveFloat = 10.0
    decel: PositiveFloat = 40.0
    max_pitch_rate: PositiveFloat = math.pi / 6
    max_yaw_rate: PositiveFloat = math.pi / 6
    target_accuracy: PositiveFloat = 10.0
    safe_distance_uav: PositiveFloat = 50.0
    safe_distance_obstacle: PositiveFloat = 25.0

    @model_validator(mode="after")
    def _consistent(self) -> Limits:
        if self.v_min > self.v_max:
            raise ValueError("limits.v_min: must not exceed limits.v_max")
        if not self.v_min <= self.v_init <= self.v_max:
            raise ValueError("limits.v_init: must lie in [limits.v_min, limits.v_max]")
        if self.safe_distance_uav < 2 * self.collision_radius:
            raise ValueError(
                "limits.safe_distance_uav: must be at least 2 × limits.collision_radius"
            )
        if self.safe_distance_obstacle < self.collision_radius:
            raise ValueError(
                "limits.safe_distance_obstacle: must be at least limits.collision_radius"
            )
        return self


class PlannerSettings(_Strict):
    """Which method plans, with which time step Δt, for at most how long (seconds)."""

    method: Literal["ppf", "apf"] = "ppf"
    dt: float = Field(default=0.01, gt=0.0, le=1.0)
    max_time: float = Field(default=300.0, gt=0.0, le=36_000.0)


class Vehicle(_Strict):
    """One fixed-wing vehicle; ``id`` is also its MAVLink system id (1–254)."""

    id: int = Field(ge=1, le=254)
    role: Literal["leader", "wingman"]
    position: Vec3
    pitch: float = Field(default=0.0, ge=-math.pi / 2, le=math.pi / 2)
    yaw: float = Field(default=0.0, ge=-math.pi, le=math.pi)
    speed: float | None = Field(default=None, gt=0.0)
    slot: Vec3 | None = None
    priority: int | None = None


class Obstacle(_Strict):
    """A spherical obstacle (no-fly volume), optionally moving at constant velocity."""

    center: Vec3
    radius: PositiveFloat
    velocity: Vec3 = (0.0, 0.0, 0.0)


class _ZoneBase(_Strict):
    """What every zone kind has: a height band and whether it keeps vehicles out or in."""

    name: str | None = Field(default=None, max_length=200)
    floor: float | None = None
    """ICS z (m) of the zone's bottom; None: unbounded below (down to the ground)."""
    ceiling: float | None = None
    """ICS z (m) of its top; None: unbounded above (nothing flies over it)."""
    inclusion: bool = False
    """False (default): an exclusion zone (no-fly); True: vehicles stay inside it."""

    @model_validator(mode="after")
    def _band(self) -> _ZoneBase:
        if self.floor is not None and self.ceiling is not None and self.floor >= self.ceiling:
            raise ValueError("ceiling: must lie above floor")
        return self


class CylinderZone(_ZoneBase):
    """A vertical cylinder: a circle (ICS ``center`` or ``center_latlon``) with a height band."""

    kind: Literal["cylinder"]
    center: Vec2 | None = None
    """ICS (x, y) m of its axis."""
    center_latlon: Vec2 | None = None
    """(lat, lon) degrees of its axis, instead of ``center``."""
    radius: PositiveFloat

    @model_validator(mode="after")
    def _one_center(self) -> CylinderZone:
        if (self.center is None) == (self.center_latlon is None):
            raise ValueError("center: give exactly one of center and center_latlon")
        if self.center_latlon is not None:
            _check_latlon(self.center_latlon, "center_latlon")
        return self


class PolygonZone(_ZoneBase):
    """An extruded polygon: a simple polygon (convex or not; ICS ``vertices`` or
    ``vertices_latlon``, either winding, not closed: the last vertex joins the first)
    with a height band."""

    kind: Literal["polygon"]
    vertices: list[Vec2] | None = Field(default=None, min_length=3, max_length=10_000)
    """ICS (x, y) m of its corners."""
    vertices_latlon: list[Vec2] | None = Field(default=None, min_length=3, max_length=10_000)
    """(lat, lon) degrees of its corners, instead of ``vertices``."""

    @model_validator(mode="after")
    def _simple(self) -> PolygonZone:
        if (self.vertices is None) == (self.vertices_latlon is None):
            raise ValueError("vertices: give exactly one of vertices and vertices_latlon")
        field = "vertices" if self.vertices is not None else "vertices_latlon"
        points = self.vertices if self.vertices is not None else self.vertices_latlon
        assert points is not None
        if field == "vertices_latlon":
            for k, p in enumerate(points):
                _check_latlon(p, f"vertices_latlon[{k}]")
        problem = polygon_problem(points)
        if problem is not None:
            raise ValueError(f"{field}: {problem}")
        return self


Zone = Annotated[CylinderZone | PolygonZone, Field(discriminator="kind")]


def _check_latlon(p: Vec2, field: str) -> None:
    if not (-90.0 <= p[0] <= 90.0 and -180.0 <= p[1] <= 180.0):
        raise ValueError(f"{field}: latitude must lie in [-90, 90] and longitude in [-180, 180]")


def polygon_problem(points: Sequence[Vec2]) -> str | None:
    """Why ``points`` (a ring, not closed) is not a simple polygon, or None (shapely's
    validity: no self-intersection, no repeated or collinear-only rings, a non-zero area)."""
    from shapely import Polygon
    from shapely.validation import explain_validity

    ring = list(points)
    if len(ring) > 3 and ring[0] == ring[-1]:
        ring = ring[:-1]  # a closed ring is taken as given once
    if len(set(ring)) != len(ring):
        return "repeated vertex"
    shape = Polygon(ring)
    if not shape.is_valid:
        return f"not a simple polygon ({explain_validity(shape)})"
    if shape.area <= 0.0:
        return "zero area (collinear vertices)"
    return None


def zone_footprint(zone: CylinderZone | PolygonZone, origin: Origin) -> list[Vec2]:
    """A polygon zone's corners in ICS metres (x east, y north), or a cylinder's centre
    as the one point; lat/lon converted on WGS-84 about ``origin`` (pymap3d)."""
    import pymap3d

    if isinstance(zone, CylinderZone):
        if zone.center is not None:
            return [zone.center]
        points = [zone.center_latlon] if zone.center_latlon is not None else []
    else:
        if zone.vertices is not None:
            return list(zone.vertices)
        points = list(zone.vertices_latlon or [])
    out: list[Vec2] = []
    for lat, lon in points:
        e, n, _ = pymap3d.geodetic2enu(lat, lon, origin.alt, origin.lat, origin.lon, origin.alt)
        out.append((float(e), float(n)))
    return out


def zone_clearance(
    zone: CylinderZone | PolygonZone, footprint: Sequence[Vec2], point: Sequence[float]
) -> float:
    """Signed distance (m) from ``point`` (ICS) to the zone's surface, positive on its
    free side (outside an exclusion zone, inside an inclusion zone); ``footprint`` is
    ``zone_footprint``'s.  Computed by shapely, apart from the planner's compiled
    ``gcs_ppf.planning.zones`` (which the tests check against it)."""
    return float(zone_clearances_m(zone, footprint, np.asarray([point], dtype=float))[0])


def zone_clearances_m(
    zone: CylinderZone | PolygonZone, footprint: Sequence[Vec2], points: FloatArray
) -> FloatArray:
    """``zone_clearance`` of every point of ``points`` ([K,3], ICS), at once."""
    import shapely

    p = np.asarray(points, dtype=float).reshape(-1, 3)
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    if isinstance(zone, CylinderZone):
        cx, cy = footprint[0]
        dh = np.hypot(x - cx, y - cy) - zone.radius
    else:
        shape = shapely.Polygon(footprint)
        here = shapely.points(x, y)
        edge = np.asarray(shapely.distance(shape.exterior, here), dtype=float)
        dh = np.where(shapely.contains_xy(shape, x, y), -edge, edge)
    below = np.full(len(p), -np.inf) if zone.floor is None else zone.floor - z
    above = np.full(len(p), -np.inf) if zone.ceiling is None else z - zone.ceiling
    dz = np.maximum(below, above)
    outside = (dh > 0.0) | (dz > 0.0)
    d = np.where(outside, np.hypot(np.maximum(dh, 0.0), np.maximum(dz, 0.0)), np.maximum(dh, dz))
    out: FloatArray = -d if zone.inclusion else d
    return out


class Loiter(_Strict):
    """Circles the leader flies round a waypoint, its leg's end, before the next leg, as
    ArduPlane's ``MAV_CMD_NAV_LOITER_TURNS`` and ``_TIME``: ``turns`` whole circles or
    ``time_s`` seconds from coming onto the circle (one of the two), on a circle of
    ``radius_m`` about the waypoint at its altitude, clockwise seen from above unless
    ``clockwise`` is false (``gcs_ppf.planning.route``)."""

    radius_m: PositiveFloat
    turns: PositiveFloat | None = None
    time_s: PositiveFloat | None = None
    clockwise: bool = True

    @model_validator(mode="after")
    def _turns_or_time(self) -> Loiter:
        if (self.turns is None) == (self.time_s is None):
            raise ValueError("turns: give exactly one of turns and time_s")
        return self


class Waypoint(_Strict):
    """A point of the leader's route, reached when the leader passes within
    ``acceptance_radius`` of it or crosses the line through it square to the leg (as
    ArduPlane's WP_RADIUS and its finish line); with a ``loiter``, the leg ends once its
    circles are flown."""

    position: Vec3
    acceptance_radius: PositiveFloat = 100.0
    loiter: Loiter | None = None


def _distance(a: Sequence[float], b: Sequence[float]) -> float:
    return math.dist(a, b)


class Mission(_Strict):
    """A formation mission (CONVENTIONS §3)."""

    name: str = Field(default="mission", min_length=1, max_length=200)
    origin: Origin = Origin(lat=47.397742, lon=8.545594, alt=488.0)
    limits: Limits = Limits()
    planner: PlannerSettings = PlannerSettings()
    target: Vec3
    route: list[Waypoint] = Field(default_factory=list, max_length=1000)
    """The waypoints the leader flies through, in order, before ``target`` (the route's
    last point, reached within ``limits.target_accuracy``); empty: straight to the target."""
    turns: Literal["hold", "free"] | None = None
    """How the leader turns in formation: ``"hold"`` keeps its speed and turn rate to what
    every slot can follow (``gcs_ppf.planning.turns``); ``"free"`` is the paper's leader.
    None (default): ``"hold"`` on a route or passing obstacles as a formation
    (``obstacle_passage``), ``"free"`` otherwise."""
    formation_frame: Literal["leader", "course"] = "leader"
    """Where the wingmen make for while obstacles or zones repel the leader: ``"leader"``
    (default), their slots in its VCS (Eq. 6) as always; ``"course"``, the slots placed
    level along its way to its target, so that a short dodge of the leader's does not
    swing them round with it (``gcs_ppf.planning.ppf.kernel.formation_frame``).  The
    formation is judged in the leader's VCS either way."""
    obstacle_passage: Literal["each", "formation"] = "each"
    """How the formation passes obstacles: ``"each"`` (default), the paper's, every vehicle
    avoids on its own and the wingmen leave their slots where these pass too close;
    ``"formation"``, the leader keeps its farthest slot's distance more from every obstacle
    (unless its target lies within that), so that every slot keeps clear and the formation
    passes whole (``KernelLimits.leader_keep_out_pad``), turning round them as the
    formation follows (``turns`` defaults to ``"hold"``).  Zones keep the paper's way."""
    at_end: Literal["loiter", "rtl"] = "loiter"
    """What the formation does once the leader is at the target: ``"loiter"``, every vehicle
    holds on a circle clear of every keep-out, stacked above the target; ``"rtl"``, the same
    circles at levels over every keep-out, then each vehicle flies ArduPlane's RTL home at
    its level where the way there is clear (``gcs_ppf.guidance.failsafe.ways_home``), and
    holds where it is not."""
    ground: float | None = None
    """ICS z (metres) of flat ground that vehicles keep ``limits.safe_distance_obstacle``
    above; None (default) is the paper's free space.  The service falls back on the
    ground under the vehicles' homes (see ``gcs_ppf.guidance.online``)."""
    vehicles: list[Vehicle] = Field(min_length=1, max_length=1000)
    obstacles: list[Obstacle] = Field(default_factory=list, max_length=10_000)
    zones: list[Zone] = Field(default_factory=list, max_length=10_000)
    """No-fly (exclusion) and stay-inside (inclusion) zones: vertical cylinders and
    extruded polygons (``CylinderZone``, ``PolygonZone``); docs/zones.md."""

    @model_validator(mode="after")
    def _consistent(self) -> Mission:
        for problem in mission_problems(self):
            raise ValueError(problem)
        return self

    @property
    def leader(self) -> Vehicle:
        return next(v for v in self.vehicles if v.role == "leader")

    @property
    def wingmen(self) -> list[Vehicle]:
        return [v for v in self.vehicles if v.role == "wingman"]

    @property
    def holds_turns(self) -> bool:
        """Whether the leader turns as the formation can follow (``turns``)."""
        if self.turns is not None:
            return self.turns == "hold"
        return bool(self.route) or self.obstacle_passage == "formation"


def mission_problems(mission: Mission) -> list[str]:
    """Cross-field checks; each problem starts with the field it names."""
    problems: list[str] = []
    lim = mission.limits
    seen: dict[int, int] = {}
    for k, v in enumerate(mission.vehicles):
        if v.id in seen:
            problems.append(f"vehicles[{k}].id: duplicate id {v.id} (also vehicles[{seen[v.id]}])")
        seen.setdefault(v.id, k)
        if v.role == "wingman" and v.slot is None:
            problems.append(f"vehicles[{k}].slot: a wingman needs a slot")
        if v.role == "leader" and v.slot is not None:
            problems.append(f"vehicles[{k}].slot: the leader has no slot")
        if v.speed is not None and not lim.v_min <= v.speed <= lim.v_max:
            problems.append(f"vehicles[{k}].speed: must lie in [limits.v_min, limits.v_max]")
    leaders = [k for k, v in enumerate(mission.vehicles) if v.role == "leader"]
    if len(leaders) != 1:
        where = ", ".join(f"vehicles[{k}]" for k in leaders) or "none"
        problems.append(f"vehicles: exactly one leader is needed, found {len(leaders)} ({where})")

    for j, o in enumerate(mission.obstacles):
        keep_out = o.radius + lim.collision_radius
        for k, v in enumerate(mission.vehicles):
            if _distance(v.position, o.center) < keep_out:
                problems.append(
                    f"vehicles[{k}].position: inside obstacles[{j}] "
                    f"(closer than radius + collision_radius = {keep_out:g} m)"
                )
        if _distance(mission.target, o.center) < o.radius + lim.target_accuracy:
            problems.append(f"target: inside obstacles[{j}]")
        for w, wp in enumerate(mission.route):
            if _distance(wp.position, o.center) < o.radius + lim.safe_distance_obstacle:
                problems.append(
                    f"route[{w}].position: inside obstacles[{j}] "
                    f"(closer than radius + limits.safe_distance_obstacle)"
                )
    tightest_m = lim.v_min / min(lim.max_yaw_rate, lim.max_pitch_rate)
    for w, wp in enumerate(mission.route):
        if wp.loiter is not None and wp.loiter.radius_m < tightest_m:
            problems.append(
                f"route[{w}].loiter.radius_m: {wp.loiter.radius_m:g} m is tighter than the "
                f"leader turns at limits.v_min ({tightest_m:.1f} m)"
            )

    problems += _zone_problems(mission)

    if mission.ground is not None:
        for k, v in enumerate(mission.vehicles):
            if v.position[2] < mission.ground + lim.collision_radius:
                problems.append(
                    f"vehicles[{k}].position: below the ground + collision_radius "
                    f"({mission.ground + lim.collision_radius:g} m)"
                )
        for w, wp in enumerate(mission.route):
            if wp.position[2] < mission.ground + lim.safe_distance_obstacle:
                problems.append(
                    f"route[{w}].position: below the ground + limits.safe_distance_obstacle "
                    f"({mission.ground + lim.safe_distance_obstacle:g} m)"
                )
        if mission.target[2] < mission.ground + lim.safe_distance_obstacle:
            problems.append(
                f"target: below the ground + limits.safe_distance_obstacle "
                f"({mission.ground + lim.safe_distance_obstacle:g} m)"
            )

    # Slots are places in the leader's VCS; the leader itself sits at the VCS origin.
    slots = [((0.0, 0.0, 0.0), "the leader")] + [
        (v.slot, f"vehicles[{k}].slot")
        for k, v in enumerate(mission.vehicles)
        if v.role == "wingman" and v.slot is not None
    ]
    for a in range(1, len(slots)):
        for b in range(a):
            gap = _distance(slots[a][0], slots[b][0])
            if gap < lim.safe_distance_uav:
                problems.append(
                    f"{slots[a][1]}: {gap:g} m from {slots[b][1]}, closer than "
                    f"limits.safe_distance_uav = {lim.safe_distance_uav:g} m"
                )
    for k, v in enumerate(mission.vehicles):
        for m in range(k):
            gap = _distance(v.position, mission.vehicles[m].position)
            if gap < lim.safe_distance_uav:
                problems.append(
                    f"vehicles[{k}].position: {gap:g} m from vehicles[{m}], closer than "
                    f"limits.safe_distance_uav"
                )
    return problems


def _zone_problems(mission: Mission) -> list[str]:
    """Vehicles, the target and the route's waypoints on the free side of every zone."""
    lim = mission.limits
    problems: list[str] = []
    for j, zone in enumerate(mission.zones):
        footprint = zone_footprint(zone, mission.origin)
        where = "outside" if zone.inclusion else "inside"
        for k, v in enumerate(mission.vehicles):
            if zone_clearance(zone, footprint, v.position) < lim.collision_radius:
                problems.append(
                    f"vehicles[{k}].position: {where} zones[{j}] (or closer to its surface "
                    f"than collision_radius = {lim.collision_radius:g} m)"
                )
        if zone_clearance(zone, footprint, mission.target) < lim.target_accuracy:
            problems.append(f"target: {where} zones[{j}] (or within target_accuracy of it)")
        for w, wp in enumerate(mission.route):
            if zone_clearance(zone, footprint, wp.position) < lim.safe_distance_obstacle:
                problems.append(
                    f"route[{w}].position: {where} zones[{j}] "
                    f"(or closer to it than limits.safe_distance_obstacle)"
                )
    return problems


class MissionError(ValueError):
    """A mission document that cannot be used; ``field`` names the offending field."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


ZONE_KINDS = ("cylinder", "polygon")


def _field_path(loc: Sequence[int | str]) -> str:
    path = ""
    for k, part in enumerate(loc):
        if k >= 2 and loc[k - 2] == "zones" and part in ZONE_KINDS:
            continue  # the zone's kind (pydantic's tag of the union) is not a field
        path += f"[{part}]" if isinstance(part, int) else (f".{part}" if path else str(part))
    return path


def describe_validation_error(error: ValidationError) -> list[MissionError]:
    """Turn pydantic's errors into ``MissionError`` s that name their field."""
    out: list[MissionError] = []
    for e in error.errors():
        msg = str(e["msg"]).removeprefix("Value error, ")
        field = _field_path(e["loc"])
        named, _, rest = msg.partition(": ")
        if rest and named.startswith(field) and " " not in named:
            field, msg = named, rest  # cross-field checks carry the field in the message
        elif rest and field.startswith("zones[") and " " not in named:
            field, msg = f"{field}.{named}", rest  # a zone's own checks: its field in it
        if e["type"] == "extra_forbidden":
            msg = "unknown key"
        out.append(MissionError(field or "mission", msg))
    return out


def load_mission(text: str) -> Mission:
    """Parse and validate a mission document; raise ``MissionError`` naming the field.

    NaN and infinities are rejected even though Python's json module would read them.
    """
    try:
        raw = json.loads(text)
    except json.JSONDecodeError as exc:
        raise MissionError("mission", f"not valid JSON: {exc}") from None
    if not isinstance(raw, dict):
        raise MissionError("mission", "must be a JSON object")
    try:
        return Mission.model_validate(raw)
    except ValidationError as exc:
        raise describe_validation_error(exc)[0] from None


def load_mission_file(path: str | Path) -> Mission:
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise MissionError("mission", f"cannot read {path}: {exc}") from None
    return load_mission(text)

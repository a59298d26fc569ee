"""Zones as the planner sees them: vertical cylinders and extruded polygons as plain
arrays, and the compiled geometry every part shares (the nearest surface point's signed
distance and the unit normal there).

A zone is a footprint (a circle or a simple polygon, convex or not) between a ``floor``
and a ``ceiling`` (ICS z; −∞ / +∞ when unbounded).  An exclusion zone keeps vehicles
out, an inclusion zone keeps them in: ``zone_distance`` returns the distance to the
surface measured on the free side (positive there) and the normal pointing into the
free side, so every user treats both kinds alike.

Layout (K zones, V vertices in all), the tuple ``Zones.arrays`` (the compiled geometry's):

* ``kind[K]``      int64: ``CYLINDER`` or ``POLYGON``, plus ``INCLUSION`` for an inclusion zone
* ``geom[K,5]``    cx, cy (the circle's centre, or the polygon's bounding-circle centre),
  radius (the circle's, or the polygon's bounding radius), floor, ceiling
* ``vstart[K+1]``  int64: polygon k's corners are ``verts[vstart[k]:vstart[k+1]]``
* ``verts[V,2]``   ICS x, y of the corners (none for a cylinder)

``Zones.planning_arrays`` adds the footprints PPF is repelled by from outside
(``hull_vstart[K+1]``, ``hull_verts[H,2]``, laid out as ``vstart`` and ``verts``): an
exclusion polygon that is not convex has its convex hull there, every other zone none.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from gcs_ppf.mission import CylinderZone, Mission, Origin, PolygonZone, zone_footprint

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

CYLINDER = 0
POLYGON = 1
SHAPE = 1  # kind & SHAPE: the footprint's shape
INCLUSION = 2  # kind & INCLUSION: vehicles stay inside

ZoneArrays = tuple[IntArray, FloatArray, IntArray, FloatArray]
PlanningZoneArrays = tuple[IntArray, FloatArray, IntArray, FloatArray, IntArray, FloatArray]


@dataclass(frozen=True)
class Zones:
    """K zones as arrays (module docstring)."""

    kind: IntArray
    geom: FloatArray
    vstart: IntArray
    verts: FloatArray
    hull_vstart: IntArray | None = None
    hull_verts: FloatArray | None = None
    """None: no hulls (zones recorded before there were any)."""

    @property
    def arrays(self) -> ZoneArrays:
        return (self.kind, self.geom, self.vstart, self.verts)

    @property
    def planning_arrays(self) -> PlanningZoneArrays:
        """``arrays`` and the hulls PPF is repelled by (module docstring)."""
        if self.hull_vstart is None or self.hull_verts is None:
            return (*self.arrays, np.zeros(len(self) + 1, dtype=np.int64), np.zeros((0, 2)))
        return (*self.arrays, self.hull_vstart, self.hull_verts)

    def __len__(self) -> int:
        return int(self.kind.shape[0])


def no_zones() -> Zones:
    return Zones(
        np.zeros(0, dtype=np.int64),
        np.zeros((0, 5)),
        np.zeros(1, dtype=np.int64),
        np.zeros((0, 2)),
        np.zeros(1, dtype=np.int64),
        np.zeros((0, 2)),
    )


def zones_from_mission(mission: Mission) -> Zones:
    """The mission's zones as arrays (lat/lon corners converted about its origin)."""
    return zones_of(mission.zones, mission.origin)


def zones_of(zones: Sequence[CylinderZone | PolygonZone], origin: Origin) -> Zones:
    """``zones`` as arrays, their lat/lon converted about ``origin``."""
    kind: list[int] = []
    geom: list[tuple[float, float, float, float, float]] = []
    vstart: list[int] = [0]
    verts: list[tuple[float, float]] = []
    hull_vstart: list[int] = [0]
    hull_verts: list[tuple[float, float]] = []
    for zone in zones:
        footprint = zone_footprint(zone, origin)
        floor = -math.inf if zone.floor is None else zone.floor
        ceiling = math.inf if zone.ceiling is None else zone.ceiling
        flag = INCLUSION if zone.inclusion else 0
        if isinstance(zone, CylinderZone):
            (cx, cy), radius = footprint[0], float(zone.radius)
            kind.append(CYLINDER | flag)
        else:
            ring = footprint[:-1] if footprint[0] == footprint[-1] else footprint
            pts = np.array(ring, dtype=float)
            cx, cy = (float(c) for c in (pts.min(axis=0) + pts.max(axis=0)) / 2.0)
            radius = float(np.hypot(pts[:, 0] - cx, pts[:, 1] - cy).max())
            verts.extend(ring)
            kind.append(POLYGON | flag)
            if not zone.inclusion:
                hull_verts.extend(pocket_hull(ring))
        geom.append((cx, cy, radius, floor, ceiling))
        vstart.append(len(verts))
        hull_vstart.append(len(hull_verts))
    return Zones(
        np.array(kind, dtype=np.int64),
        np.array(geom, dtype=float).reshape(-1, 5),
        np.array(vstart, dtype=np.int64),
        np.array(verts, dtype=float).reshape(-1, 2),
        np.array(hull_vstart, dtype=np.int64),
        np.array(hull_verts, dtype=float).reshape(-1, 2),
    )


def pocket_hull(ring: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The convex hull of a polygon that has pockets (a U, an L), none for a convex one.

    PPF takes a zone by its nearest surface point, and the influence radius measured from
    it (``surface_influence_radius``) holds only where that surface is flat or convex
    towards the vehicle.  Flown into a U opening towards it, the formation was repelled
    from wall to wall inside the pocket and planned through its corner, 114 m deep
    (``examples/scene_u_pocket.json``).  Repelled by the hull while outside it, a vehicle
    sees the pocket's mouth as a flat wall and never enters it."""
    import shapely

    shape = shapely.Polygon(ring)
    hull = shape.convex_hull
    if hull.area - shape.area <= 1e-9 * max(hull.area, 1.0) or not isinstance(
        hull, shapely.Polygon
    ):
        return []
    coords = list(hull.exterior.coords)[:-1]
    return [(float(x), float(y)) for x, y in coords]


@njit(cache=True)
def polygon_distance(
    px: float, py: float, verts: np.ndarray, first: int, last: int
) -> tuple[float, float, float]:
    """Signed distance (m, negative inside) from (px, py) to the boundary of the polygon
    ``verts[first:last]`` (either winding, simple) and the unit outward normal at the
    nearest boundary point (from it towards the point outside, away from it inside; the
    edge's own normal when the point is on the boundary)."""
    best2, bx, by = math.inf, 0.0, 0.0
    ex, ey = 1.0, 0.0  # the nearest edge's direction
    inside = False
    n = last - first
    for a in range(n):
        x0, y0 = verts[first + a, 0], verts[first + a, 1]
        x1, y1 = verts[first + (a + 1) % n, 0], verts[first + (a + 1) % n, 1]
        crosses = (y0 > py) != (y1 > py)  # crossing number (even-odd)
        if crosses and px < x0 + (py - y0) * (x1 - x0) / (y1 - y0):
            inside = not inside
        sx, sy = x1 - x0, y1 - y0
        s2 = sx * sx + sy * sy
        t = 0.0 if s2 == 0.0 else min(max(((px - x0) * sx + (py - y0) * sy) / s2, 0.0), 1.0)
        qx, qy = x0 + t * sx, y0 + t * sy
        d2 = (px - qx) ** 2 + (py - qy) ** 2
        if d2 < best2:
            best2, bx, by, ex, ey = d2, qx, qy, sx, sy
    dx, dy = px - bx, py - by
    d = math.hypot(dx, dy)  # (not √best2: exact when the square underflows)
    if d > 0.0:
        # From the ratios to the larger part, normalised: a unit vector for subnormal
        # offsets too ((−1, −1) at (−5e-324, −5e-324) from a corner, d rounding to 5e-324).
        m = max(abs(dx), abs(dy))
        sx, sy = dx / m, dy / m
        r = math.hypot(sx, sy)
        nx, ny = sx / r, sy / r
        if inside:
            nx, ny = -nx, -ny
    else:  # on the boundary: the edge's normal, outward by the winding
        e = math.hypot(ex, ey)
        nx, ny = ey / e, -ex / e
        if polygon_area(verts, first, last) < 0.0:
            nx, ny = -nx, -ny
    return (-d if inside else d), nx, ny


@njit(cache=True)
def polygon_area(verts: np.ndarray, first: int, last: int) -> float:
    """Signed area (m²; positive counter-clockwise) of ``verts[first:last]``."""
    n, area = last - first, 0.0
    for a in range(n):
        x0, y0 = verts[first + a, 0], verts[first + a, 1]
        x1, y1 = verts[first + (a + 1) % n, 0], verts[first + (a + 1) % n, 1]
        area += x0 * y1 - x1 * y0
    return 0.5 * area


@njit(cache=True)
def footprint_distance(
    k: int,
    px: float,
    py: float,
    kind: np.ndarray,
    geom: np.ndarray,
    vstart: np.ndarray,
    verts: np.ndarray,
) -> tuple[float, float, float]:
    """Zone k's footprint: signed horizontal distance (negative inside) and unit outward
    normal (as ``polygon_distance``; a circle's from its centre, +x at the centre)."""
    if kind[k] & SHAPE == POLYGON:
        return polygon_distance(px, py, verts, vstart[k], vstart[k + 1])
    dx, dy = px - geom[k, 0], py - geom[k, 1]
    r = math.hypot(dx, dy)
    if r == 0.0:
        return -geom[k, 2], 1.0, 0.0
    return r - geom[k, 2], dx / r, dy / r


@njit(cache=True)
def zone_distance(
    k: int,
    px: float,
    py: float,
    pz: float,
    kind: np.ndarray,
    geom: np.ndarray,
    vstart: np.ndarray,
    verts: np.ndarray,
) -> tuple[float, float, float, float]:
    """Distance (m) from (px, py, pz) to zone k's surface, positive on its free side
    (outside an exclusion zone, inside an inclusion zone), and the unit normal at the
    nearest surface point pointing into the free side.

    The prism's signed distance: with h the footprint's signed distance and v =
    max(floor − z, z − ceiling), outside it is √(max(h,0)² + max(v,0)²) (a wall, the
    floor or ceiling, or an edge between them), inside max(h, v)."""
    h, hx, hy = footprint_distance(k, px, py, kind, geom, vstart, verts)
    below, above = geom[k, 3] - pz, pz - geom[k, 4]
    v, vz = (below, -1.0) if below > above else (above, 1.0)
    if h > 0.0 or v > 0.0:
        a, b = max(h, 0.0), max(v, 0.0)
        d = math.hypot(a, b)
        # The normal from the ratios to the larger part, normalised: a unit vector for
        # subnormal parts too (a/d and b/d were 1 and 1 at a/b = 5e-324, d rounding to a).
        m = max(a, b)
        sa, sb = a / m, b / m
        r = math.hypot(sa, sb)
        nx, ny, nz = sa / r * hx, sa / r * hy, sb / r * vz
    elif h > v:
        d, nx, ny, nz = h, hx, hy, 0.0
    else:
        d, nx, ny, nz = v, 0.0, 0.0, vz
    if kind[k] & INCLUSION:
        return -d, -nx, -ny, -nz
    return d, nx, ny, nz


@njit(cache=True)
def zone_lower_bound(k: int, px: float, py: float, pz: float, geom: np.ndarray) -> float:
    """A cheap lower bound of an exclusion zone's ``zone_distance`` (its bounding
    cylinder's), to skip far zones (inclusion zones have none: callers test them all)."""
    h = math.hypot(px - geom[k, 0], py - geom[k, 1]) - float(geom[k, 2])
    return max(h, float(geom[k, 3]) - pz, pz - float(geom[k, 4]))


@njit(cache=True)
def nearest_zone_clearance(
    px: float,
    py: float,
    pz: float,
    kind: np.ndarray,
    geom: np.ndarray,
    vstart: np.ndarray,
    verts: np.ndarray,
) -> tuple[float, int]:
    """The least ``zone_distance`` of (px, py, pz) over every zone, and which (−1: none)."""
    best, which = math.inf, -1
    for k in range(kind.shape[0]):
        if not kind[k] & INCLUSION and zone_lower_bound(k, px, py, pz, geom) >= best:
            continue
        d = zone_distance(k, px, py, pz, kind, geom, vstart, verts)[0]
        if d < best:
            best, which = d, k
    return best, which


@njit(cache=True)
def clearances(
    points: np.ndarray,
    kind: np.ndarray,
    geom: np.ndarray,
    vstart: np.ndarray,
    verts: np.ndarray,
    out: np.ndarray,
) -> None:
    """``out[P, K]``: every zone's ``zone_distance`` of every row of ``points`` [P,3]."""
    for p in range(points.shape[0]):
        for k in range(kind.shape[0]):
            out[p, k] = zone_distance(
                k, points[p, 0], points[p, 1], points[p, 2], kind, geom, vstart, verts
            )[0]


def zone_clearances(points: FloatArray, zones: Zones) -> FloatArray:
    """[P, K] distances of ``points`` [P,3] to every zone's surface (free side positive)."""
    pts = np.ascontiguousarray(np.asarray(points, dtype=float).reshape(-1, 3))
    out = np.empty((pts.shape[0], len(zones)))
    clearances(pts, *zones.arrays, out)
    return out

"""Repulsion from zones (cylinders and extruded polygons, exclusion and inclusion): Eq.
10–13 with each zone taken by its nearest surface point (``gcs_ppf.planning.zones``).

The kernel (``fleet_step``) adds ``zone_repulsion`` to the obstacles' repulsion, so
everything after it (the teammates' push stripped of components into it, the s2 escape
of Eq. 20, the slide along static obstacles) treats a zone as it treats a sphere.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gcs_ppf.planning.ppf.primitives import (
    EPSILON_1,
    INFLUENCE_STEPS,
    MAX_AVOID_PITCH,
    KernelLimits,
    airframe_limited,
)
from gcs_ppf.planning.zones import INCLUSION, POLYGON, SHAPE, zone_distance, zone_lower_bound


@njit(cache=True, inline="always")
def surface_influence_radius(speed: float, turn_rate: float, safe_distance: float) -> float:
    """Distance from a zone's surface at which avoidance must begin (erratum 4 measured
    from the surface).  A vehicle flying square at a wall turns at full rate ω on a
    circle of radius ρ = v/ω; the circle reaches ρ further forward, so avoidance that
    clears the wall by the safe distance begins at ρ + safe distance.  This is the bound
    of the sphere's √((keep_out + ρ)² − ρ²) − R_o as R_o grows (a sphere's surface curves
    away from the vehicle, a wall does not), so it holds for every footprint whose
    nearest surface is flat or convex towards the vehicle."""
    return speed / turn_rate + safe_distance


@njit(cache=True, inline="always")
def lateral_extent(
    k: int,
    px: float,
    py: float,
    hx: float,
    hy: float,
    kind: np.ndarray,
    geom: np.ndarray,
    vstart: np.ndarray,
    verts: np.ndarray,
) -> tuple[float, float]:
    """The footprint's extent (lowest, highest) across the horizontal heading (hx, hy)
    (unit), measured from the vehicle to its left."""
    lx, ly = -hy, hx
    if kind[k] & SHAPE == POLYGON:
        lo, hi = math.inf, -math.inf
        for a in range(vstart[k], vstart[k + 1]):
            s = (verts[a, 0] - px) * lx + (verts[a, 1] - py) * ly
            lo, hi = min(lo, s), max(hi, s)
        return lo, hi
    s = (geom[k, 0] - px) * lx + (geom[k, 1] - py) * ly
    return s - geom[k, 2], s + geom[k, 2]


@njit(cache=True, inline="always")
def overflight_direction(
    k: int,
    d: float,
    nx: float,
    ny: float,
    nz: float,
    px: float,
    py: float,
    pz: float,
    ux: float,
    uy: float,
    rho: float,
    lim: KernelLimits,
    kind: np.ndarray,
    geom: np.ndarray,
    vstart: np.ndarray,
    verts: np.ndarray,
) -> tuple[float, float, float]:
    """The repulsion's direction from exclusion zone k at distance ``d`` with surface
    normal (nx, ny, nz): the normal, unless flying over the zone is shorter than flying
    round it and still within reach, then the normal tilted up by 90° − γ (γ the steepest
    climb allowed: ``MAX_AVOID_PITCH`` or the airframe's), so that the slide along it
    (``slide_along_obstacles``) is a climb at γ straight on over the ceiling.

    Over is shorter when the climb to the ceiling plus the safe distance is less than the
    sidestep round the footprint across the heading (``lateral_extent``) plus the safe
    distance; it is within reach when a pull-up at full pitch rate (radius ρ) and the
    climb at γ reach that height a safe distance before the wall."""
    climb = geom[k, 4] + lim.safe_distance_obstacle - pz
    if climb <= 0.0 or nz != 0.0 or not math.isfinite(geom[k, 4]):
        return nx, ny, nz  # above the ceiling already, or under / over it: the normal
    h = math.hypot(ux, uy)
    if h == 0.0 or (nx * ux + ny * uy) >= 0.0:
        return nx, ny, nz  # not flying towards the wall
    lo, hi = lateral_extent(k, px, py, ux / h, uy / h, kind, geom, vstart, verts)
    if lo >= lim.safe_distance_obstacle or hi <= -lim.safe_distance_obstacle:
        return nx, ny, nz  # the heading misses it
    around = min(hi, -lo) + lim.safe_distance_obstacle
    gamma = min(MAX_AVOID_PITCH, lim.max_climb_angle)
    pull_up = rho * math.sin(gamma) + max(climb - rho * (1.0 - math.cos(gamma)), 0.0) / math.tan(
        gamma
    )
    if climb >= around or pull_up > d - lim.safe_distance_obstacle:
        return nx, ny, nz
    s, c = math.sin(gamma), math.cos(gamma)
    return s * nx, s * ny, c


@njit(cache=True, inline="always")
def zone_repulsion(
    i: int,
    pos: np.ndarray,
    speed: np.ndarray,
    direction: np.ndarray,
    zones: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    zone_start: np.ndarray,
    near_zones: np.ndarray,
    lim: KernelLimits,
    dt: float,
) -> tuple[float, float, float]:
    """Repulsion on vehicle i from the zones (Eq. 12–13): ε₁ along the normal at the
    nearest surface point of every zone whose influence radius (from its surface:
    ``surface_influence_radius``, a few steps of travel and for an ``airframe_limited``
    vehicle one more turn radius, as for spheres) the vehicle is in; for an exclusion
    zone whose ceiling is shorter to climb over than going round, tilted up
    (``overflight_direction``).  An exclusion polygon with pockets repels a vehicle
    outside its convex hull from the hull (``zones.pocket_hull``).  ``direction[N,3]``
    the vehicles' flight directions; ``zones`` ``Zones.planning_arrays``; only the zones
    ``near_zones[zone_start[i]:zone_start[i+1]]`` are looked at (``nearby_zones``)."""
    kind, geom, vstart, verts, hull_vstart, hull_verts = zones
    omega = min(lim.max_pitch_rate, lim.max_yaw_rate)
    vi = speed[i]
    rho = vi / omega
    reach = surface_influence_radius(vi, omega, lim.safe_distance_obstacle)
    reach += INFLUENCE_STEPS * vi * dt + (rho if airframe_limited(lim) else 0.0)
    px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
    rx, ry, rz = 0.0, 0.0, 0.0
    for c in range(zone_start[i], zone_start[i + 1]):
        k = near_zones[c]
        excluded = not kind[k] & INCLUSION
        if excluded and zone_lower_bound(k, px, py, pz, geom) > reach:
            continue
        d, nx, ny, nz = -1.0, 0.0, 0.0, 0.0
        if hull_vstart[k + 1] > hull_vstart[k]:  # outside the hull: the hull
            d, nx, ny, nz = zone_distance(k, px, py, pz, kind, geom, hull_vstart, hull_verts)
        if d <= 0.0:
            d, nx, ny, nz = zone_distance(k, px, py, pz, kind, geom, vstart, verts)
        if d > reach:
            continue
        if excluded:
            nx, ny, nz = overflight_direction(
                k,
                d,
                nx,
                ny,
                nz,
                px,
                py,
                pz,
                direction[i, 0],
                direction[i, 1],
                rho,
                lim,
                kind,
                geom,
                vstart,
                verts,
            )
        rx += EPSILON_1 * nx
        ry += EPSILON_1 * ny
        rz += EPSILON_1 * nz
    return rx, ry, rz

"""The altitude each vehicle's own GCS failsafe flies home at: ArduPlane's RTL_ALTITUDE.

When the service dies mid-run, each ArduPlane with FS_GCS_ENABL set flies RTL after
FS_LONG_TIMEOUT: straight to its home, climbing or descending to RTL_ALTITUDE above it, and
avoiding nothing.  At ArduPlane's default (100 m) every vehicle of Table 3 flew RTL through
the first sphere (campaign (l), 3 of 3 runs at ×10).  So the service sets each vehicle's
RTL_ALTITUDE over every keep-out the mission knows (obstacles at their tops, exclusion
zones at their ceilings, by the safe distance), one level of the holding stack apart in the
mission's order, so that the vehicles come home over everything and circle their homes at
different heights.  Pure: the mission and the homes in, the altitudes out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gcs_ppf.mission import Mission
from gcs_ppf.planning.scene import obstacles_from_mission
from gcs_ppf.planning.zones import zone_clearances, zones_from_mission

Point = tuple[float, float, float]
WAY_SAMPLE_M = 10.0
"""Spacing of the points a way home is checked at."""


def keep_outs_top_m(mission: Mission, mission_time_s: float) -> float:
    """The highest point (ICS z) of any obstacle's or exclusion zone's keep-out now; -inf when
    there is none, or only zones without a ceiling (nothing flies over those)."""
    obstacles = obstacles_from_mission(mission).at(mission_time_s)
    tops = [float(z + r) for (_, _, z), r in zip(obstacles.center, obstacles.radius, strict=True)]
    tops += [z.ceiling for z in mission.zones if not z.inclusion and z.ceiling is not None]
    if not tops:
        return -math.inf
    return max(tops) + mission.limits.safe_distance_obstacle


def rtl_altitudes_m(
    mission: Mission, home_z_m: dict[int, float], mission_time_s: float, spacing_m: float
) -> dict[int, float]:
    """Each vehicle of ``home_z_m`` (its home's ICS z) → its RTL_ALTITUDE (metres above that
    home, whole metres up): the k-th of the mission's vehicles ``spacing_m``·k above the
    lowest level, which clears every keep-out's top (``keep_outs_top_m``) and every home by
    the safe distance."""
    if not home_z_m:
        return {}
    lowest = max(
        keep_outs_top_m(mission, mission_time_s),
        max(home_z_m.values()) + mission.limits.safe_distance_obstacle,
    )
    order = [v.id for v in mission.vehicles if v.id in home_z_m]
    return {
        vid: float(math.ceil(lowest + spacing_m * k - home_z_m[vid])) for k, vid in enumerate(order)
    }


def return_floor_m(mission: Mission, home_z_m: dict[int, float], mission_time_s: float) -> float:
    """The lowest level (ICS z) the holds of a return home are stacked from: twice the safe
    distance over every keep-out's surface (as a hold's circle keeps it, ``holding``) and
    the safe distance over every home (``home_z_m``, not empty)."""
    safe = mission.limits.safe_distance_obstacle
    return max(keep_outs_top_m(mission, mission_time_s) + safe, max(home_z_m.values()) + safe)


@dataclass(frozen=True)
class WayHome:
    """One vehicle's way home from its holding circle: its RTL_ALTITUDE (metres above its
    home: its circle's level, whole metres down), the least clearance of the way from every
    keep-out's surface, and whether that is enough."""

    rtl_altitude_m: float
    clearance_m: float
    clear: bool


def ways_home(
    mission: Mission,
    circles: dict[int, tuple[Point, float]],
    homes: dict[int, Point],
    mission_time_s: float,
) -> dict[int, WayHome]:
    """For each vehicle with a circle (its centre, its level the centre's z; its radius) and
    a home (ICS), ArduPlane's RTL from it at that level: straight to the home's vertical and
    round it.  The vehicle leaves from anywhere on its circle, so a point a fraction s of the
    way is anywhere within radius·(1 − s) of the line at that level; it circles its home at
    up to the same radius.  Clear when that whole region keeps twice the safe distance from
    every obstacle's and zone's surface (inclusion zones' too; as a hold's circle does) and
    the level is the safe distance over the home.  The vehicles fly at their circles'
    levels, one stack level apart: the teammates are not a keep-out here."""
    lim = mission.limits
    keep = 2.0 * lim.safe_distance_obstacle
    obstacles = obstacles_from_mission(mission).at(mission_time_s)
    zones = zones_from_mission(mission)
    out: dict[int, WayHome] = {}
    for vid, (centre, radius) in circles.items():
        home = homes.get(vid)
        if home is None:
            continue
        level = centre[2]
        start = np.array([centre[0], centre[1], level])
        end = np.array([home[0], home[1], level])
        samples = max(2, math.ceil(float(np.linalg.norm(end - start)) / WAY_SAMPLE_M) + 1)
        s = np.linspace(0.0, 1.0, samples)
        way = start + s[:, None] * (end - start)
        spread = radius * (1.0 - s)  # how far off the line the vehicle may be
        spread[-1] = radius  # circling its home
        clear = np.full(samples, math.inf)
        if obstacles.radius.size:  # the nearest point of each disc to each sphere
            c = obstacles.center[None]
            across = np.hypot(way[:, None, 0] - c[..., 0], way[:, None, 1] - c[..., 1])
            nearest = np.maximum(across - spread[:, None], 0.0)
            gaps = np.hypot(nearest, way[:, None, 2] - c[..., 2]) - obstacles.radius[None]
            clear = np.minimum(clear, gaps.min(axis=1))
        if len(zones):  # a zone's distance changes by at most what the point moves
            clear = np.minimum(clear, zone_clearances(way, zones).min(axis=1) - spread)
        above = level - home[2]
        out[vid] = WayHome(
            rtl_altitude_m=float(math.floor(above)),
            clearance_m=float(clear.min()),
            clear=bool(clear.min() >= keep and above >= lim.safe_distance_obstacle),
        )
    return out

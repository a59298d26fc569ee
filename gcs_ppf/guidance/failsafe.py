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

from gcs_ppf.mission import Mission
from gcs_ppf.planning.scene import obstacles_from_mission


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

"""Whether the vehicles are where a run may start from: none inside a keep-out, none far
from its mission start position.

The plan the operator looked at started each vehicle at its ``position``; an airborne
vehicle flies on while the operator prepares, and one may already be inside an obstacle's,
a zone's or a teammate's keep-out.  Then a start is not silent (``FormationService.start``
answers 409 naming each) unless the operator asks to start from where the vehicles are: the
run then begins with the run-time assurance's escape from any keep-out.  Pure.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gcs_ppf.guidance.safety_monitor import violations
from gcs_ppf.mission import Mission
from gcs_ppf.planning.scene import obstacles_from_mission
from gcs_ppf.planning.zones import zones_from_mission

FAR_FLIGHT_S = 30.0
"""A vehicle this many seconds of flight at v_max from its start position is far from it:
the SITL's airborne vehicles fly on from their start states (at ×10 the seconds between
the links and the start are tens of theirs); an operator's minutes are more."""


@dataclass(frozen=True)
class Misplaced:
    """A vehicle a run should not start from unasked: ``keep_out`` is ``obstacle``,
    ``zone`` or ``teammate`` (``other``: the obstacle's or zone's index, the teammate's
    id; ``distance_m``: how deep inside the safe distance), or ``far`` (``distance_m``
    from its start position)."""

    vehicle_id: int
    keep_out: str
    other: int | None
    distance_m: float

    def words(self) -> str:
        if self.keep_out == "far":
            return f"vehicle {self.vehicle_id} is {self.distance_m:.0f} m from its start position"
        what = "vehicle" if self.keep_out == "teammate" else self.keep_out
        return (
            f"vehicle {self.vehicle_id} is {self.distance_m:.1f} m inside the keep-out of "
            f"{what} {self.other}"
        )


def far_m(mission: Mission) -> float:
    """How far from its start position a vehicle is far (``FAR_FLIGHT_S`` at v_max)."""
    return FAR_FLIGHT_S * mission.limits.v_max


def misplaced(
    mission: Mission, positions: dict[int, tuple[float, float, float]], mission_time_s: float = 0.0
) -> list[Misplaced]:
    """What keeps a run of ``mission`` from starting with its vehicles at ``positions``
    (ICS, those heard): each keep-out entered (``safety_monitor.violations``, the ground
    apart: a vehicle on it takes off), then each vehicle ``far_m`` from its start."""
    ids = [v.id for v in mission.vehicles if v.id in positions]
    if not ids:
        return []
    at = np.array([positions[i] for i in ids], dtype=float)
    lim = mission.limits
    found = [
        Misplaced(v.vehicle_id, v.kind, v.other, round(v.depth_m, 1))
        for v in violations(
            ids,
            at,
            obstacles_from_mission(mission).at(mission_time_s),
            None,
            lim.safe_distance_uav,
            lim.safe_distance_obstacle,
            zones=zones_from_mission(mission),
        )
    ]
    for v, p in zip((v for v in mission.vehicles if v.id in positions), at, strict=True):
        d = float(np.linalg.norm(p - np.array(v.position)))
        if d > far_m(mission):
            found.append(Misplaced(v.id, "far", None, round(d, 1)))
    return found

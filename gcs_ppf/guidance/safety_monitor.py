"""The safety monitor: every vehicle's reported position checked against the keep-outs —
obstacles, zones (cylinders and polygons, exclusion and inclusion), teammates, the ground —
independently of the planner's state and predictions.

Pure: positions in, violations out. The service feeds it the positions the vehicles report
(GLOBAL_POSITION_INT converted to the ICS, not planned), each only carried to the instant of
the newest one (``aligned``), and records each violation that begins as a
``safety_violation`` event; a run with one is never a plain ``completed`` (issue 10,
"honest outcomes").
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from gcs_ppf.planning.scene import BoolArray, FloatArray, Obstacles
from gcs_ppf.planning.zones import Zones, zone_clearances

Kind = Literal["obstacle", "zone", "teammate", "ground"]


@dataclass(frozen=True, slots=True)
class Violation:
    """A keep-out entered: ``depth_m`` is how far inside the safe distance the vehicle is
        (safe distance − clearance, > 0); ``other`` the obstacle's or the zone's index (in the
    mission's ``obstacles`` / ``zones``) or the teammate's id."""

    kind: Kind
    vehicle_id: int
    other: int | None
    depth_m: float

    @property
    def key(self) -> tuple[Kind, int, int | None]:
        """What the violation is about (a teammate pair counted once, by the lower id)."""
        return (self.kind, self.vehicle_id, self.other)


MAX_ALIGN_S = 1.0
"""A position is carried at most this far (vehicle seconds) towards the newest one."""


def aligned(positions: FloatArray, velocities: FloatArray, ages_s: FloatArray) -> FloatArray:
    """Positions [N,3] reported ``ages_s`` [N] ago (vehicle seconds), each carried along its
    reported velocity [N,3] to the instant of the newest (at most ``MAX_ALIGN_S``): the
    latest reports of two vehicles are not of one moment.  Measured (Table 3, ×5, 300 ms,
    20 % loss): two wingmen's latest reports, 0.1 s apart in their time, put them 46.5 m
    apart where, on one instant, they never came closer than 58.4 m."""
    if len(ages_s) == 0:
        return positions
    behind = np.clip(np.asarray(ages_s, dtype=float) - np.min(ages_s), 0.0, MAX_ALIGN_S)
    return positions + velocities * behind[:, None]


def current(ages_s: FloatArray) -> BoolArray:
    """Which reports [N] (``ages_s``, vehicle seconds) are of the moment the monitor judges:
    no more than ``MAX_ALIGN_S`` behind the newest.  A vehicle gone silent for longer is
    where it was, not where it is (until the watchdog calls it lost): judged there, a
    wingman passing the spot where a teammate had stopped reporting 3.5 s before was a
    violation, 45.4 m from a vehicle that was not there (test_flown_safety, a CPU burner
    per core; the independent observer on the vehicles' ports judges every one)."""
    ages = np.asarray(ages_s, dtype=float)
    if ages.size == 0:
        return np.zeros(0, dtype=bool)
    out: BoolArray = ages - ages.min() <= MAX_ALIGN_S
    return out


def violations(
    ids: list[int],
    positions: FloatArray,
    obstacles: Obstacles,
    ground_z_m: float | None,
    safe_distance_uav: float,
    safe_distance_obstacle: float,
    airborne: list[bool] | None = None,
    zones: Zones | None = None,
) -> list[Violation]:
    """The keep-outs the vehicles at ``positions`` [N,3] (ICS) are inside now: an obstacle's
    surface closer than ``safe_distance_obstacle``, a zone's the same on its free side
    (``zones``; inside an exclusion zone or outside an inclusion zone is deeper still), a
    teammate closer than
    ``safe_distance_uav``, and — for vehicles that have been airborne (``airborne``, default
    all) — the ground closer than ``safe_distance_obstacle``."""
    out: list[Violation] = []
    n = len(ids)
    if n == 0:
        return out
    if obstacles.radius.shape[0]:
        gap = np.linalg.norm(positions[:, None] - obstacles.center[None], axis=-1)
        depth = safe_distance_obstacle - (gap - obstacles.radius[None])
        for i, j in zip(*np.nonzero(depth > 0.0), strict=True):
            out.append(Violation("obstacle", ids[i], int(j), float(depth[i, j])))
    if zones is not None and len(zones):
        depth = safe_distance_obstacle - zone_clearances(positions, zones)
        for i, j in zip(*np.nonzero(depth > 0.0), strict=True):
            out.append(Violation("zone", ids[i], int(j), float(depth[i, j])))
    if n > 1:
        gap = np.linalg.norm(positions[:, None] - positions[None], axis=-1)
        depth = safe_distance_uav - gap
        for i, j in zip(*np.nonzero(np.triu(depth > 0.0, k=1)), strict=True):
            a, b = sorted((ids[i], ids[j]))
            out.append(Violation("teammate", a, b, float(depth[i, j])))
    if ground_z_m is not None:
        flying = [True] * n if airborne is None else airborne
        depth = safe_distance_obstacle - (positions[:, 2] - ground_z_m)
        for i in np.nonzero(depth > 0.0)[0]:
            if flying[i]:
                out.append(Violation("ground", ids[i], None, float(depth[i])))
    return out


@dataclass
class Monitor:
    """Violations over a run: which are in progress (an event when one begins), the deepest
    of each kind, and how many began."""

    active: dict[tuple[Kind, int, int | None], Violation] = field(default_factory=dict)
    count: int = 0
    deepest_m: dict[str, float] = field(default_factory=dict)
    airborne: set[int] = field(default_factory=set)
    """Vehicles that have been clear of the ground's keep-out (from then on it counts)."""

    def watch(
        self,
        ids: list[int],
        positions: FloatArray,
        obstacles: Obstacles,
        ground_z_m: float | None,
        safe_distance_uav: float,
        safe_distance_obstacle: float,
        zones: Zones | None = None,
    ) -> list[Violation]:
        """One sample of reported positions: the violations that have just begun."""
        if ground_z_m is not None:
            clear = positions[:, 2] - ground_z_m >= safe_distance_obstacle
            self.airborne.update(i for i, c in zip(ids, clear, strict=True) if c)
        now = violations(
            ids,
            positions,
            obstacles,
            ground_z_m,
            safe_distance_uav,
            safe_distance_obstacle,
            [i in self.airborne for i in ids],
            zones,
        )
        return self.update(now)

    def update(self, now: list[Violation]) -> list[Violation]:
        """Take this sample's violations; return those that have just begun."""
        began = [v for v in now if v.key not in self.active]
        self.active = {v.key: v for v in now}
        self.count += len(began)
        for v in now:
            self.deepest_m[v.kind] = max(self.deepest_m.get(v.kind, 0.0), v.depth_m)
        return began

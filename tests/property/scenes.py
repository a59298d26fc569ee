"""Random *feasible* scenes for property tests.

Feasible means the guarantees behind the influence radius (CONVENTIONS §2 erratum 4) and
the teammate rules can hold:

* the influence spheres of the obstacles at v_max (keep-out plus a turn radius) do not
  overlap, so a vehicle answers to one obstacle at a time;
* every start and the target lie outside every influence sphere at v_max;
* vehicles start at least ``START_GAP`` apart and their slots are at least the safe
  distance apart (the mission validator's rule);
* obstacles do not move (moving obstacles are tested head-on in tests/scenarios);
* with ``ground``, the ground lies below every start and the target by more than the
  safe distance plus a pull-up from the start pitch (obstacles may reach into it).
"""

from __future__ import annotations

import math
from typing import Any

from hypothesis import assume
from hypothesis import strategies as st

from gcs_ppf.mission import Limits, Mission
from gcs_ppf.planning.ppf.kernel import influence_radius

START_GAP = 300.0
#: Height a start needs above the ground's keep-out: levelling out from the steepest start
#: pitch (0.3 rad) at v_max on a pull-up arc of radius v_max/ω loses 573·(1 − cos 0.3) = 26 m,
#: plus three steps of travel.
GROUND_MARGIN = 40.0
LIM = Limits()
OMEGA = min(LIM.max_pitch_rate, LIM.max_yaw_rate)

coord = st.floats(-3000.0, 3000.0, allow_nan=False)
height = st.floats(-500.0, 500.0, allow_nan=False)


def influence_at_v_max(radius: float) -> float:
    return influence_radius(LIM.v_max, OMEGA, radius + LIM.safe_distance_obstacle) + 30.0


@st.composite
def feasible_missions(
    draw: st.DrawFn, max_wingmen: int = 4, max_obstacles: int = 4, ground: bool = False
) -> Mission:
    n_wingmen = draw(st.integers(0, max_wingmen))
    starts = [(draw(coord) - 6000.0, draw(coord), draw(height)) for _ in range(n_wingmen + 1)]
    for a in range(len(starts)):
        for b in range(a):
            assume(math.dist(starts[a], starts[b]) >= START_GAP)
    target = (draw(coord) + 6000.0, draw(coord), draw(height))
    slots: list[tuple[float, float, float]] = []
    spacing = draw(st.floats(60.0, 400.0))  # a V: rows of two, behind the leader
    for k in range(n_wingmen):
        row, side = divmod(k, 2)
        slots.append((-spacing * (row + 1), spacing * (row + 1) * (1 if side == 0 else -1), 0.0))
    obstacles: list[dict[str, Any]] = []
    for _ in range(draw(st.integers(0, max_obstacles))):
        centre = (draw(st.floats(-4000.0, 4000.0)), draw(coord), draw(height))
        radius = draw(st.floats(30.0, 700.0))
        reach = influence_at_v_max(radius)
        if any(math.dist(centre, p) < reach for p in [*starts, target]):
            continue
        if any(
            math.dist(centre, o["center"]) < reach + influence_at_v_max(o["radius"])
            for o in obstacles
        ):
            continue
        obstacles.append({"center": centre, "radius": radius})
    vehicles = [{
        "id": k + 1,
        "role": "leader" if k == 0 else "wingman",
        "position": starts[k],
        "pitch": draw(st.floats(-0.3, 0.3)),
        "yaw": draw(st.floats(-math.pi, math.pi)),
        "speed": draw(st.floats(LIM.v_min, LIM.v_max)),
        **({"slot": slots[k - 1]} if k else {}),
    } for k in range(n_wingmen + 1)]  # fmt: skip
    extra: dict[str, Any] = {}
    if ground:  # below every start by more than a pull-up from the start pitch needs
        lowest = min(p[2] for p in [*starts, target])
        extra["ground"] = (
            lowest - LIM.safe_distance_obstacle - GROUND_MARGIN - draw(st.floats(0.0, 400.0))
        )
    return Mission.model_validate(
        {
            **extra,
            "planner": {"max_time": 90.0},
            "target": target,
            "vehicles": vehicles,
            "obstacles": obstacles,
        }
    )

"""Explore scene families beyond the 'feasible' ones, and count where PPF fails.

    PYTHONPATH=. .venv/bin/python tests/property/explore.py FAMILY [EXAMPLES]

FAMILY is ``feasible`` (scenes.py), ``dense`` (2–8 obstacles whose influence spheres may
overlap), ``moving`` (feasible scenes whose obstacles move at up to 300 m/s) or ``close``
(vehicles starting only 80 m apart).  Prints how many plans broke the obstacle clearance,
the vehicle separation, or did not reach the target within max_time (90 s).
"""

from __future__ import annotations

import math
import sys
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gcs_ppf.mission import Mission
from gcs_ppf.offline.plan import plan_mission
from tests.property import scenes


@st.composite
def dense(draw: st.DrawFn) -> Mission:
    base = draw(scenes.feasible_missions(max_obstacles=0))
    obstacles: list[dict[str, Any]] = []
    for _ in range(draw(st.integers(2, 8))):
        centre = (draw(st.floats(-3000, 3000)), draw(st.floats(-1500, 1500)),
                  draw(st.floats(-300, 300)))  # fmt: skip
        radius = draw(st.floats(100, 700))
        reach = scenes.influence_at_v_max(radius)
        points = [v.position for v in base.vehicles] + [base.target]
        if all(math.dist(centre, p) >= reach for p in points):
            obstacles.append({"center": centre, "radius": radius})
    return Mission.model_validate({**base.model_dump(), "obstacles": obstacles})


@st.composite
def moving(draw: st.DrawFn) -> Mission:
    doc = draw(scenes.feasible_missions()).model_dump()
    for o in doc["obstacles"]:
        speed, heading = draw(st.floats(0, 300)), draw(st.floats(-math.pi, math.pi))
        o["velocity"] = (speed * math.cos(heading), speed * math.sin(heading), 0.0)
    return Mission.model_validate(doc)


def main() -> None:
    family = sys.argv[1]
    examples = int(sys.argv[2]) if len(sys.argv) > 2 else 300
    if family == "close":
        scenes.START_GAP = 80.0
    strategy = {"feasible": scenes.feasible_missions(), "dense": dense(), "moving": moving(),
                "close": scenes.feasible_missions(max_obstacles=0)}[family]  # fmt: skip
    counts = {"plans": 0, "clearance": 0, "separation": 0, "not_reached": 0}

    @settings(max_examples=examples, deadline=None, database=None,
              suppress_health_check=list(HealthCheck))  # fmt: skip
    @given(strategy)
    def run(mission: Mission) -> None:
        m = plan_mission(mission).metrics
        lim = mission.limits
        counts["plans"] += 1
        clear, sep = m["min_obstacle_clearance_m"], m["min_separation_m"]
        counts["clearance"] += clear is not None and clear < lim.safe_distance_obstacle
        counts["separation"] += sep is not None and sep < lim.safe_distance_uav
        counts["not_reached"] += not m["reached"]

    run()
    print(family, counts)


if __name__ == "__main__":
    main()

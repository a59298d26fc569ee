"""Explore scene families beyond the 'feasible' ones, and count where PPF fails.

    PYTHONPATH=. .venv/bin/python tests/property/explore.py FAMILY [EXAMPLES]

FAMILY is one of ``gcs_ppf.offline.sweep.families``: ``feasible``, ``dense`` (2–8 obstacles
whose influence spheres may overlap), ``moving`` (feasible scenes whose obstacles move at up
to 300 m/s) or ``close`` (vehicles starting only 80 m apart), drawn by hypothesis (new
scenes each run). Prints how many plans broke the obstacle clearance, the vehicle
separation, or did not reach the target within max_time (90 s). ``gcs-ppf sweep FAMILY``
plans seeded scenes of the same families on several cores and summarises them.
"""

from __future__ import annotations

import sys

from hypothesis import HealthCheck, given, settings

from gcs_ppf.mission import Mission
from gcs_ppf.offline.plan import plan_mission
from gcs_ppf.offline.sweep.families import FAMILIES
from tests.property.scenes import missions


def main() -> None:
    family = sys.argv[1]
    examples = int(sys.argv[2]) if len(sys.argv) > 2 else 300
    counts = {"plans": 0, "clearance": 0, "separation": 0, "not_reached": 0}

    @settings(max_examples=examples, deadline=None, database=None,
              suppress_health_check=list(HealthCheck))  # fmt: skip
    @given(missions(FAMILIES[family]))
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

"""The leg in the run's status: where the leader flies, its turn point included."""

from __future__ import annotations

import numpy as np

from gcs_ppf.mission import Mission
from gcs_ppf.planning.route import onto_target
from gcs_ppf.service import commanding
from gcs_ppf.service.run import Run, leg_status
from gcs_ppf.service.store import StoredRun
from tests.conftest import EXAMPLES


def test_the_last_leg_names_the_turn_point_the_leader_flies_out_to() -> None:
    """The loiter route's target lies 1 km north of its last waypoint, inside the 633 m
    turn its V follows: a leader there heading east flies on east to a turn point first."""
    mission = Mission.model_validate_json((EXAMPLES / "arduplane_route_loiter_3.json").read_text())
    run = Run(record=StoredRun(1, 1, "running", 0.0, None, None, None), mission_id=1,
              mission=mission, orders=commanding.Orders(mission, "course", 3.0))  # fmt: skip
    run.leg = len(run.legs) - 1
    assert leg_status(run)["turn_point_m"] is None
    at_waypoint = np.array(mission.route[-1].position, dtype=float)
    run.legs[run.leg] = onto_target(run.legs[run.leg], at_waypoint, 0.0, 21.9)
    status = leg_status(run)
    assert status["to_m"] == list(mission.target)
    turn = status["turn_point_m"]
    assert turn is not None
    assert turn[0] > at_waypoint[0] + 500.0  # on east, well past the waypoint
    assert turn[1] == at_waypoint[1]
    assert turn[2] == mission.target[2]

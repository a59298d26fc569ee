"""A route flown closed loop: ``python -m sitl`` and ``gcs-ppf serve`` as real processes,
the waypoints judged from an independent pymavlink listener's record of the leader."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gcs_ppf.planning.route import leg_flown, legs
from gcs_ppf.tools.demo import http_json as http
from tests.conftest import EXAMPLES
from tests.integration.test_service_sitl import check_safety, fly


@pytest.mark.integration
def test_the_arduplane_route_is_flown_waypoint_by_waypoint(tmp_path: Path) -> None:
    """Three vehicles take off together and fly a route north, east and back west (a 90°
    and a 162° turn in formation): the run completes safely, the leader's own track
    passes each waypoint (within its acceptance radius or across its finish line) in
    order, and the service said so in its events."""
    doc = json.loads((EXAMPLES / "arduplane_route_3.json").read_text())
    seen: dict[str, Any] = {}

    def read_back(api: str, mission_id: int) -> None:
        seen["events"] = http("GET", f"{api}/missions/{mission_id}/events")
        seen["runs"] = http("GET", f"{api}/runs")

    flight = fly(tmp_path, doc, after=read_back)
    assert flight.final["state"] == "completed", flight.final
    check_safety(flight)

    leader = flight.tracks[flight.mission.leader.id][:, 1:4]
    k = 1
    for leg in legs(flight.mission)[:-1]:
        while k < len(leader) and not leg_flown(leg, leader[k - 1], leader[k]):
            k += 1
        assert k < len(leader), f"the leader never flew leg {leg.index} (to {leg.end_m})"
        k += 1

    status, events = seen["events"]
    assert status == 200
    reached = [e for e in events if e["kind"] == "waypoint_reached"]
    assert [e["detail"]["waypoint"] for e in reached] == [0, 1]
    times = [e["mission_time_s"] for e in reached]
    assert times == sorted(times)
    status, runs = seen["runs"]
    summary = runs[-1]["summary"]
    assert np.allclose(summary["waypoint_times_s"], times, atol=1e-3)

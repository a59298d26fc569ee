"""The service hands the lead over when the leader is lost (``flight.hand_over``)."""

from __future__ import annotations

from typing import cast

from gcs_ppf.service.flight import hand_over
from gcs_ppf.service.run import status
from gcs_ppf.service.station import Station
from tests.unit.service.test_flight_formation import Events, table3_run


def test_the_leader_lost_wingman_2_leads_and_the_run_says_so() -> None:
    run = table3_run()
    run.lost_ids = {1}
    events = Events()
    assert hand_over(cast(Station, events), run, "lost")
    assert run.mission.leader.id == 2
    assert run.orders.mission is run.mission
    assert run.last is None
    assert run.speed_plan is None
    kind, vid, detail = events.seen[-1]
    assert (kind, vid) == ("leader_succeeded", 2)
    assert detail["lost_leader"] == 1
    assert detail["why"] == "lost"
    assert detail["slots"]["4"] == [0.0, -200.0, 0.0]
    shown = status(run)
    assert shown["leader_id"] == 2
    assert shown["slots"]["1"] == [100.0, -100.0, 0.0]


def test_a_wingman_not_responding_is_passed_over_and_with_none_left_the_lead_stays() -> None:
    run = table3_run()
    run.lost_ids = {1, 2}
    run.obedience.not_responding = {3}
    events = Events()
    assert hand_over(cast(Station, events), run, "not_responding")
    assert run.mission.leader.id == 4
    alone = table3_run()
    alone.lost_ids = {1, 2, 3, 4, 5}
    before = alone.mission
    assert not hand_over(cast(Station, Events()), alone, "lost")
    assert alone.mission is before

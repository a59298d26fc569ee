"""The service's flown formation (``flight.watch_formation``): the wingmen's slot errors from
the reported positions each tick, the events, and the status and summary that carry them."""

from __future__ import annotations

import time
from types import SimpleNamespace
from typing import Any, cast

import numpy as np

from gcs_ppf.frames import local_target_point
from gcs_ppf.mavlink.telemetry import VehicleTelemetry
from gcs_ppf.mission import Mission
from gcs_ppf.service import commanding
from gcs_ppf.service.fleet import Vehicle
from gcs_ppf.service.flight import watch_formation
from gcs_ppf.service.run import Run, status, summary
from gcs_ppf.service.station import Station
from gcs_ppf.service.store import StoredRun
from tests.conftest import EXAMPLES

LEADER_POS_M = np.array([1500.0, 2000.0, 300.0])
SPEED_M_S = 150.0  # the leader flies east, level


class Events:
    """What a run's events would be stored as: (kind, vehicle id, detail)."""

    def __init__(self) -> None:
        self.seen: list[tuple[str, int | None, dict[str, Any]]] = []
        self.fleet = SimpleNamespace(by_id={})  # no vehicle heard: no clock

    def event(self, run: Run, kind: str, vehicle_id: int | None = None, **detail: Any) -> None:
        self.seen.append((kind, vehicle_id, detail))


def table3_run() -> Run:
    mission = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())
    record = StoredRun(1, 1, "running", 0.0, None, None, None)
    return Run(record=record, mission_id=1, mission=mission,
               orders=commanding.Orders(mission, "course", 3.0))  # fmt: skip


def reported(run: Run, off_m: dict[int, float], missing: tuple[int, ...] = ()) -> list[Any]:
    """Every vehicle but ``missing`` reporting: the leader at LEADER_POS_M flying east, each
    wingman on its slot moved ``off_m`` metres north."""
    out = []
    for v in run.mission.vehicles:
        if v.id in missing:
            continue
        if v.role == "leader":
            pos = LEADER_POS_M
        else:
            assert v.slot is not None
            pos = local_target_point(LEADER_POS_M, 0.0, 0.0, np.array(v.slot))
            pos = pos + np.array([0.0, off_m.get(v.id, 0.0), 0.0])
        t = VehicleTelemetry(v.id, 1, vn_m_s=0.0, ve_m_s=SPEED_M_S, vd_m_s=0.0)
        out.append((Vehicle(v.id, 0, t, last_heard_s=time.monotonic()), tuple(pos.tolist())))
    return out


def tick(events: Events, run: Run, t_s: float, located: list[Any]) -> None:
    run.mission_time_s = t_s
    together = np.array([p for _, p in located], dtype=float).reshape(-1, 3)
    watch_formation(cast(Station, events), run, located, together)


def test_the_formation_forms_and_breaks_with_the_worst_wingman_in_the_event() -> None:
    events, run = Events(), table3_run()
    for k in range(20):  # every wingman on its slot but wingman 3, 4 m off
        tick(events, run, 10.0 + 0.1 * k, reported(run, {3: 4.0}))
    assert events.seen == [
        ("formation_formed", None, {"worst_wingman_id": 3, "worst_error_m": 4.0, "since_s": 10.0})
    ]
    s = status(run)
    assert s["formation_formed"] is True
    assert s["formation"]["worst_wingman_id"] == 3
    assert s["formation"]["time_to_form_s"] == 10.0
    assert {w["id"]: w["slot_error_m"] for w in s["formation"]["wingmen"]} == {
        2: 0.0, 3: 4.0, 4: 0.0, 5: 0.0,
    }  # fmt: skip
    for k in range(15):  # wingman 5 drifts 60 m off from 12 s
        tick(events, run, 12.0 + 0.1 * k, reported(run, {3: 4.0, 5: 60.0}))
    kind, vehicle_id, detail = events.seen[-1]
    assert (kind, vehicle_id) == ("formation_broken", None)
    assert detail == {"worst_wingman_id": 5, "worst_error_m": 60.0, "since_s": 12.0}
    figures = summary(run)["formation"]
    assert figures["longest_hold_s"] == 2.0
    assert figures["holds"] == 1


def test_a_wingman_not_heard_keeps_it_from_forming_and_a_lost_one_does_not() -> None:
    events, run = Events(), table3_run()
    tick(events, run, 1.0, reported(run, {}, missing=(4,)))
    assert events.seen == []
    assert status(run)["formation_formed"] is False
    run.lost_ids.add(4)
    tick(events, run, 1.1, reported(run, {}, missing=(4,)))
    assert [kind for kind, _, _ in events.seen] == ["formation_formed"]


def test_a_leader_without_a_velocity_measures_no_slot() -> None:
    events, run = Events(), table3_run()
    located = reported(run, {})
    leader = located[0][0]
    leader.telemetry = VehicleTelemetry(leader.system_id, 1)  # no velocity reported
    tick(events, run, 1.0, located)
    assert events.seen == []
    assert status(run)["formation"]["wingmen"] == []

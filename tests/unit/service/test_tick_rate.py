"""The tick keeps its rate or says so (``service.tick_rate``, ``flight.keep_rate``), and says
where its time went (``service.tick_phases``)."""

from __future__ import annotations

import time
from types import SimpleNamespace
from typing import Any, cast

import pytest

from gcs_ppf.service.flight import keep_rate
from gcs_ppf.service.run import status
from gcs_ppf.service.station import Station
from gcs_ppf.service.tick_phases import PHASES, TickPhases
from gcs_ppf.service.tick_rate import KEPT_AFTER_TICKS, TickRate
from tests.unit.service.test_flight_formation import Events, table3_run


def test_ticks_within_their_period_raise_nothing_and_are_measured() -> None:
    rate = TickRate(10.0)
    assert rate.measured_hz() is None
    events = [rate.update(0.1 * k, 0.05) for k in range(100)]
    assert events == [None] * 100
    assert rate.measured_hz() == pytest.approx(10.0)
    assert rate.as_dict()["overruns"] == 0
    assert not rate.overrunning


def test_an_overrun_is_said_once_and_the_rate_kept_again_after_a_run_of_ticks_on_time() -> None:
    rate = TickRate(10.0)
    now = 0.0
    said = []
    for work in [0.05] * 10 + [0.35] * 20:  # the ticks then come every 0.35 s, for 7 s
        now += max(0.1, work)
        said.append(rate.update(now, work))
    assert said[:10] == [None] * 10
    assert said[10:] == ["tick_overrun"] + [None] * 19
    assert rate.overrunning
    assert rate.overruns == 20
    assert rate.measured_hz() == pytest.approx(1 / 0.35, rel=0.05)
    kept = []
    for _ in range(KEPT_AFTER_TICKS):
        now += 0.1
        kept.append(rate.update(now, 0.05))
    assert kept == [None] * (KEPT_AFTER_TICKS - 1) + ["tick_rate_kept"]
    assert not rate.overrunning
    assert rate.overruns == 20  # over the run


def test_the_run_raises_the_overrun_event_with_the_rate_and_its_status_carries_it() -> None:
    run = table3_run()
    run.tick_rate = TickRate(10.0)
    events = Events()
    fleet = SimpleNamespace(clock_rate=lambda: 5.0)  # a SITL at 5x
    station = cast(Station, SimpleNamespace(event=events.event, fleet=fleet))
    now = 0.0
    for _ in range(5):
        now += 0.1
        keep_rate(station, run, now, 0.01)  # 50 ms of vehicle time at 5x: on time
    assert events.seen == []
    now += 0.3
    keep_rate(station, run, now, 0.04)  # 200 ms of vehicle time: over its 100 ms
    ((kind, vid, detail),) = events.seen
    assert (kind, vid) == ("tick_overrun", None)
    assert detail["work_s"] == pytest.approx(0.2)
    assert detail["period_s"] == pytest.approx(0.1)
    assert detail["measured_hz"] < 10.0
    shown = status(run)["tick_rate"]
    assert shown["overrunning"]
    assert (shown["overruns"], shown["target_hz"]) == (1, 10.0)


def test_phases_count_their_own_time_and_a_tick_only_its_own() -> None:
    phases = TickPhases()
    with phases.phase("events"):
        time.sleep(0.01)  # between ticks: not the next tick's
    phases.begin_tick()
    with phases.phase("commanding"):
        time.sleep(0.02)
        with phases.phase("assurance"):
            time.sleep(0.03)
    phases.add("decoding", 0.005)
    done = phases.end_tick()
    assert set(done) == set(PHASES)
    assert done["events"] == 0.0
    assert done["assurance"] >= 0.03
    assert 0.02 <= done["commanding"] < 0.03 + 0.02  # the assurance inside taken out
    assert done["decoding"] == 0.005
    summary = cast(dict[str, Any], phases.summary_ms())
    assert summary["assurance"]["p50"] >= 30.0

"""The tick keeps its rate or says so (``service.tick_rate``, ``flight.keep_rate``), and says
where its time went (``service.tick_phases``)."""

from __future__ import annotations

import time
from types import SimpleNamespace
from typing import Any, cast

import pytest

from gcs_ppf.service.flight import TICK_FALLBACK, TICK_SPACING, due, keep_rate, tick_spacing
from gcs_ppf.service.run import status
from gcs_ppf.service.station import Station
from gcs_ppf.service.tick_phases import PHASES, TickPhases
from gcs_ppf.service.tick_rate import KEPT_AFTER_TICKS, TickRate
from tests.unit.service.test_flight_formation import Events, table3_run

pytestmark = pytest.mark.realtime  # phases measured in wall time


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


def ticked_fixes(fixes_s: list[float], period_s: float = 0.1) -> list[float]:
    """The leader's positions (its clock) a tick plans from, each message read as it comes."""
    ticks: list[float] = []
    for fix in fixes_s:
        if not ticks or due(fix - ticks[-1], fix, ticks[-1], period_s):
            ticks.append(fix)
    return ticks


def test_a_tick_comes_with_every_position_of_a_stream_stamped_on_the_autopilots_loop() -> None:
    # 10 Hz on a 50 Hz loop: 0.08 and 0.12 s apart every half second (the built-in SITL's).
    fixes = [0.02, 0.12, 0.22, 0.32, 0.40, 0.52, 0.62, 0.72, 0.82, 0.90, 1.02]
    assert ticked_fixes(fixes) == fixes
    # A whole period after the last tick, every early position was passed over.
    assert ticked_fixes(fixes, period_s=0.1 / TICK_SPACING * 0.999) != fixes


def test_a_tick_waits_for_a_new_position_and_comes_without_one_only_after_the_fallback() -> None:
    assert not due(0.05, 1.0, 1.0, 0.1)  # the same position again
    assert not due(0.15, 1.0, 1.0, 0.1)  # its other messages moved the clock a period on
    assert due(0.1 * TICK_FALLBACK, 1.0, 1.0, 0.1)  # no position for two periods
    assert not due(0.05, 1.05, 1.0, 0.1)  # a position too soon: a stream faster than asked
    assert due(0.05, 1.08, 1.0, 0.1)
    assert not due(0.05, None, 1.0, 0.1)


def test_vehicles_on_a_radio_or_an_overrunning_tick_keep_whole_periods() -> None:
    fixes = [0.02, 0.12, 0.22, 0.32, 0.40, 0.52, 0.62, 0.72, 0.82, 0.90, 1.02]
    spacing = tick_spacing(on_radio=True, overrunning=False)
    ticks: list[float] = []
    for fix in fixes:
        if not ticks or due(fix - ticks[-1], fix, ticks[-1], 0.1, spacing):
            ticks.append(fix)
    assert ticks == [0.02, 0.12, 0.22, 0.32, 0.52, 0.62, 0.72, 0.82, 1.02]
    assert tick_spacing(on_radio=False, overrunning=False) == TICK_SPACING
    assert tick_spacing(on_radio=False, overrunning=True) == 1.0

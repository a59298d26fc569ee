"""The formation watch on synthetic sequences: slot errors (Eq. 6), forming and breaking with
hysteresis, and a run's figures."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_ppf.guidance.formation_watch import (
    BREAK_AFTER_S,
    Change,
    FormationWatch,
    slot_errors_m,
)

ACCURACY_M = 10.0
DT_S = 0.1


def feed(watch: FormationWatch, t0_s: float, t1_s: float, errors: dict[int, float]) -> list[str]:
    """Ticks every ``DT_S`` over [t0_s, t1_s) with the same errors; the kinds that changed."""
    kinds: list[str] = []
    for k in range(round((t1_s - t0_s) / DT_S)):
        kinds += [c.kind for c in watch.update(t0_s + k * DT_S, errors)]
    return kinds


# Slot errors --------------------------------------------------------------------------------
def test_a_wingman_on_its_slot_behind_a_leader_flying_north_has_no_error() -> None:
    # leader flying north (ψ = π/2): the slot (-100, 100, 0), 100 m behind and 100 m to the
    # left wing, is 100 m south and 100 m west of it
    errors = slot_errors_m(
        (1000.0, 2000.0, 300.0), (0.0, 50.0, 0.0),
        {2: ((900.0, 1900.0, 300.0), (-100.0, 100.0, 0.0)),
         3: ((1100.0, 1900.0, 300.0), (-100.0, 100.0, 0.0))},
    )  # fmt: skip
    assert errors[2] == pytest.approx(0.0, abs=1e-9)
    assert errors[3] == pytest.approx(200.0)  # mirrored: on the right wing's side


def test_the_leaders_pitch_carries_the_slot() -> None:
    # climbing at 45° due east: a slot 100 m behind is 70.7 m west and 70.7 m below
    r = 100.0 / math.sqrt(2.0)
    errors = slot_errors_m(
        (0.0, 0.0, 500.0), (30.0, 0.0, 30.0), {2: ((-r, 0.0, 500.0 - r), (-100.0, 0.0, 0.0))}
    )
    assert errors[2] == pytest.approx(0.0, abs=1e-9)
    level = slot_errors_m((0.0, 0.0, 500.0), (30.0, 0.0, 0.0),
                          {2: ((-r, 0.0, 500.0 - r), (-100.0, 0.0, 0.0))})  # fmt: skip
    assert level[2] > 50.0


def test_no_slot_error_without_the_leaders_flight_path_and_bad_positions_left_out() -> None:
    wingman = {2: ((10.0, 0.0, 0.0), (-100.0, 0.0, 0.0))}
    assert slot_errors_m((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), wingman) == {}
    assert slot_errors_m((0.0, 0.0, 0.0), (math.nan, 1.0, 0.0), wingman) == {}
    assert slot_errors_m((0.0, math.inf, 0.0), (20.0, 0.0, 0.0), wingman) == {}
    bad = {2: ((math.nan, 0.0, 0.0), (-100.0, 0.0, 0.0)), 3: ((1.0, 2.0), (0.0, 1.0, 0.0)),
           4: ((-100.0, 0.0, 0.0), (-100.0, 0.0, 0.0))}  # fmt: skip
    assert slot_errors_m((0.0, 0.0, 0.0), (20.0, 0.0, 0.0), bad) == {4: pytest.approx(0.0)}


# Forming and breaking ---------------------------------------------------------------------
def test_it_forms_when_every_wingman_is_within_the_accuracy_at_once() -> None:
    watch = FormationWatch(ACCURACY_M)
    assert feed(watch, 0.0, 5.0, {2: 3.0, 3: 40.0}) == []  # one of two within: not formed
    assert not watch.formed
    changes = watch.update(5.0, {2: 3.0, 3: 9.5})
    assert [(c.kind, c.since_s, c.worst_wingman_id, c.worst_error_m) for c in changes] == [
        ("formation_formed", 5.0, 3, 9.5)
    ]
    assert watch.formed
    assert watch.figures().time_to_form_s == 5.0


def test_noise_at_the_threshold_raises_no_events() -> None:
    watch = FormationWatch(ACCURACY_M)
    rng = np.random.default_rng(7)
    kinds = []
    for k in range(600):  # 60 s, the worst wingman jittering ±2 m about the threshold,
        t = k * DT_S  # out for at most 0.5 s at a time
        out = (k // 5) % 2 == 1
        error = ACCURACY_M + (1.0 if out else -1.0) * float(rng.uniform(0.1, 2.0))
        kinds += [c.kind for c in watch.update(t, {2: 1.0, 3: error})]
    assert kinds == ["formation_formed"]
    f = watch.figures()
    assert f.fraction_in_formation == pytest.approx(1.0)
    assert f.longest_hold_s == pytest.approx(59.9)


def test_it_breaks_after_the_worst_wingman_stays_out_for_the_grace_dated_when_it_left() -> None:
    watch = FormationWatch(ACCURACY_M)
    feed(watch, 0.0, 10.0, {2: 2.0, 3: 4.0})
    changes: list[Change] = []
    t = 10.0
    while not changes:  # wingman 3 drifts out at 10 s
        changes = watch.update(t, {2: 2.0, 3: 25.0})
        t = round(t + DT_S, 6)
    (broken,) = changes
    assert broken.kind == "formation_broken"
    assert broken.since_s == 10.0
    assert (broken.worst_wingman_id, broken.worst_error_m) == (3, 25.0)
    assert t - DT_S == pytest.approx(10.0 + BREAK_AFTER_S)  # noticed a grace later
    assert not watch.formed
    assert watch.figures().longest_hold_s == pytest.approx(10.0)  # 0 → 10 s, not 11 s


def test_a_lost_wingman_or_no_measurement_counts_as_out_of_formation() -> None:
    watch = FormationWatch(ACCURACY_M)
    feed(watch, 0.0, 2.0, {2: 1.0})
    assert watch.formed
    assert feed(watch, 2.0, 4.0, {}) == ["formation_broken"]
    assert watch.worst is None
    leader_only = FormationWatch(ACCURACY_M)
    assert feed(leader_only, 0.0, 5.0, {}) == []
    assert leader_only.figures().time_to_form_s is None
    assert leader_only.figures().fraction_in_formation is None


def test_a_wingman_not_measured_yet_keeps_the_formation_from_forming() -> None:
    watch = FormationWatch(ACCURACY_M)
    assert watch.update(1.0, {2: 1.0}, unmeasured=1) == []
    assert not watch.formed
    assert [c.kind for c in watch.update(1.1, {2: 1.0, 3: 2.0})] == ["formation_formed"]


def test_bad_input_is_ignored_and_never_raises() -> None:
    watch = FormationWatch(ACCURACY_M)
    assert watch.update(math.nan, {2: 1.0}) == []
    assert watch.mission_time_s is None
    watch.update(5.0, {2: 1.0, 3: math.nan, 4: -3.0, 5: math.inf})
    assert watch.errors_m == {2: 1.0}  # the bad ones left out: formed on wingman 2 alone
    assert watch.formed
    assert watch.update(4.0, {2: 50.0}) == []  # a tick back in time is ignored
    assert watch.errors_m == {2: 1.0}
    watch.update(5.0, {2: "far"})  # type: ignore[dict-item]
    assert watch.errors_m == {}


# Figures ------------------------------------------------------------------------------------
def test_the_figures_of_a_run_that_forms_breaks_and_forms_again() -> None:
    watch = FormationWatch(ACCURACY_M)
    feed(watch, 0.0, 20.0, {2: 80.0, 3: 50.0})  # forming: not yet
    feed(watch, 20.0, 30.0, {2: 3.0, 3: 4.0})  # 10 s in formation
    feed(watch, 30.0, 35.0, {2: 3.0, 3: 30.0})  # broken from 30 s (noticed at 31 s)
    feed(watch, 35.0, 40.0, {2: 6.0, 3: 8.0})  # formed again: 5 s, to the last tick 39.9 s
    f = watch.figures()
    assert f.time_to_form_s == pytest.approx(20.0)
    assert f.holds == 2
    assert f.longest_hold_s == pytest.approx(10.0)
    # in formation 10 s + 4.9 s of the 19.9 s since it first formed
    assert f.fraction_in_formation == pytest.approx(14.9 / 19.9)
    # errors while formed: 100 ticks of (3, 4), 50 of (6, 8); the grace's 30 m not among them
    pool = np.array([3.0, 4.0] * 100 + [6.0, 8.0] * 50)
    assert f.rms_slot_error_m == pytest.approx(float(np.sqrt(np.mean(pool**2))))
    assert f.p95_slot_error_m == pytest.approx(float(np.percentile(pool, 95)))
    assert f.p95_slot_error_m is not None
    assert f.p95_slot_error_m <= ACCURACY_M


def test_a_forgiven_excursion_counts_in_the_errors_while_formed() -> None:
    watch = FormationWatch(ACCURACY_M)
    feed(watch, 0.0, 5.0, {2: 2.0})
    feed(watch, 5.0, 5.8, {2: 14.0})  # out for 0.8 s: forgiven
    feed(watch, 5.8, 10.0, {2: 2.0})
    f = watch.figures()
    assert f.holds == 1
    assert f.p95_slot_error_m == pytest.approx(14.0)  # 8 of 100 ticks at 14 m
    assert f.rms_slot_error_m is not None
    assert f.rms_slot_error_m > 2.0


def test_the_status_lists_every_wingman_and_the_worst() -> None:
    watch = FormationWatch(ACCURACY_M)
    watch.update(3.0, {3: 12.0, 2: 4.0})
    s = watch.status()
    assert s["wingmen"] == [
        {"id": 2, "slot_error_m": 4.0, "within": True},
        {"id": 3, "slot_error_m": 12.0, "within": False},
    ]
    assert (s["formed"], s["worst_wingman_id"], s["worst_error_m"]) == (False, 3, 12.0)
    assert s["time_to_form_s"] is None

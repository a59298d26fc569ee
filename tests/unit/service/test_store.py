"""SQLite persistence: schema migration, missions, runs, events survive a reopen."""

from __future__ import annotations

from pathlib import Path

import pytest

from gcs_ppf.mission import Mission
from gcs_ppf.service.store import MIGRATIONS, Store


def test_everything_survives_a_reopen(tmp_path: Path, table3: Mission) -> None:
    db = tmp_path / "state" / "gcs.db"
    store = Store(db)
    stored = store.add_mission(table3)
    run = store.add_run(stored.id, "starting")
    store.add_event(run.id, "formation_formed", mission_time_s=12.5, detail={"n": 4})
    store.add_telemetry(run.id, [(0.5, 1, 47.0, 8.0, 800.0, 1.0, 2.0, 3.0, 100.0)])
    store.update_run(
        run.id,
        "completed",
        ended=True,
        outcome="leader reached the target",
        summary={"min_separation_m": 90.0},
    )
    store.close()

    again = Store(db)
    assert again.schema_version == len(MIGRATIONS)
    assert again.mission(stored.id).mission == table3
    [r] = again.runs(stored.id)
    assert (r.state, r.outcome, r.summary) == (
        "completed",
        "leader reached the target",
        {"min_separation_m": 90.0},
    )
    assert r.ended_s is not None
    [e] = again.events(run.id)
    assert (e.kind, e.mission_time_s, e.detail) == ("formation_formed", 12.5, {"n": 4})
    assert again.telemetry_count(run.id) == 1
    assert again.interrupted_runs() == []


def test_unknown_ids_raise_key_error(table3: Mission) -> None:
    store = Store(":memory:")
    with pytest.raises(KeyError):
        store.mission(7)
    with pytest.raises(KeyError):
        store.replace_mission(7, table3)
    with pytest.raises(KeyError):
        store.run(3)


def test_a_run_left_unfinished_is_reported(table3: Mission) -> None:
    store = Store(":memory:")
    m = store.add_mission(table3)
    run = store.add_run(m.id, "running")
    assert [r.id for r in store.interrupted_runs()] == [run.id]


def test_failed_write_changes_nothing(table3: Mission) -> None:
    store = Store(":memory:")
    with pytest.raises(Exception, match="FOREIGN KEY"):
        store.add_run(99, "starting")
    assert store.runs() == []


def test_events_and_telemetry_are_written_behind_and_read_back_in_order(
    tmp_path: Path, table3: Mission
) -> None:
    store = Store(tmp_path / "gcs.db")
    run = store.add_run(store.add_mission(table3).id, "running")
    for k in range(300):
        store.add_event(run.id, "tick", mission_time_s=0.1 * k, detail={"k": k})
        store.add_telemetry(run.id, [(0.1 * k, 1, 47.0, 8.0, 800.0, 1.0, 2.0, 3.0, 100.0)])
    # what one caller wrote it reads back at once, in the order written
    assert [e.detail for e in store.events(run.id)] == [{"k": k} for k in range(300)]
    assert store.telemetry_count(run.id) == 300
    store.add_event(run.id, "last")
    store.close()  # writes what is still queued
    assert [e.kind for e in Store(tmp_path / "gcs.db").events(run.id)][-2:] == ["tick", "last"]


def test_a_failed_write_behind_is_counted_and_the_others_kept(table3: Mission) -> None:
    store = Store(":memory:")
    run = store.add_run(store.add_mission(table3).id, "running")
    store.add_event(run.id, "before")
    store.add_event(99, "of no run")  # FOREIGN KEY: refused, logged
    store.add_event(run.id, "after")
    assert [e.kind for e in store.events(run.id)] == ["before", "after"]
    assert store.write_errors == 1

"""Crash recovery (issue 26 item 3): an interrupted run read back from its records, resumed
or aborted by a service started again; the links it was told of opened again."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from gcs_ppf.mavlink import commands
from gcs_ppf.mission import Mission
from gcs_ppf.planning import succession
from gcs_ppf.service import flight, resumption, runs
from gcs_ppf.service.errors import Conflict
from gcs_ppf.service.run import Run, RunState
from gcs_ppf.service.runs import FormationService
from gcs_ppf.service.settings import Settings
from gcs_ppf.service.store import Store, StoredEvent
from tests.conftest import EXAMPLES
from tests.unit.service.test_runs import recording, report_flying, until_running

TABLE3 = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())


def ev(
    kind: str, t: float | None, vid: int | None = None, wall: float = 0.0, **detail: object
) -> StoredEvent:
    return StoredEvent(1, t, wall, kind, vid, detail or None)


def test_the_standing_is_what_the_events_said() -> None:
    events = [
        ev("run_started", 0.0),
        ev("run_running", 0.0, leader_clock_zero_s=12.0),
        ev("vehicle_lost", 20.0, 3),
        ev("safety_violation", 21.0, 4, keep_out="teammate", other=5, depth_m=2.5),
        ev("vehicle_back", 25.0, 3),
        ev("vehicle_lost", 30.0, 1),
        ev("leader_succeeded", 35.0, 2, wall=100.0, leader_clock_zero_s=13.0),
        ev("vehicle_lost", 36.0, 5, wall=101.0),
    ]
    s = resumption.standing(TABLE3, events)
    expected = succession.led_by(TABLE3, TABLE3.vehicles[1])
    assert s.mission == expected
    assert s.mission.leader.id == 2
    assert s.flew
    assert (s.mission_time_s, s.wall_s, s.clock_zero_s) == (36.0, 101.0, 13.0)
    assert s.lost_ids == {1, 5}
    assert (s.violations, s.deepest_m) == (1, {"teammate": 2.5})
    # on the new leader's clock: 13 s at mission time 0, 63 s now
    assert resumption.mission_time_now_s(s, 63.0, 1e9, 10.0) == pytest.approx(50.0)
    # the leader restarted (its clock behind the latest event): the wall time since, x10
    assert resumption.mission_time_now_s(s, 20.0, 103.0, 10.0) == pytest.approx(56.0)


def test_a_run_that_died_launching_starts_again_from_zero() -> None:
    s = resumption.standing(TABLE3, [ev("run_started", 0.0), ev("takeoff", 0.0, 2, wall=5.0)])
    assert not s.flew
    assert resumption.mission_time_now_s(s, 100.0, 50.0, 10.0) == 0.0


def test_the_closest_separation_and_clearance_of_the_samples() -> None:
    o = TABLE3.obstacles[0]
    x, y, z = o.center
    rows = [
        (1.0, 1, 0, 0, 0, x, y, z + o.radius + 40.0, 0.0),
        (1.0, 2, 0, 0, 0, x, y + 500.0, z + o.radius + 40.0, 0.0),
        (2.0, 1, 0, 0, 0, 0.0, 0.0, 300.0, 0.0),
        (2.0, 2, 0, 0, 0, 0.0, 70.0, 300.0, 0.0),
    ]
    separation, clear = resumption.closest_m(TABLE3, rows)
    assert separation == pytest.approx(70.0)
    assert clear == pytest.approx(40.0)


def interrupted(tmp_path: Path, mission: Mission = TABLE3) -> tuple[int, int]:
    """A store as a service killed mid-run left it, then marked by a service started again:
    the mission's run ``interrupted`` 40 s in (the leader's clock at 1.0 s at its zero),
    wingman 5 lost at 10 s."""
    store = Store(tmp_path / "gcs.db")
    mid = store.add_mission(mission).id
    run = store.add_run(mid, RunState.RUNNING)
    store.add_event(run.id, "run_started", mission_time_s=0.0)
    store.add_event(run.id, "run_running", mission_time_s=0.0, detail={"leader_clock_zero_s": 1.0})
    store.add_event(run.id, "vehicle_lost", mission_time_s=10.0, vehicle_id=5)
    store.add_event(run.id, "avoidance_entered", mission_time_s=40.0, vehicle_id=1)
    store.close()
    FormationService(Settings(db=tmp_path / "gcs.db", tlog_dir=None), Store(tmp_path / "gcs.db"))
    return mid, run.id


def test_resume_flies_the_interrupted_run_on_from_its_record(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The same run record, reopened: its mission time on the leader's clock (61 s since
    its zero at 1 s), the lost wingman still lost and left out of the launch, the vehicles
    taken back (the launch) before it runs again; ``run_resumed`` then ``run_running``."""
    mid, run_id = interrupted(tmp_path)
    monkeypatch.setattr(runs, "load_kernels", lambda planner_dt_s: None)
    launched: list[list[int]] = []

    async def launch_fleet(station: object, run: Run) -> None:
        launched.append(sorted(v.id for v in run.mission.vehicles if v.id not in run.lost_ids))

    monkeypatch.setattr(flight, "launch_fleet", launch_fleet)
    sent: list[tuple[int, object]] = []

    async def scenario() -> None:
        service = recording(tmp_path, monkeypatch, sent)
        async with service.running():
            report_flying(service, TABLE3, time_boot_ms=62_000)
            del service.fleet.by_id[5]  # lost before the crash, not heard since
            status = await service.resume(mid)
            assert status["run_id"] == run_id
            assert status["state"] == "starting"
            assert status["mission_time_s"] == pytest.approx(61.0)
            assert await until_running(service, mid) == "running"
            assert launched == [[1, 2, 3, 4]]
            assert service.store.run(run_id).ended_s is None
            service.fleet.by_id.clear()
        kinds = [e.kind for e in service.store.events(run_id)]
        assert kinds[kinds.index("run_interrupted") :][:3] == [
            "run_interrupted",
            "run_resumed",
            "run_running",
        ]

    asyncio.run(scenario())


def test_resume_is_refused_leaving_the_run_as_it_was(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """409 with a vehicle the run had not lost unheard (naming it), and for a mission whose
    last run is not interrupted; the run stays ``interrupted``, ended."""
    mid, run_id = interrupted(tmp_path)
    monkeypatch.setattr(runs, "load_kernels", lambda planner_dt_s: None)

    async def scenario() -> None:
        service = recording(tmp_path, monkeypatch, [])
        async with service.running():
            report_flying(service, TABLE3)
            del service.fleet.by_id[3]
            with pytest.raises(Conflict, match=r"vehicles not connected: \[3\]"):
                await service.resume(mid)
            assert service.status(mid)["state"] == "interrupted"
            assert service.store.run(run_id).ended_s is not None
            other = service.create_mission(TABLE3).id
            with pytest.raises(Conflict, match="has no interrupted run"):
                await service.resume(other)
            service.fleet.by_id.clear()

    asyncio.run(scenario())


def test_abort_of_an_interrupted_run_holds_every_vehicle_heard(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Aborted instead: ``aborted``, and every vehicle heard flown to its holding circle
    (``holds_flown``) and handed it."""
    mid, run_id = interrupted(tmp_path)
    monkeypatch.setattr(runs, "load_kernels", lambda planner_dt_s: None)
    sent: list[tuple[int, object]] = []

    async def scenario() -> None:
        service = recording(tmp_path, monkeypatch, sent)
        async with service.running():
            report_flying(service, TABLE3)
            status = await service.abort(mid)
            assert status["state"] == "aborted"
            for _ in range(100):
                flown = [e for e in service.store.events(run_id) if e.kind == "holds_flown"]
                if flown:
                    break
                await asyncio.sleep(0.05)
            assert flown[0].detail == {"vehicles": [1, 2, 3, 4, 5]}
        # stopped meanwhile: the circles handed to every autopilot
        holds = {vid for vid, m in sent
                 if getattr(m, "command", None) == commands.MAV_CMD_DO_REPOSITION}  # fmt: skip
        assert holds == {v.id for v in TABLE3.vehicles}
        assert service.store.run(run_id).state == "aborted"
        with pytest.raises(Conflict, match="is not running"):
            await service.abort(mid)

    asyncio.run(scenario())


def test_links_added_are_opened_again_by_the_next_service(tmp_path: Path) -> None:
    async def scenario() -> None:
        settings = Settings(db=tmp_path / "gcs.db", tlog_dir=None)
        service = FormationService(settings, Store(settings.db))
        async with service.running():
            await service.add_link("tcp:127.0.0.1:2")
            info = await service.add_link("tcp:127.0.0.1:1", allow_unsigned=True)
            await service.remove_link(info["id"] - 1)
        service.store.close()
        again = FormationService(settings, Store(settings.db))
        async with again.running():
            assert [e["url"] for e in again.fleet.links()] == ["tcp:127.0.0.1:1"]
        again.store.close()

    asyncio.run(scenario())

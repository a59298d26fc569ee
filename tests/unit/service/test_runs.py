"""Starting a run: the request is answered at once, the fleet launches once the kernels
are loaded."""

from __future__ import annotations

import asyncio
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from gcs_ppf.mavlink.telemetry import VehicleTelemetry
from gcs_ppf.mission import Mission
from gcs_ppf.service import flight, launch, runs
from gcs_ppf.service.errors import Conflict
from gcs_ppf.service.fleet import Vehicle
from gcs_ppf.service.run import Run
from gcs_ppf.service.runs import FormationService
from gcs_ppf.service.settings import Settings
from gcs_ppf.service.store import Store
from tests.conftest import EXAMPLES

pytestmark = pytest.mark.realtime  # the service's loops in wall time


def test_start_answers_while_the_kernels_load_and_launch_waits_for_them(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """On a cold numba cache the kernels take minutes to compile; the start request awaited
    them and an HTTP client timed out (fly_check, session 4). The run must answer
    ``starting`` at once and launch nothing until they are loaded."""
    loaded = threading.Event()
    launched: list[int] = []

    def slow_load(planner_dt_s: float) -> None:
        assert loaded.wait(30)

    async def launch_fleet(station: object, run: Run) -> None:
        launched.append(run.mission_id)
        raise RuntimeError("launch stops here")  # the run fails; enough for this test

    monkeypatch.setattr(runs, "load_kernels", slow_load)
    monkeypatch.setattr(flight, "launch_fleet", launch_fleet)
    mission = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())

    async def scenario() -> None:
        settings = Settings(db=tmp_path / "gcs.db", tlog_dir=None)
        service = FormationService(settings, Store(settings.db))
        async with service.running():
            for v in mission.vehicles:  # as if their links had reported them
                service.fleet.by_id[v.id] = Vehicle(
                    v.id, 0, VehicleTelemetry(v.id, 1), last_heard_s=time.monotonic() + 60
                )
            mid = service.create_mission(mission).id
            status = await asyncio.wait_for(service.start(mid), 1.0)
            assert status["state"] == "starting"
            await asyncio.sleep(0.3)
            assert launched == []  # still loading: nothing launched
            loaded.set()
            for _ in range(100):
                if launched:
                    break
                await asyncio.sleep(0.05)
            assert launched == [mid]
            service.fleet.by_id.clear()

    asyncio.run(scenario())


def report_flying(
    service: FormationService,
    mission: Mission,
    on_ground: int | None = None,
    time_boot_ms: int = 1000,
) -> None:
    """Every vehicle of ``mission`` as if its link reported it flying east at 150 m/s where
    the mission starts it (``on_ground``: that one on the ground there, 300 m below the
    others' height above home)."""
    from gcs_ppf.geodesy import enu_to_geodetic

    for v in mission.vehicles:
        lat, lon, alt = enu_to_geodetic(*v.position, mission.origin)
        t = VehicleTelemetry(v.id, 1, lat_deg=lat, lon_deg=lon, alt_amsl_m=alt,
                             relative_alt_m=0.0 if v.id == on_ground else 300.0, vn_m_s=0.0,
                             ve_m_s=150.0, vd_m_s=0.0, time_boot_ms=time_boot_ms,
                             position_received_s=time.monotonic())  # fmt: skip
        service.fleet.by_id[v.id] = Vehicle(v.id, 0, t, last_heard_s=time.monotonic() + 60)


def recording(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, sent: list[tuple[int, object]]
) -> FormationService:
    """A service whose fleet records what it sends (system id, message) in ``sent``."""
    settings = Settings(db=tmp_path / "gcs.db", tlog_dir=None)
    service = FormationService(settings, Store(settings.db))

    async def send(system_id: int, msg: object) -> None:
        sent.append((system_id, msg))

    monkeypatch.setattr(service.fleet, "send", send)
    return service


async def until_running(service: FormationService, mission_id: int) -> str:
    """Wait (5 s at most) for the run to be ``running``; its state then."""
    for _ in range(100):
        if service.status(mission_id)["state"] == "running":
            break
        await asyncio.sleep(0.05)
    return str(service.status(mission_id)["state"])


def test_a_service_stopped_while_a_run_flies_hands_every_vehicle_its_hold(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Stopped mid-run, the service left every vehicle on the last course it was sent (in
    GUIDED, for ever). Now the run ends ``failed`` and, before the links close, every
    vehicle is sent its holding circle (DO_REPOSITION with a radius, then v_min and the
    altitude), once."""
    from gcs_ppf.mavlink import commands

    monkeypatch.setattr(runs, "load_kernels", lambda planner_dt_s: None)

    async def launch_fleet(station: object, run: Run) -> None:
        return None  # as if every vehicle were flying in GUIDED

    monkeypatch.setattr(flight, "launch_fleet", launch_fleet)
    mission = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())
    sent: list[tuple[int, object]] = []

    async def scenario() -> None:
        service = recording(tmp_path, monkeypatch, sent)
        async with service.running():
            report_flying(service, mission)
            mid = service.create_mission(mission).id
            await service.start(mid)
            assert await until_running(service, mid) == "running"
            sent.clear()
        assert service.status(mid)["state"] == "failed"
        holds = {vid: m for vid, m in sent
                 if getattr(m, "command", None) == commands.MAV_CMD_DO_REPOSITION}  # fmt: skip
        assert set(holds) == {v.id for v in mission.vehicles}
        assert all(getattr(m, "param3", 0.0) >= 80.0 for m in holds.values())

    asyncio.run(scenario())


def test_the_first_tick_s_work_leaves_out_the_launch_s_decoding(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The decoding a tick counts is the links' since the last tick; the first counted it
    since the service started, the whole launch's (1.7–4.6 s of work and a
    ``tick_overrun`` event in 15 of 69 flights at ×10).  Now it counts from the loop's
    start: 4 s decoded during the launch, none since."""
    monkeypatch.setattr(runs, "load_kernels", lambda planner_dt_s: None)

    async def launch_fleet(station: object, run: Run) -> None:
        return None  # as if every vehicle were flying in GUIDED

    monkeypatch.setattr(flight, "launch_fleet", launch_fleet)
    mission = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())

    async def scenario() -> None:
        service = recording(tmp_path, monkeypatch, [])
        monkeypatch.setattr(service.fleet, "decoding_s", lambda: 4.0)
        async with service.running():
            report_flying(service, mission)
            mid = service.create_mission(mission).id
            await service.start(mid)
            assert await until_running(service, mid) == "running"
            for _ in range(40):
                if service.status(mid).get("tick_phases_ms"):
                    break
                await asyncio.sleep(0.05)
            phases = service.status(mid)["tick_phases_ms"]
            service.fleet.by_id.clear()
        assert phases["decoding"]["p99"] == 0.0

    asyncio.run(scenario())


def test_while_one_vehicle_takes_off_the_others_holds_are_flown_then_handed_over(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Wingman 2 on the ground, the others flying: while it takes off the others are flown
    to holding circles by the service (course commands through the assurance, a
    ``launch_holds_flown`` event), not left to their autopilots' loiter at once (two
    wingmen came to 43.0 m on their way to theirs); when the launch is done each is sent
    its circle once (DO_REPOSITION), and the one taking off is never commanded by the
    holds."""
    from gcs_ppf.mavlink import commands

    monkeypatch.setattr(runs, "load_kernels", lambda planner_dt_s: None)

    async def takeoff(*args: object, **kwargs: object) -> None:
        await asyncio.sleep(1.5)  # the first hold tick comes within 1 s

    monkeypatch.setattr(launch, "launch", takeoff)
    mission = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())
    sent: list[tuple[int, object]] = []
    events: list[str] = []

    async def scenario() -> None:
        service = recording(tmp_path, monkeypatch, sent)
        async with service.running():
            report_flying(service, mission, on_ground=2)
            mid = service.create_mission(mission).id
            await service.start(mid)
            await until_running(service, mid)
            launched.extend(sent)  # the launch's (the run's first tick is a second away)
            events.extend(e["kind"] for e in service.events(mid))
            service.fleet.by_id.clear()

    launched: list[tuple[int, object]] = []
    asyncio.run(scenario())
    assert "launch_holds_flown" in events

    def sent_to(vid: int, command: int) -> int:
        return sum(1 for i, m in launched if i == vid and getattr(m, "command", None) == command)

    flying = [v.id for v in mission.vehicles if v.id != 2]
    assert all(sent_to(v, commands.MAV_CMD_GUIDED_CHANGE_HEADING) >= 1 for v in flying)
    assert all(sent_to(v, commands.MAV_CMD_DO_REPOSITION) == 1 for v in flying)
    assert sent_to(2, commands.MAV_CMD_GUIDED_CHANGE_HEADING) == 0
    assert sent_to(2, commands.MAV_CMD_DO_REPOSITION) == 0


def test_a_service_stopped_mid_launch_retries_nothing_over_its_closed_links(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Stopped while the failsafe's RTL_ALTITUDE was still being set (unanswered), the
    service went on sending it over the links it had closed until the retries ran out
    (5 s a stop); now what is left is cancelled once the links are closed."""
    monkeypatch.setattr(runs, "load_kernels", lambda planner_dt_s: None)

    async def takeoff(*args: object, **kwargs: object) -> None:
        await asyncio.sleep(0.2)

    monkeypatch.setattr(launch, "launch", takeoff)
    mission = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())
    service = recording(tmp_path, monkeypatch, [])

    async def scenario() -> int:
        async with service.running():
            report_flying(service, mission)
            mid = service.create_mission(mission).id
            await service.start(mid)
            await until_running(service, mid)
            service.fleet.by_id.clear()
        return mid

    mid = asyncio.run(scenario())
    kinds = [e["kind"] for e in service.events(mid)]
    assert "run_failed" in kinds
    assert "parameter_unanswered" not in kinds


def test_vehicles_sent_on_after_their_takeoff_are_held_once_one_nears_its_point(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The formation takeoff of five, climbed out, each sent on to where the way is clear
    (``clear_ahead``), where ArduPlane circles at WP_LOITER_RAD unassured: the five points
    lie 100 m apart abreast, and a hand-off held 65 s on a lossy link let the leader and
    wingman 5 circle there 47.2 m apart.  While none is near its point they fly on, nothing
    commanded (a quick hand-off ends there); once the leader nears its point, every vehicle
    up and in GUIDED is held on a circle flown under assurance (``launch_wait_held``,
    course commands, each circle sent once at the end), a stack level over the climb-out of
    the one still taking off, which is never commanded."""
    from gcs_ppf.geodesy import enu_to_geodetic
    from gcs_ppf.mavlink import commands
    from gcs_ppf.mavlink.ardupilot import PlaneMode
    from gcs_ppf.service import commanding

    monkeypatch.setattr(runs, "load_kernels", lambda planner_dt_s: None)
    mission = Mission.model_validate_json(
        (EXAMPLES / "arduplane_formation_takeoff_5.json").read_text()
    )
    late = 3  # its switch to GUIDED not confirmed yet: still in TAKEOFF
    flying_on: list[tuple[int, object]] = []
    held_before: list[dict[str, object]] = []

    def up(service: FormationService, vid: int, east: float, north: float, mode: int) -> None:
        lat, lon, alt = enu_to_geodetic(east, north, 50.0, mission.origin)
        service.fleet.by_id[vid].telemetry = VehicleTelemetry(
            vid, 1, lat_deg=lat, lon_deg=lon, alt_amsl_m=alt, relative_alt_m=50.0,
            vn_m_s=22.0, ve_m_s=0.0, vd_m_s=0.0, time_boot_ms=60_000, custom_mode=mode,
            armed=True, position_received_s=time.monotonic(),
        )  # fmt: skip

    async def takeoff(*args: object, **kwargs: object) -> None:
        service = holder[0]
        ahead = kwargs["clear_ahead"]
        assert callable(ahead)
        points = {}
        for v in mission.vehicles:
            mode = PlaneMode.TAKEOFF if v.id == late else PlaneMode.GUIDED
            up(service, v.id, v.position[0], v.position[1] + 300.0, int(mode))
            if v.id != late:
                east, north = ahead(v.id, service.fleet.telemetry(v.id))
                points[v.id] = (v.position[0] + east, v.position[1] + 300.0 + north)
        await asyncio.sleep(1.0)
        flying_on.extend(sent)
        held_before.extend(e for e in service.events(mid[0]) if e["kind"] == "launch_wait_held")
        x, y = points[mission.leader.id]  # flown on to 300 m short of its point
        up(service, mission.leader.id, x, y - 300.0, int(PlaneMode.GUIDED))
        await asyncio.sleep(2.0)

    monkeypatch.setattr(launch, "launch", takeoff)
    sent: list[tuple[int, object]] = []
    events: list[dict[str, object]] = []
    holder: list[FormationService] = []
    mid: list[int] = []

    async def scenario() -> None:
        service = recording(tmp_path, monkeypatch, sent)
        holder.append(service)
        async with service.running():
            report_on_ground(service, mission)
            mid.append(service.create_mission(mission).id)
            await service.start(mid[0])
            await until_running(service, mid[0])
            launched.extend(sent)
            events.extend(service.events(mid[0]))
            service.fleet.by_id.clear()

    launched: list[tuple[int, object]] = []
    asyncio.run(scenario())

    def sent_to(vid: int, command: int, messages: list[tuple[int, object]]) -> int:
        return sum(1 for i, m in messages if i == vid and getattr(m, "command", None) == command)

    guided = [v.id for v in mission.vehicles if v.id != late]
    heading, reposition = commands.MAV_CMD_GUIDED_CHANGE_HEADING, commands.MAV_CMD_DO_REPOSITION
    assert held_before == []
    assert all(sent_to(v, c, flying_on) == 0 for v in guided for c in (heading, reposition))
    held = [e["detail"] for e in events if e["kind"] == "launch_wait_held"]
    assert held == [{"vehicles": guided, "nearing": [mission.leader.id]}]
    assert all(sent_to(v, heading, launched) >= 1 for v in guided)
    assert all(sent_to(v, reposition, launched) == 1 for v in guided)
    assert sent_to(late, heading, launched) == sent_to(late, reposition, launched) == 0
    # a stack level over the late one's climb-out (home 0 m, TKOFF_ALT 50 m), not at it
    over_climb = mission.origin.alt + 50.0 + commanding.stack_spacing_m(mission)
    circles: list[Any] = [m for _, m in launched if getattr(m, "command", None) == reposition]
    assert min(m.z for m in circles) >= over_climb - 0.5


def report_on_ground(service: FormationService, mission: Mission) -> None:
    """Every vehicle of ``mission`` standing on the ground where the mission starts it,
    disarmed, as a SITL just booted reports it."""
    from gcs_ppf.geodesy import enu_to_geodetic

    for v in mission.vehicles:
        lat, lon, alt = enu_to_geodetic(v.position[0], v.position[1], 0.0, mission.origin)
        t = VehicleTelemetry(
            v.id,
            1,
            lat_deg=lat,
            lon_deg=lon,
            alt_amsl_m=alt,
            relative_alt_m=0.0,
            vn_m_s=0.0,
            ve_m_s=0.0,
            vd_m_s=0.0,
            time_boot_ms=1000,
            position_received_s=time.monotonic(),
        )
        service.fleet.by_id[v.id] = Vehicle(v.id, 0, t, last_heard_s=time.monotonic() + 60)


@pytest.mark.parametrize("some_flying", [False, True])
def test_a_start_that_fails_leaves_the_vehicles_on_the_ground_alone(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    caplog: pytest.LogCaptureFixture,
    some_flying: bool,
) -> None:
    """Real ArduPlane refused the arm (pre-arm checks not passed yet) and the run failed;
    the holds that followed were commanded to vehicles still on the ground, and raised
    ``ValueError: lateral_accel_m_s2 must be > 0`` (``holds_flight_failed``).  Now those on
    the ground are left alone (``holds_not_on_ground``), the flying ones hold, nothing
    raises."""
    from gcs_ppf.mavlink import commands

    monkeypatch.setattr(runs, "load_kernels", lambda planner_dt_s: None)

    async def refused(*args: object, **kwargs: object) -> None:
        raise launch.CommandFailed(2, "arm", result="FAILED", attempts=1)

    monkeypatch.setattr(launch, "launch", refused)
    mission = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())
    sent: list[tuple[int, object]] = []
    events: list[dict[str, object]] = []

    async def scenario() -> None:
        service = recording(tmp_path, monkeypatch, sent)
        async with service.running():
            if some_flying:
                report_flying(service, mission, on_ground=2)
            else:
                report_on_ground(service, mission)
            mid = service.create_mission(mission).id
            await service.start(mid)
            for _ in range(100):
                events[:] = service.events(mid)
                if any(e["kind"] in ("holds_loitering", "holds_flight_failed") for e in events):
                    break
                await asyncio.sleep(0.05)
            assert service.status(mid)["state"] == "failed"
            service.fleet.by_id.clear()

    asyncio.run(scenario())
    kinds = [e["kind"] for e in events]
    assert "holds_flight_failed" not in kinds
    grounded = [e for e in events if e["kind"] == "holds_not_on_ground"]
    on_ground = [2] if some_flying else [v.id for v in mission.vehicles]
    assert [e["detail"]["vehicles"] for e in grounded] == [on_ground]  # type: ignore[index]
    # the launch (refused at once) asked for parameters and set the failsafe's RTL altitude
    # only; the holds sent them nothing
    kinds_sent = {getattr(m, "get_type", lambda: "?")() for vid, m in sent if vid in on_ground}
    assert kinds_sent <= {"PARAM_REQUEST_READ", "PARAM_SET"}
    set_names = {m.param_id for vid, m in sent if vid in on_ground and m.get_type() == "PARAM_SET"}  # type: ignore[attr-defined]
    assert set_names == {"RTL_ALTITUDE"}
    assert not [r for r in caplog.records if r.exc_info], "a refusal is not an exception"
    if some_flying:
        reposition = commands.MAV_CMD_DO_REPOSITION
        holds = {vid for vid, m in sent if getattr(m, "command", None) == reposition}
        assert holds == {v.id for v in mission.vehicles} - {2}


def test_a_start_with_a_system_id_heard_on_two_links_is_refused(tmp_path: Path) -> None:
    mission = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())

    async def scenario() -> None:
        settings = Settings(db=tmp_path / "gcs.db", tlog_dir=None)
        service = FormationService(settings, Store(settings.db))
        async with service.running():
            for v in mission.vehicles:
                service.fleet.by_id[v.id] = Vehicle(
                    v.id, 0, VehicleTelemetry(v.id, 1), last_heard_s=time.monotonic() + 60
                )
            first = await service.fleet.add_link("tcp:127.0.0.1:9")
            second = await service.fleet.add_link("tcp:127.0.0.1:10")
            now = time.monotonic()
            service.fleet.by_id[3].heard_on = {first["id"]: now, second["id"]: now}
            mid = service.create_mission(mission).id
            with pytest.raises(Conflict) as refused:
                await service.start(mid)
            assert "vehicle 3 on links 1, 2" in refused.value.message
            assert refused.value.detail == {"duplicate_links": {"3": [1, 2]}}
            assert service.status(mid)["state"] == "pending"  # nothing started

    asyncio.run(scenario())


def test_a_run_left_flying_by_a_dead_service_is_interrupted_on_restart(tmp_path: Path) -> None:
    """``kill -9`` mid-run leaves the run unended in the store; the next service marks it
    ``interrupted`` (not ``failed``: nothing handed the vehicles their holds), with an
    event, and keeps every event stored before."""
    mission = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())
    store = Store(tmp_path / "gcs.db")
    mid = store.add_mission(mission).id
    run = store.add_run(mid, runs.RunState.RUNNING)
    store.add_event(run.id, "run_started")
    store.add_event(run.id, "run_running", mission_time_s=1.5)
    store.close()
    settings = Settings(db=tmp_path / "gcs.db", tlog_dir=None)
    again = Store(settings.db)
    service = FormationService(settings, again)
    status = service.status(mid)
    assert status["state"] == "interrupted"
    assert status["outcome"] == "the service stopped while the run was running"
    kinds = [e.kind for e in again.events(run.id)]
    assert kinds == ["run_started", "run_running", "run_interrupted"]
    assert again.interrupted_runs() == []
    again.close()
    # A third start finds nothing to mark again.
    third = Store(settings.db)
    FormationService(settings, third)
    assert [e.kind for e in third.events(run.id)].count("run_interrupted") == 1
    third.close()


def test_a_start_far_from_the_plan_is_refused_unless_asked_from_where_they_are(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Vehicle 3 flew on 10 km from where the uploaded mission starts it: the start is a
    409 naming it and the distance (nothing started), and with ``from_where_they_are``
    the run starts, its ``run_started`` event saying what it started over."""
    monkeypatch.setattr(runs, "load_kernels", lambda planner_dt_s: None)

    async def launch_fleet(station: object, run: Run) -> None:
        return None

    monkeypatch.setattr(flight, "launch_fleet", launch_fleet)
    flown = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())
    doc = flown.model_dump()
    doc["vehicles"][2]["position"] = [1500.0, -8500.0, 200.0]  # vehicle 3, 10 km south
    planned = Mission.model_validate(doc)

    async def scenario() -> None:
        service = recording(tmp_path, monkeypatch, [])
        async with service.running():
            report_flying(service, flown)
            mid = service.create_mission(planned).id
            with pytest.raises(Conflict, match="vehicle 3 is 10000 m from its start") as err:
                await service.start(mid)
            assert err.value.detail["misplaced"][0]["vehicle_id"] == 3
            assert service.status(mid)["state"] == "pending"
            status = await service.start(mid, from_where_they_are=True)
            assert status["state"] == "starting"
            started = service.events(mid)[0]
            assert started["kind"] == "run_started"
            assert started["detail"]["from_where_they_are"][0]["keep_out"] == "far"
            service.fleet.by_id.clear()

    asyncio.run(scenario())


def test_obstacles_replaced_mid_run_keep_the_run_s_own_leader(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """After a leader succession the run flies a document of its own (wingman 2 leading);
    ``PUT …/obstacles`` changed the run's document back to the uploaded one, leader and
    all. Now only the obstacles change in it."""
    from gcs_ppf.planning import succession

    monkeypatch.setattr(runs, "load_kernels", lambda planner_dt_s: None)

    async def launch_fleet(station: object, run: Run) -> None:
        return None

    monkeypatch.setattr(flight, "launch_fleet", launch_fleet)
    mission = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())

    async def scenario() -> None:
        service = recording(tmp_path, monkeypatch, [])
        async with service.running():
            report_flying(service, mission)
            mid = service.create_mission(mission).id
            await service.start(mid)
            run = service._runs[mid]
            run.mission = succession.led_by(run.mission, run.mission.vehicles[1])
            service.replace_obstacles(mid, mission.obstacles[:1])
            assert run.mission.leader.id == 2
            assert len(run.mission.obstacles) == 1
            assert run.orders.mission is run.mission
            assert service.mission(mid).mission.leader.id == 1  # the uploaded one
            service.fleet.by_id.clear()

    asyncio.run(scenario())

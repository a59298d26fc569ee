"""The whole product on loopback: ``python -m sitl`` and ``gcs-ppf serve`` as real processes.

An independent pymavlink listener (``gcs_ppf.tools.observer``), connected to every vehicle's own
port, records where the vehicles really flew; the safety checks use its record, not the
service's state.
"""

from __future__ import annotations

import json
import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pymavlink import mavutil

from gcs_ppf.mission import Mission
from gcs_ppf.service.store import Store
from gcs_ppf.tools.campaign import process
from gcs_ppf.tools.demo import FINISHED
from gcs_ppf.tools.demo import http_json as http
from gcs_ppf.tools.observer import (
    Observer,
    closest_pass,
    free_port,
    free_port_block,
    resample,
    tracks_enu,
    vehicle_time_at,
)
from gcs_ppf.tools.observer import formation_offsets as observer_formation_offsets
from tests.checks import wait_for
from tests.conftest import EXAMPLES

SPEEDUP = 10
WATCH_AFTER_S = 5.0  # vehicle seconds the observer keeps listening after a run ends
MISSION = EXAMPLES / "paper_table3.json"


@dataclass
class Flight:
    mission: Mission
    api: str
    mission_id: int
    final: dict[str, Any]
    tracks: dict[int, np.ndarray]
    serve: list[str]
    env: dict[str, str]
    # Per vehicle, [K,2] rows of (our wall-clock s, vehicle s) of the listener's samples.
    clocks: dict[int, np.ndarray] = field(default_factory=dict)


def fly(tmp_path: Path, mission_doc: dict[str, Any], *, sitl_extra: Sequence[str] = (),
        env_extra: dict[str, str] | None = None,
        during: Callable[[str, int], None] | None = None,
        after: Callable[[str, int], None] | None = None,
        links: Sequence[str] | None = None,
        ports_out: dict[int, int] | None = None) -> Flight:  # fmt: skip
    """Start SITL and service, fly ``mission_doc`` to its end, record it independently.
    ``links``: the URLs the service is given (default: each vehicle's TCP port);
    ``ports_out``: filled with each vehicle's TCP port."""
    mission = Mission.model_validate(mission_doc)
    path = tmp_path / "mission.json"
    path.write_text(json.dumps(mission_doc))
    base = free_port_block(10 * len(mission.vehicles))
    api_port = free_port_block(1)
    ports = {v.id: base + 10 * k for k, v in enumerate(mission.vehicles)}
    if ports_out is not None:
        ports_out.update(ports)
    api = f"http://127.0.0.1:{api_port}"
    serve = [sys.executable, "-m", "gcs_ppf.cli", "serve", "--port", str(api_port),
             "--db", str(tmp_path / "gcs.db")]  # fmt: skip
    env = {"GCS_PPF_TLOG_DIR": str(tmp_path / "tlogs"), **(env_extra or {})}
    sitl = [sys.executable, "-m", "sitl", str(path), "--speedup", str(SPEEDUP),
            "--base-port", str(base), *sitl_extra]  # fmt: skip
    # The service first, then the SITL, then the links (as ../shared/tools/fly_check.py
    # does): the SITL's faults are scheduled on its clock from its start, and a service slow
    # to start on a busy machine (5 s with a CPU burner per core) found a vehicle dead.
    with process(serve, tmp_path / "gcs.log", env):
        wait_for(lambda: _up(api), 60, "the service")
        with process(sitl, tmp_path / "sitl.log"):
            wait_for(lambda: "sitl ready" in _text(tmp_path / "sitl.log"), 60, "the SITL")
            urls = [f"tcp:127.0.0.1:{port}" for port in ports.values()] if links is None else links
            for url in urls:
                status, body = http("POST", f"{api}/links", {"url": url})
                assert status == 201, body
            mid, final, tracks, clocks = _fly_started(
                api, mission, mission_doc, ports, during, after
            )
    return Flight(mission, api, mid, final, tracks, serve, env, clocks)


def _fly_started(
    api: str,
    mission: Mission,
    mission_doc: dict[str, Any],
    ports: dict[int, int],
    during: Callable[[str, int], None] | None,
    after: Callable[[str, int], None] | None,
) -> tuple[int, dict[str, Any], dict[int, Any], dict[int, Any]]:
    """With the vehicles on links: the mission uploaded, started and flown to its end, the
    observer listening. Returns (mission id, final status, observer tracks, clocks)."""
    wait_for(lambda: _vehicle_count(api) == len(ports), 60, "vehicles discovered")
    with Observer(ports) as listener:
        status, created = http("POST", f"{api}/missions", mission_doc)
        assert status == 201
        mid = created["id"]
        status, started = http("POST", f"{api}/missions/{mid}/start")
        assert status == 202, started
        if during is not None:
            during(api, mid)
        final = wait_for(lambda: _finished(api, mid), 120, "the mission to finish")
        # The observer hears the vehicles a little after the service did: keep listening
        # until it has WATCH_AFTER_S of vehicle time past the end (check_safety's window).
        end_v = max(listener.latest_boot_ms().values()) / 1000.0
        wait_for(
            lambda: max(listener.latest_boot_ms().values()) / 1000.0 >= end_v + WATCH_AFTER_S,
            30,
            "the observer to hear the run's end",
        )
        if after is not None:
            after(api, mid)
    return mid, final, tracks_enu(listener, mission), listener.clocks()


def _text(path: Path) -> str:
    return path.read_text(errors="replace") if path.exists() else ""


def check_safety(flight: Flight, exclude: Sequence[int] = ()) -> tuple[float, float, float]:
    """Leader through the target; separations and clearances over the run (listener data).
    Returns (start_s, min separation, min clearance)."""
    mission, tracks = flight.mission, {k: v for k, v in flight.tracks.items() if k not in exclude}
    lim = mission.limits
    start_s = min(t[0, 0] for t in tracks.values())
    end_s = min(t[-1, 0] for t in tracks.values())
    assert closest_pass(tracks[mission.leader.id], np.array(mission.target)) <= lim.target_accuracy
    t = np.arange(start_s, end_s, 0.05)
    t = t[t <= start_s + flight.final["mission_time_s"] + 5.0]  # the run, and just after
    pos = resample(tracks, t)
    gaps = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=-1)
    n = pos.shape[1]
    gaps[:, np.arange(n), np.arange(n)] = np.inf
    clearance = min(
        [float((np.linalg.norm(pos - np.array(o.center), axis=-1) - o.radius).min())
         for o in mission.obstacles] or [np.inf]
    )  # fmt: skip
    assert gaps.min() >= lim.safe_distance_uav
    assert clearance >= lim.safe_distance_obstacle
    # The ground (the vehicles' homes): a vehicle keeps the safe distance above it from
    # when it first has it (Table 3 starts wingman 2 at the origin's altitude).
    for sysid, tr in tracks.items():
        height = tr[(tr[:, 0] >= start_s) & (tr[:, 0] <= t[-1]), 4]
        up = np.flatnonzero(height >= lim.safe_distance_obstacle)
        assert up.size, f"vehicle {sysid} never climbed to the safe distance above the ground"
        assert height[up[0] :].min() >= lim.safe_distance_obstacle, f"vehicle {sysid} sank"
    return start_s, float(gaps.min()), clearance


@pytest.mark.integration
def test_table3_flown_closed_loop_is_safe_and_survives_a_restart(tmp_path: Path) -> None:
    flight = fly(tmp_path, json.loads(MISSION.read_text()))
    assert flight.final["state"] == "completed", flight.final
    start_s, separation, clearance = check_safety(flight)
    assert {43001, 43002} <= commands_sent(tmp_path / "tlogs")  # flown by course and altitude

    # Figures for the record: flown time, and how far the flight strayed from the offline
    # plan made from the same start (the vehicles' state when the mission started).
    deviation = deviation_from_offline_plan(
        flight.mission, flight.tracks, start_s, flight.final["mission_time_s"]
    )
    best, closest = formation_offsets(flight, start_s)
    print(
        f"\nflown: mission time {flight.final['mission_time_s']:.1f} s, min separation "
        f"{separation:.1f} m, min clearance {clearance:.1f} m, largest deviation from the "
        f"offline plan {deviation:.0f} m; "
        f"formation: closest {closest:.0f} m (worst wingman), each wingman's best "
        + ", ".join(f"{vid}: {d:.0f} m" for vid, d in best.items())
    )

    # A restarted service still has the mission and the finished run.
    api, mid = flight.api, flight.mission_id
    with process(flight.serve, tmp_path / "gcs2.log", flight.env):
        wait_for(lambda: _up(api), 60, "the restarted service")
        _, missions = http("GET", f"{api}/missions")
        assert [m["id"] for m in missions] == [mid]
        _, runs = http("GET", f"{api}/runs")
        assert [(r["mission_id"], r["state"]) for r in runs] == [(mid, "completed")]
        _, events = http("GET", f"{api}/missions/{mid}/events")
        kinds = [e["kind"] for e in events]
        ended = kinds.index("run_completed")  # then the holds (flown while the service ran)
        assert kinds[ended + 1] == "holds_flown"


def repositions(tlog_dir: Path) -> dict[int, float]:
    """The loiter radius (param3) of the last DO_REPOSITION the service sent each vehicle."""
    radius: dict[int, float] = {}
    for path in tlog_dir.glob("*.tlog"):
        log = mavutil.mavlink_connection(str(path), dialect="ardupilotmega")
        while (msg := log.recv_match(type="COMMAND_INT")) is not None:
            if msg.command == 192:
                radius[int(msg.target_system)] = float(msg.param3)
    return radius


def commands_sent(tlog_dir: Path) -> set[int]:
    """The MAV_CMD numbers of every COMMAND_INT the service's tlogs recorded."""
    sent: set[int] = set()
    for path in tlog_dir.glob("*.tlog"):
        log = mavutil.mavlink_connection(str(path), dialect="ardupilotmega")
        while (msg := log.recv_match(type="COMMAND_INT")) is not None:
            sent.add(int(msg.command))
    return sent


@pytest.mark.integration
def test_guided_points_for_an_arduplane_without_slew_commands(tmp_path: Path) -> None:
    """``GCS_PPF_GUIDANCE=point``: DO_REPOSITION ahead on the plan instead of course and
    altitude; the level formation scene is flown safely to its target.  (Table 3 by guided
    points came to 50.7 and 97.9 m of separation in two runs: the point lags the plan more,
    which is why course and altitude are the default.)"""
    doc = json.loads((EXAMPLES / "paper_table2.json").read_text())
    doc["target"] = [15000.0, 2000.0, 300.0]
    flight = fly(tmp_path, doc, env_extra={"GCS_PPF_GUIDANCE": "point"})
    assert flight.final["state"] == "completed", flight.final
    _, separation, _ = check_safety(flight)
    print(f"\nlevel scene by guided points: mission time {flight.final['mission_time_s']:.1f}"
          f" s, min separation {separation:.1f} m")  # fmt: skip
    sent = commands_sent(tmp_path / "tlogs")
    assert 192 in sent  # MAV_CMD_DO_REPOSITION
    assert not sent & {43001, 43002}  # no GUIDED_CHANGE_ALTITUDE / _HEADING


def fly_formation(tmp_path: Path, doc: dict[str, Any], label: str) -> tuple[Flight, float]:
    """Fly ``doc`` (no obstacles) to completion, check it was safe, print how near the
    wingmen came to their local target points; the worst wingman's closest (m)."""
    flight = fly(tmp_path, doc)
    assert flight.final["state"] == "completed", flight.final
    start_s, separation, _ = check_safety(flight)
    best, closest = formation_offsets(flight, start_s)
    print(
        f"\n{label} flown: mission time {flight.final['mission_time_s']:.1f} s, min "
        f"separation {separation:.1f} m; formation: closest {closest:.1f} m (worst wingman), "
        "each wingman's best " + ", ".join(f"{vid}: {d:.1f} m" for vid, d in best.items())
    )
    return flight, closest


@pytest.mark.integration
def test_table2_flown_closed_loop_and_how_near_the_formation_comes(tmp_path: Path) -> None:
    """The paper's formation scene (no obstacles; offline, with the paper's free pitch, the
    formation forms at 27 s; planned at ArduPlane's 20° it does not within 113 s): safe and
    complete; how near the wingmen come to their slots is printed."""
    fly_formation(tmp_path, json.loads((EXAMPLES / "paper_table2.json").read_text()), "Table 2")


@pytest.mark.integration
def test_the_formation_forms_closed_loop(tmp_path: Path) -> None:
    """Table 2's vehicles with a target 13.5 km straight ahead of the leader at its own
    altitude (offline the formation forms at 27.0 s): flown closed loop, every wingman is
    within the target accuracy of its local target point (Eq. 6, from the leader's track
    as the listener recorded it) at one same moment."""
    doc = json.loads((EXAMPLES / "paper_table2.json").read_text())
    doc["target"] = [15000.0, 2000.0, 300.0]
    flight, closest = fly_formation(tmp_path, doc, "level formation")
    assert closest <= flight.mission.limits.target_accuracy


@pytest.mark.integration
def test_an_obstacle_moved_into_the_path_mid_run_is_avoided(tmp_path: Path) -> None:
    """PUT …/obstacles while flying: a new sphere on the leader's way to the target."""
    doc = json.loads(MISSION.read_text())
    doc["obstacles"] = []
    new = [{"center": [3300.0, 3900.0, 300.0], "radius": 300.0, "velocity": [0, 0, 0]}]

    def move_obstacle(api: str, mid: int) -> None:
        time.sleep(0.5)  # ~5 s of flight at the SITL's 10×
        status, body = http("PUT", f"{api}/missions/{mid}/obstacles", new)
        assert status == 200, body

    flight = fly(tmp_path, doc, during=move_obstacle)
    assert flight.final["state"] == "completed", flight.final
    flight.mission = flight.mission.model_copy(update={"obstacles": Mission.model_validate(
        {**doc, "obstacles": new}).obstacles})  # fmt: skip
    _, separation, clearance = check_safety(flight)
    print(
        f"\nobstacle added mid-run: min clearance {clearance:.1f} m, separation {separation:.1f} m"
    )
    # It stood in the way: the straight line from the leader's start to the target
    # passes through it.
    start, target = np.array(doc["vehicles"][0]["position"]), np.array(doc["target"])
    track = np.stack([start + s * (target - start) for s in np.linspace(0, 1, 1001)])
    blocked = np.linalg.norm(track - np.array(new[0]["center"]), axis=1).min()
    assert blocked < new[0]["radius"]


@pytest.mark.integration
def test_a_wingman_lost_mid_run_leaves_and_the_rest_continue(tmp_path: Path) -> None:
    """Vehicle 3 dies (goes silent) during the run: lost, the mission still completes."""
    flight = fly(
        tmp_path,
        json.loads(MISSION.read_text()),
        sitl_extra=["--fault", "3:die=30"],
    )  # lost after the default 5 s of silence in vehicle time: 0.5 s of ours at 10×
    assert flight.final["state"] == "completed", flight.final
    lost = [v["id"] for v in flight.final["vehicles"] if v["lost"]]
    assert lost == [3]
    check_safety(flight, exclude=[3])
    # Lost after the 5 s timeout counted in vehicle time (the watchdog looks every 0.2 s of
    # ours, 2 s of the SITL's at 10×; the SITL stamps its last messages up to 0.1 s early).
    # Both ends in vehicle time, as the listener heard it (the SITL's vehicles share one
    # clock): vehicle 3's last message, and the leader's clock when the service recorded
    # the event (its wall time).  Not the event's mission time: the run's clock is the
    # telemetry the service has processed, which lags the vehicles when the service does.
    store = Store(tmp_path / "gcs.db")
    run = store.runs(flight.mission_id)[0]
    event = next(e for e in store.events(run.id) if e.kind == "vehicle_lost")
    leader = flight.clocks[flight.mission.leader.id]
    assert leader[0, 0] < event.wall_s < leader[-1, 0]
    declared = vehicle_time_at(leader, event.wall_s)
    last_heard = flight.tracks[3][-1, 0]
    silent = declared - last_heard
    assert event.mission_time_s is not None
    run_clock = run_start_vehicle_time_s(tmp_path / "tlogs", flight.mission.leader.id)
    print(
        f"\nvehicle 3 last heard at {last_heard:.2f} s of vehicle time, declared lost at "
        f"{declared:.2f} s: {silent:.2f} s silent (the run's clock stamped the event "
        f"{run_clock + event.mission_time_s:.2f} s)"
    )
    assert 5.0 - 0.2 <= silent <= 5.0 + 3.0, (declared, last_heard)


RUN_TICK_COMMANDS = {43001, 43002, 192}
"""What a run's tick sends (GUIDED_CHANGE_HEADING/_ALTITUDE, DO_REPOSITION); the launch
sends none of them."""


def run_start_vehicle_time_s(tlog_dir: Path, leader_id: int) -> float:
    """The run's clock origin in vehicle seconds, from the service's tlogs: the first tick
    reads the leader's ``time_boot_ms`` (of its latest message carrying one) and then, with
    no await in between, sends the leader its first command; so it is the ``time_boot_ms``
    of the last leader message the tlog has before that command."""
    for path in sorted(tlog_dir.glob("*.tlog")):
        log = mavutil.mavlink_connection(str(path), dialect="ardupilotmega")
        boot_ms: int | None = None
        while (msg := log.recv_match()) is not None:
            if msg.get_srcSystem() == leader_id and hasattr(msg, "time_boot_ms"):
                boot_ms = int(msg.time_boot_ms)
            elif (msg.get_type() == "COMMAND_INT" and msg.target_system == leader_id
                  and msg.command in RUN_TICK_COMMANDS):  # fmt: skip
                assert boot_ms is not None
                return boot_ms / 1000.0
    raise AssertionError("no command of a run's tick to the leader in the tlogs")


@pytest.mark.integration
def test_a_run_that_outlasts_planner_max_time_fails_and_the_vehicles_hold_clear(
    tmp_path: Path,
) -> None:
    """Failed at max_time: every vehicle is flown to a holding circle chosen clear of the
    obstacles (``gcs_ppf.guidance.holding``), not a plain LOITER around wherever it happens
    to be, and once all fly theirs the circles are handed to the autopilots (GUIDED,
    DO_REPOSITION with its radius; ``holds_loitering``)."""
    doc = json.loads(MISSION.read_text())
    doc["planner"]["max_time"] = 10.0  # the leader needs some 90 s

    def all_hold(api: str, mid: int) -> None:
        def loitering() -> bool:
            _, events = http("GET", f"{api}/missions/{mid}/events")
            return any(e["kind"] == "holds_loitering" for e in events)

        def modes() -> bool:
            _, vehicles = http("GET", f"{api}/vehicles")
            return {v["mode"] for v in vehicles} == {"GUIDED"}

        wait_for(loitering, 120, "the holds handed to the autopilots")
        wait_for(modes, 10, "every vehicle holding in GUIDED")

    flight = fly(tmp_path, doc, after=all_hold)
    holds = repositions(tmp_path / "tlogs")
    assert {v.id for v in flight.mission.vehicles} <= set(holds)
    assert all(radius >= 80.0 for radius in holds.values())
    assert flight.final["state"] == "failed", flight.final
    assert "max_time" in (flight.final["outcome"] or ""), flight.final
    run = Store(tmp_path / "gcs.db").runs(flight.mission_id)[0]
    assert run.state == "failed"
    events = Store(tmp_path / "gcs.db").events(run.id)
    ended = next(e for e in events if e.kind == "run_failed")
    assert ended.mission_time_s is not None
    assert 10.0 <= ended.mission_time_s <= 11.0
    assert [e.kind for e in events if e.kind.startswith("hold")] == [
        "holds_flown",
        "holds_settled",
        "holds_loitering",
    ]


def formation_offsets(flight: Flight, start_s: float) -> tuple[dict[int, float], float]:
    """From the listener's record: each wingman's smallest distance to its local target
    point over the run, and the smallest over time of the worst wingman's distance
    (``gcs_ppf.tools.observer.formation_offsets``)."""
    return observer_formation_offsets(
        flight.mission, flight.tracks, start_s, flight.final["mission_time_s"]
    )


def deviation_from_offline_plan(
    mission: Mission, tracks: dict[int, np.ndarray], start_s: float, duration_s: float
) -> float:
    """Largest distance between flown and offline-planned positions over the run."""
    from gcs_ppf.offline.plan import plan_mission

    doc = mission.model_dump()
    for v in doc["vehicles"]:
        tr = tracks[v["id"]]
        k = int(np.searchsorted(tr[:, 0], start_s))
        a, b = tr[k], tr[min(k + 5, len(tr) - 1)]
        vel = (b[1:4] - a[1:4]) / max(b[0] - a[0], 1e-3)
        v["position"] = tuple(a[1:4])
        v["yaw"] = math.atan2(vel[1], vel[0])
        v["pitch"] = math.atan2(vel[2], math.hypot(vel[0], vel[1]))
        v["speed"] = min(max(float(np.linalg.norm(vel)), mission.limits.v_min),
                         mission.limits.v_max)  # fmt: skip
    plan = plan_mission(Mission.model_validate(doc)).trajectory
    t = plan.t[plan.t <= duration_s]
    flown = resample(tracks, start_s + t)
    return float(np.linalg.norm(flown - plan.pos[: t.shape[0]], axis=-1).max())


def _up(api: str) -> bool:
    try:
        return http("GET", f"{api}/missions")[0] == 200
    except OSError:
        return False


def _vehicle_count(api: str) -> int:
    try:
        status, vehicles = http("GET", f"{api}/vehicles")
    except OSError:
        return 0
    return len(vehicles) if status == 200 else 0


def _finished(api: str, mid: int) -> dict[str, Any] | None:
    """The run's status once it has ended; None while it runs (or if one poll of it fails
    at the socket: a Table 2 run once ended its test 0.3 s in, the service still flying)."""
    try:
        status, s = http("GET", f"{api}/missions/{mid}/status")
    except OSError:
        return None
    return s if status == 200 and s["state"] in FINISHED else None


@pytest.mark.integration
@pytest.mark.campaign
def test_table3_with_every_vehicle_on_one_udp_port(tmp_path: Path) -> None:
    """The SITL's five vehicles each stream from a socket of their own to one UDP port
    (``--out``, as SITL instances stream to a GCS's 14550); the service listens there on one
    ``udpin`` link: five vehicles discovered on it, each commanded where it speaks from, and
    the observer finds the run safe, every command answered.  In ``make campaign-check``
    (``make test`` is near its time budget).  With a CPU burner per core it used to fail:
    asyncio's datagram transport reads one datagram each time the event loop wakes, on
    both ends, and the service's commands at ×10 came faster than the SITL's loop woke
    (4 commands in 10 unanswered, vehicles taken for not responding); both now read the
    whole backlog at a wake-up (``gcs_ppf.datagrams``)."""
    port = free_port()
    seen: dict[str, Any] = {}

    def after(api: str, mid: int) -> None:
        seen["links"] = http("GET", f"{api}/links")[1]
        seen["events"] = http("GET", f"{api}/missions/{mid}/events")[1]

    flight = fly(
        tmp_path,
        json.loads(MISSION.read_text()),
        sitl_extra=["--out", f"udp:127.0.0.1:{port}"],
        links=[f"udpin:127.0.0.1:{port}"],
        after=after,
    )
    assert flight.final["state"] == "completed", flight.final
    (link,) = seen["links"]
    assert link["vehicles"] == [1, 2, 3, 4, 5]
    kinds = [e["kind"] for e in seen["events"]]
    assert "vehicle_not_responding" not in kinds
    _, separation, clearance = check_safety(flight)
    seconds = flight.final["mission_time_s"]
    print(
        f"\none udpin port, five vehicles: completed at {seconds:.1f} s, separation "
        f"{separation:.1f} m, clearance {clearance:.1f} m"
    )

"""Closed-loop campaign: missions flown end to end under stated conditions, judged independently.

``python -m gcs_ppf.tools.campaign [--runs N] [--conditions a,b,c,d,e] [--missions M.json ...]
[--out DIR] [--jobs J]``.  Each run starts ``python -m sitl`` and ``gcs-ppf serve`` on their
own loopback ports, uploads and starts the mission over REST (httpx), and watches every
vehicle's own port with ``gcs_ppf.tools.observer`` from the start of the run until 30 s of vehicle
time after it ends.  A run *violates* when the observer saw two vehicles closer than
``safe_distance_uav`` or a vehicle closer than ``safe_distance_obstacle`` to an obstacle's
surface.  Nothing here reads the service's state to judge: the service's status gives only
the run's end and outcome (and its own figures, recorded beside the observer's).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import numpy as np
from pymavlink import mavutil

from gcs_ppf.mission import Mission
from gcs_ppf.tools.campaign_crash import KINDS as CRASHES
from gcs_ppf.tools.campaign_crash import (
    ServiceProcess,
    crash,
    get_json,
    judge_crash,
    outside_m,
    wait_for,
)
from gcs_ppf.tools.campaign_crash import moment_s as crash_moment_s
from gcs_ppf.tools.campaign_tables import format_tables, progress_line, summarize
from gcs_ppf.tools.observer import (
    FloatArray,
    Judgement,
    Observer,
    free_port_block,
    held_s,
    judge,
    slot_distances,
    tracks_enu,
)

ROOT = Path(__file__).resolve().parents[2]  # the repository (gcs_ppf/tools/ → ../..)
EXAMPLES = ROOT / "examples"
DEFAULT_MISSIONS = ("paper_table3", "paper_table2", "scene_head_on", "scene_narrow_gap")
FINISHED = ("completed", "completed_unsafe", "aborted", "failed", "interrupted")
AFTER_S = 30.0  # vehicle seconds watched after a run ends
INJECTOR_SYSID = 203  # sends the run-time faults; neither a vehicle, the service nor the observer
LOST_TIMEOUT_S = 5.0  # the service's default vehicle_timeout_s
LOST_SLACK_S = 3.0  # the allowance the integration test gives the lost declaration


@dataclass(frozen=True)
class Condition:
    """How a run is flown.  ``event`` is done ``event_at_s`` of mission time into the run:
    ``stuck`` makes the last wingman ignore commands (SIM_CMD_IGNORE=1, the SITL's
    ``ignore`` fault from then on), ``kill`` makes the leader die (SIM_KILL=1, the ``die``
    fault from then on); the ``crash_…`` events kill the service (``campaign_crash``).
    ``expect`` is the outcome a good run ends with."""

    key: str
    label: str
    speedup: float
    sitl_args: tuple[str, ...] = ()
    burn_cpus: bool = False
    event: str | None = None
    expect: str = "completed"
    radios: str = ""
    """``"each"``: each vehicle on a telemetry radio of its own, ``"one"``: one radio
    carrying them all; a radio is a pty pair (Debian's socat) at ``RADIO_BAUD``, carrying
    what such a radio does (the SITL's ``--radio``), the service linked by ``serial:``; the
    observer stays on the vehicles' TCP ports."""
    service_env: tuple[tuple[str, str], ...] = ()
    """The service's settings for the condition (``GCS_PPF_…`` variables)."""


RADIO_BAUD = 57600


FAILSAFE = ("--param", "FS_GCS_ENABL=1")  # ArduPlane's GCS failsafe: RTL after 5 s of silence

CONDITIONS: dict[str, Condition] = {
    "a": Condition("a", "x10, idle", 10.0),
    "b": Condition("b", "x10, a CPU burner per core", 10.0, burn_cpus=True),
    "c": Condition("c", "x5, latency 300 ms, 20 % loss", 5.0, ("--fault", "latency=300,loss=20")),
    "d": Condition("d", "x10, a wingman ignores commands", 10.0, event="stuck"),
    "e": Condition("e", "x10, the leader's link dies (a wingman leads on)", 10.0, event="kill"),
    "f": Condition("f", "x5, idle", 5.0),
    "g": Condition("g", "x5, a CPU burner per core", 5.0, burn_cpus=True),
    "h": Condition("h", "x1, idle", 1.0),  # fleets too large for the tick at 5x (issue 29)
    "i": Condition("i", "x5, latency 100 ms", 5.0, ("--fault", "latency=100")),
    # the service killed mid-run (issue 26 item 3), the vehicles' GCS failsafe on
    "j": Condition(
        "j",
        "x10, the service killed, started again, the run resumed",
        10.0,
        FAILSAFE,
        event="crash_resume",
    ),
    "k": Condition(
        "k",
        "x10, the service killed, started again, the run aborted",
        10.0,
        FAILSAFE,
        event="crash_abort",
        expect="aborted",
    ),
    "l": Condition(
        "l",
        "x10, the service killed and left dead (GCS failsafe)",
        10.0,
        FAILSAFE,
        event="crash_dead",
        expect="failsafe",
    ),
    "m": Condition(
        "m",
        "x10, the service killed and left dead, no GCS failsafe (the vehicles' fences)",
        10.0,
        event="crash_fenced",
        expect="fenced",
    ),
    # issue 30: what a 57,600-baud radio carries, one a vehicle
    "n": Condition("n", "x10, each vehicle on its own 57,600-baud radio", 10.0, radios="each"),
    "o": Condition(
        "o",
        "x10, every vehicle on one 57,600-baud radio, streams and ticks at 5 Hz",
        10.0,
        radios="one",
        service_env=(("GCS_PPF_STREAM_RATE_HZ", "5"), ("GCS_PPF_TICK_HZ", "5")),
    ),
    "p": Condition(
        "p",
        "x10, every vehicle on one 57,600-baud radio, rates fitted by the service",
        10.0,
        radios="one",
    ),
}


@contextmanager
def process(
    args: Sequence[str], log: Path, env: dict[str, str] | None = None
) -> Iterator[subprocess.Popen[bytes]]:
    """A child process (its output appended to ``log``) for the duration of the block,
    then ``stop``ped."""
    with log.open("a") as out:
        p = subprocess.Popen(
            list(args),
            stdout=out,
            stderr=subprocess.STDOUT,
            cwd=ROOT,
            env={**os.environ, **(env or {})},
        )
        try:
            yield p
        finally:
            stop(p)


def stop(p: subprocess.Popen[bytes]) -> None:
    """SIGTERM, then SIGKILL after 10 s, unless it has already exited."""
    if p.poll() is None:
        p.terminate()
        try:
            p.wait(timeout=10)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


@contextmanager
def radio(directory: Path, name: str) -> Iterator[tuple[Path, Path]]:
    """A pty pair standing in for two telemetry radios (socat): (the vehicle's end, the
    ground's end), for the block's duration."""
    if shutil.which("socat") is None:
        raise RuntimeError("the radio conditions need Debian's socat (make install adds it)")
    directory = directory.resolve()  # the service opens the path it is given: absolute
    air, ground = directory / f"{name}-air", directory / f"{name}-ground"
    args = ["socat", f"pty,raw,echo=0,link={air}", f"pty,raw,echo=0,link={ground}"]
    with process(args, directory / f"{name}-socat.log") as p:
        wait_for(lambda: (air.exists() and ground.exists()) or p.poll() is not None, 10, "socat")
        if p.poll() is not None:
            raise RuntimeError(f"socat exited ({p.returncode}): see {name}-socat.log")
        yield air, ground


@contextmanager
def cpu_burners(count: int) -> Iterator[None]:
    """``count`` processes each burning a core (``python3 -c 'while True: pass'``)."""
    procs = [subprocess.Popen(["python3", "-c", "while True: pass"]) for _ in range(count)]
    try:
        yield
    finally:
        for p in procs:
            p.kill()
        for p in procs:
            p.wait()


def set_param(port: int, sysid: int, name: str, value: float, *, until_silent: bool) -> None:
    """PARAM_SET ``name`` on the vehicle at ``port`` until it confirms (its PARAM_VALUE), or
    with ``until_silent`` until it falls silent (SIM_KILL answers nothing)."""
    conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=INJECTOR_SYSID)
    try:
        for _ in range(20):
            conn.mav.param_set_send(sysid, 1, name.encode(), value, 2)
            deadline = time.monotonic() + 1.0
            heard = confirmed = False
            while time.monotonic() < deadline:
                msg = conn.recv_match(blocking=True, timeout=0.2)
                if msg is None or msg.get_srcSystem() != sysid:
                    continue
                heard = True
                if msg.get_type() == "PARAM_VALUE" and msg.param_id == name:
                    confirmed = msg.param_value == value
            if (until_silent and not heard) or (not until_silent and confirmed):
                return
        raise TimeoutError(f"vehicle {sysid} did not take {name}={value:g}")
    finally:
        conn.close()


def fly_once(
    mission_path: Path,
    cond: Condition,
    workdir: Path,
    *,
    event_at_s: float = 15.0,
    after_s: float = AFTER_S,
    seed: int = 0,
) -> dict[str, Any]:
    """Fly ``mission_path`` once under ``cond`` in ``workdir``; the run's record (JSON-able).
    ``seed`` seeds the SITL's packet loss and noise: runs with one seed lose the same
    packets, so each run of a campaign gets its own."""
    workdir.mkdir(parents=True, exist_ok=True)
    if cond.event in CRASHES:  # a moment of its own for each run
        event_at_s = crash_moment_s(seed)
    doc = json.loads(mission_path.read_text())
    mission = Mission.model_validate(doc)
    base = free_port_block(10 * len(mission.vehicles))
    api_port = free_port_block(1)
    ports = {v.id: base + 10 * k for k, v in enumerate(mission.vehicles)}
    rec: dict[str, Any] = {
        "mission": mission.name,
        "mission_file": str(mission_path),
        "condition": cond.key,
        "dir": str(workdir),
    }
    sitl = [
        sys.executable,
        "-m",
        "sitl",
        str(mission_path),
        "--speedup",
        f"{cond.speedup:g}",
        "--base-port",
        str(base),
        "--seed",
        str(seed),
        *cond.sitl_args,
    ]
    serve = [
        sys.executable,
        "-m",
        "gcs_ppf.cli",
        "serve",
        "--port",
        str(api_port),
        "--db",
        str(workdir / "gcs.db"),
    ]
    budget_s = (mission.planner.max_time + 60.0) / cond.speedup * 2.0 + 60.0
    t_total = time.monotonic()
    url = f"http://127.0.0.1:{api_port}"
    with ExitStack() as stack, httpx.Client(base_url=url, timeout=5.0) as api:
        links = [f"tcp:127.0.0.1:{p}" for p in ports.values()]
        if cond.radios:
            names = [f"radio{vid}" for vid in ports] if cond.radios == "each" else ["radio"]
            pairs = [stack.enter_context(radio(workdir, name)) for name in names]
            sitl += [a for air, _ in pairs for a in ("--serial", f"{air}:{RADIO_BAUD}")]
            sitl.append("--radio")
            links = [f"serial:{ground}:{RADIO_BAUD}" for _, ground in pairs]
        obs, service = _start_processes(
            stack, api, sitl, serve, workdir, ports, links, dict(cond.service_env)
        )
        flight = _fly(
            api, doc, mission, cond, ports, obs, service, budget_s, event_at_s, after_s, rec
        )
    rec["total_wall_s"] = round(time.monotonic() - t_total, 1)
    raw = {v: {"pos": r.pos, "texts": r.texts, "modes": r.modes} for v, r in obs.records.items()}
    (workdir / "observer.json").write_text(json.dumps({"end_wall": flight.end_wall, **raw}))
    status, event = flight.status, flight.event
    rec.update(
        state=status.get("state", "no status"),
        outcome=status.get("outcome"),
        mission_time_s=round(flight.mission_time_s, 1),
        event=event,
        service={
            k: status.get(k)
            for k in ("min_separation_m", "min_obstacle_clearance_m", "safety_violations")
        },
    )
    if status.get("state") not in FINISHED:
        rec["state"] = f"not finished after {budget_s:.0f} s"
    _judge_run(rec, flight, obs, mission, after_s)
    if cond.event in CRASHES:
        crashed_ok = judge_crash(rec, obs, event)
        _judge_down(rec, obs, mission, flight, after_s)
        if mission.zones and event is not None:
            tracks = tracks_enu(obs, mission)
            rec["outside_zones_m"] = outside_m(mission, tracks, float(event["vehicle_s"]))
        rec["ok"] = (
            rec["state"] == cond.expect and crashed_ok and not rec.get("violations_commanded")
        )
    else:
        rec["ok"] = rec["state"] == cond.expect
    if cond.event == "kill":
        handed = flight.handed_over_wall
        rec["ok"] = rec["ok"] and _handed_over_in_time(rec, obs, mission, event, handed)
    return rec


@dataclass(frozen=True)
class Flight:
    """What a run left for judging: the service's last status and the event injected, the
    watch window in vehicle seconds (the start, the end seen by the status poll), the
    end and the first leader succession (None: none) in wall time (``time.time()``)."""

    status: dict[str, Any]
    event: dict[str, Any] | None
    start_v: float
    end_v: float
    end_wall: float
    handed_over_wall: float | None = None
    event_walls: tuple[tuple[str, float], ...] = ()
    """(kind, wall time) of every event the service answered at the end."""

    @property
    def mission_time_s(self) -> float:
        return float(self.status.get("mission_time_s") or 0.0)


def _start_processes(
    stack: ExitStack,
    api: httpx.Client,
    sitl: list[str],
    serve: list[str],
    workdir: Path,
    ports: dict[int, int],
    links: list[str],
    service_env: dict[str, str],
) -> tuple[Observer, ServiceProcess]:
    """Start the service and the SITL in ``stack``, link the service to every vehicle (by
    ``links``), and the observer (on ``ports``) once the vehicles are discovered and
    heard."""
    # The service first: the vehicles fly straight on from their start states until the
    # run starts, so the SITL starts only once the service is up (its first start may
    # compile the planner), and the service connects to it then.
    env = {"GCS_PPF_TLOG_DIR": str(workdir / "tlogs"), **service_env}
    service = ServiceProcess(stack, lambda: process(serve, workdir / "serve.log", env))
    service.start()
    wait_for(lambda: get_json(api, "/missions") is not None, 180, "the service")
    sitl_log = workdir / "sitl.log"
    stack.enter_context(process(sitl, sitl_log))
    wait_for(lambda: "sitl ready" in sitl_log.read_text(), 60, "the SITL")
    for link in links:
        api.post("/links", json={"url": link}).raise_for_status()
    obs = stack.enter_context(Observer(ports))
    wait_for(lambda: len(get_json(api, "/vehicles") or []) == len(ports), 60, "vehicles discovered")
    wait_for(lambda: all(obs.latest_boot_ms().values()), 30, "the observer's first samples")
    return obs, service


def _fly(
    api: httpx.Client,
    doc: dict[str, Any],
    mission: Mission,
    cond: Condition,
    ports: dict[int, int],
    obs: Observer,
    service: ServiceProcess,
    budget_s: float,
    event_at_s: float,
    after_s: float,
    rec: dict[str, Any],
) -> Flight:
    """Upload and start the mission, inject the condition's event on time, wait for the end
    (or ``budget_s``) and ``after_s`` of vehicle time more; ``rec`` gets the run's wall
    time and the service's events."""
    r = api.post("/missions", json=doc)
    r.raise_for_status()
    mid = r.json()["id"]
    start_v = max(obs.latest_boot_ms().values()) / 1000.0
    t0 = time.monotonic()
    r = api.post(f"/missions/{mid}/start")
    r.raise_for_status()
    status: dict[str, Any] = {}
    event: dict[str, Any] | None = None
    while time.monotonic() - t0 < budget_s:
        status = get_json(api, f"/missions/{mid}/status") or status
        if status.get("state") in FINISHED:
            break
        if cond.event and event is None and (status.get("mission_time_s") or 0) >= event_at_s:
            if cond.event in CRASHES:
                ids = [v.id for v in mission.vehicles]
                event = crash(cond.event, api, mid, service, obs, ids, status, cond.speedup)
                if cond.event in ("crash_dead", "crash_fenced"):
                    break
            else:
                event = _inject(cond.event, mission, ports, obs, status)
        time.sleep(0.1)
    end_wall = time.time()
    rec["wall_s"] = round(time.monotonic() - t0, 1)
    end_v = max(obs.latest_boot_ms().values()) / 1000.0
    wait_for(
        lambda: max(obs.latest_boot_ms().values()) / 1000.0 >= end_v + after_s,
        after_s / cond.speedup * 4 + 30,
        "vehicle time after the end",
    )
    # the service watches after the end too: a violation then makes a completed run
    # completed_unsafe, so its last word is read after the watch
    status = get_json(api, f"/missions/{mid}/status") or status
    events = get_json(api, f"/missions/{mid}/events") or []
    rec["events"] = [(e["kind"], e["vehicle_id"]) for e in events]
    ended = [e["wall_s"] for e in events if e["kind"] in {f"run_{s}" for s in FINISHED}]
    if ended:  # the service's own moment (the status poll may be held up by an event)
        end_wall = min(end_wall, min(ended))
    handed = [e["wall_s"] for e in events if e["kind"] == "leader_succeeded"]
    walls = tuple((e["kind"], e["wall_s"]) for e in events)
    return Flight(status, event, start_v, end_v, end_wall, min(handed, default=None), walls)


def _judge_run(
    rec: dict[str, Any], flight: Flight, obs: Observer, mission: Mission, after_s: float
) -> None:
    """The observer's judgement of the run into ``rec``: the window watched, separation and
    clearance (a stuck wingman's apart: it is not controlled), the lowest heights, the
    leader's distance to the target, the violations of the safe distances, who sank."""
    tracks = tracks_enu(obs, mission)
    end_v = flight.end_v
    j = judge(
        mission, tracks, flight.start_v, end_v + after_s, run_start_s=end_v - flight.mission_time_s
    )
    lim = mission.limits
    event = flight.event
    uncontrolled = [event["vehicle"]] if event and event["kind"] == "stuck" else []
    clearance = j.min_clearance_m(exclude=uncontrolled)
    rec.update(
        window_s=[round(flight.start_v, 1), round(end_v + after_s, 1)],
        samples=j.samples,
        min_separation_m=_r(j.min_separation_m),
        closest_pair=j.closest_pair,
        min_clearance_m=_r(clearance),
        uncontrolled_clearance_m=_r(
            min(
                (c for v, c in j.clearance_m.items() if v in uncontrolled and c is not None),
                default=None,
            )
        ),
        lowest_height_m={v: _r(h) for v, h in j.lowest_m.items()},
        leader_to_target_m=_r(j.leader_to_target_m),
    )
    rec["violations"] = violations_of(j, mission, uncontrolled)
    rec["sank"] = [
        v for v, h in j.lowest_m.items() if h is not None and h < lim.safe_distance_obstacle
    ]
    rec["formation_m"], rec["formation_held_s"] = formation_seen(
        mission, tracks, flight.start_v, end_v
    )


def violations_of(j: Judgement, mission: Mission, uncontrolled: Sequence[int] = ()) -> list[str]:
    """The safe distances the observer saw broken, in words (``uncontrolled`` vehicles'
    clearance apart)."""
    lim = mission.limits
    out = []
    if j.min_separation_m is not None and j.min_separation_m < lim.safe_distance_uav:
        out.append(f"separation {j.min_separation_m:.1f} m {j.closest_pair}")
    for v, c in j.clearance_m.items():
        if c is not None and c < lim.safe_distance_obstacle and v not in uncontrolled:
            out.append(f"vehicle {v} clearance {c:.1f} m")
    return out


def formation_seen(
    mission: Mission, tracks: dict[int, FloatArray], start_s: float, end_s: float
) -> tuple[float | None, float | None]:
    """The formation as the observer saw it during the run, [start_s, end_s] of vehicle
    time: the worst wingman's distance from its slot (Eq. 6) at the best moment, and the
    longest time every wingman stayed within the target accuracy at once.  None for a
    lone leader, or a vehicle never heard."""
    ids = [mission.leader.id, *(w.id for w in mission.wingmen)]
    if not mission.wingmen or end_s <= start_s or any(len(tracks.get(v, ())) == 0 for v in ids):
        return None, None
    step = 0.1
    offsets = slot_distances(mission, {v: tracks[v] for v in ids}, np.arange(start_s, end_s, step))
    worst = np.max(np.stack(list(offsets.values())), axis=0)
    return _r(float(worst.min())), _r(held_s(worst, mission.limits.target_accuracy, step))


def _judge_down(
    rec: dict[str, Any], obs: Observer, mission: Mission, flight: Flight, after_s: float
) -> None:
    """A crash's run split where the service did not command the vehicles (from the kill
    until the run flew again after the restart, or the abort's holds; to the watch's end
    when left dead) and where it did: each part's violations."""
    event = flight.event
    if event is None:
        return
    tracks = tracks_enu(obs, mission)
    killed_v, end_v = float(event["vehicle_s"]), flight.end_v + after_s
    back = [w for k, w in flight.event_walls if k in ("run_running", "holds_flown")]
    back = [w for w in back if w > float(event["wall_s"])]
    clock = max(obs.clocks().values(), key=len)
    back_v = float(np.interp(min(back), clock[:, 0], clock[:, 1])) if back else end_v
    down = judge(mission, tracks, killed_v, back_v)
    rec["down"] = {
        "window_s": [round(killed_v, 1), round(back_v, 1)],
        "min_separation_m": _r(down.min_separation_m),
        "min_clearance_m": _r(down.min_clearance_m()),
        "violations": violations_of(down, mission),
    }
    commanded = [judge(mission, tracks, flight.start_v, killed_v)]
    if back_v < end_v:
        commanded.append(judge(mission, tracks, back_v, end_v))
    rec["violations_commanded"] = [v for j in commanded for v in violations_of(j, mission)]


def _r(x: float | None) -> float | None:
    return None if x is None else round(x, 1)


def _inject(
    kind: str, mission: Mission, ports: dict[int, int], obs: Observer, status: dict[str, Any]
) -> dict[str, Any]:
    """Do the condition's mid-run event now; what was done, and when (vehicle s)."""
    vid = mission.wingmen[-1].id if kind == "stuck" else mission.leader.id
    name = "SIM_CMD_IGNORE" if kind == "stuck" else "SIM_KILL"
    set_param(ports[vid], vid, name, 1.0, until_silent=kind == "kill")
    return {
        "kind": kind,
        "vehicle": vid,
        "mission_time_s": status.get("mission_time_s"),
        "vehicle_s": max(obs.latest_boot_ms().values()) / 1000.0,
    }


def _handed_over_in_time(
    rec: dict[str, Any],
    obs: Observer,
    mission: Mission,
    event: dict[str, Any] | None,
    handed_over_wall: float | None,
) -> bool:
    """Condition (e): a wingman led (``leader_succeeded``) within the lost-vehicle timeout
    (+ slack) of the leader's last message, in vehicle time: the event's wall time dated on
    a live vehicle's clock."""
    if event is None or handed_over_wall is None:
        rec["handover_delay_s"] = None
        return False
    clocks = obs.clocks()
    lead = clocks[mission.leader.id]
    alive = max((c for v, c in clocks.items() if v != mission.leader.id), key=len)
    silent_from = float(lead[-1, 1])
    handed = float(np.interp(handed_over_wall, alive[:, 0], alive[:, 1]))
    rec["handover_delay_s"] = round(handed - silent_from, 1)
    return bool(handed - silent_from <= LOST_TIMEOUT_S + LOST_SLACK_S)


# ---- the campaign ------------------------------------------------------------------------
def mission_path(name: str) -> Path:
    """A mission file, or the name of one in examples/ (``paper_table3``)."""
    p = Path(name)
    return p.resolve() if p.suffix == ".json" else EXAMPLES / f"{name}.json"


def run_campaign(
    missions: Sequence[Path],
    conditions: Sequence[str],
    runs: int,
    out: Path,
    *,
    jobs: int = 1,
    event_at_s: float = 15.0,
    progress: Callable[[str], None] = print,
    after_s: float = AFTER_S,
) -> list[dict[str, Any]]:
    """Fly every mission ``runs`` times under every condition; each run's record is
    appended to ``out/runs.jsonl`` as it ends, the summary written to ``out/summary.json``
    and the tables to ``out/table.txt``."""
    out.mkdir(parents=True, exist_ok=True)
    results: list[dict[str, Any]] = []
    total = len(missions) * len(conditions) * runs
    stamp = time.strftime("%Y%m%d-%H%M%S")
    for key in conditions:
        cond = CONDITIONS[key]
        with cpu_burners((os.cpu_count() or 1) if cond.burn_cpus else 0):
            jobs_list = [(m, k) for m in missions for k in range(runs)]

            def one(job: tuple[Path, int], cond: Condition = cond) -> dict[str, Any]:
                m, k = job
                workdir = out / stamp / f"{m.stem}-{cond.key}-{k}"
                try:
                    rec = fly_once(m, cond, workdir, event_at_s=event_at_s, seed=k, after_s=after_s)
                except Exception as exc:  # a broken run is a result too
                    rec = {
                        "mission": m.stem,
                        "condition": cond.key,
                        "dir": str(workdir),
                        "state": "error",
                        "error": repr(exc),
                        "ok": False,
                        "violations": [],
                    }
                rec["run"] = k
                return rec

            with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
                for rec in pool.map(one, jobs_list):
                    results.append(rec)
                    with (out / "runs.jsonl").open("a") as f:
                        f.write(json.dumps(rec) + "\n")
                    progress(f"[{len(results)}/{total}] {progress_line(rec)}")
    summary = summarize(results, CONDITIONS)
    (out / "summary.json").write_text(json.dumps(summary, indent=1))
    (out / "table.txt").write_text(format_tables(summary))
    return results


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m gcs_ppf.tools.campaign",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--runs", type=int, default=3, help="runs per mission and condition")
    labels = "; ".join(f"{c.key}: {c.label}" for c in CONDITIONS.values())
    p.add_argument("--conditions", default="a,b,c,d,e", help=labels.replace("%", "%%"))
    p.add_argument(
        "--missions",
        nargs="+",
        default=list(DEFAULT_MISSIONS),
        help="mission files, or names in examples/",
    )
    p.add_argument("--out", type=Path, default=Path("out/campaign"))
    p.add_argument("--jobs", type=int, default=1, help="runs at once (the default 1 suits 2 cores)")
    p.add_argument(
        "--event-at",
        type=float,
        default=15.0,
        help="mission time (s) of (d)'s stuck wingman, (e)'s dead leader",
    )
    p.add_argument("--after", type=float, default=AFTER_S, help="vehicle s watched after the end")
    a = p.parse_args(argv)
    conditions = [c.strip() for c in a.conditions.split(",") if c.strip()]
    unknown = [c for c in conditions if c not in CONDITIONS]
    if unknown or a.runs < 1:
        p.error(f"unknown conditions {unknown}" if unknown else "--runs must be at least 1")
    missions = [mission_path(m) for m in a.missions]
    for m in missions:
        if not m.is_file():
            p.error(f"no mission file {m}")
    results = run_campaign(
        missions, conditions, a.runs, a.out, jobs=a.jobs, event_at_s=a.event_at, after_s=a.after
    )
    print(format_tables(summarize(results, CONDITIONS)), end="")
    print(f"runs: {a.out / 'runs.jsonl'}; summary: {a.out / 'summary.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The whole product on loopback: ``python -m sitl`` and ``gcs-ppf serve`` as real processes.

An independent pymavlink listener, connected to every vehicle's own port, records where
the vehicles really flew; the safety checks use its record, not the service's state.
"""

from __future__ import annotations

import json
import math
import os
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pymavlink import mavutil

from gcs_ppf.geodesy import geodetic_to_enu
from gcs_ppf.mission import Mission, load_mission_file
from tests.conftest import EXAMPLES, ROOT

SPEEDUP = 10
MISSION = EXAMPLES / "paper_table3.json"


def free_port_block(span: int) -> int:
    """A base port P with P … P+span free on 127.0.0.1 (best effort)."""
    for _ in range(50):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            base = int(s.getsockname()[1])
        if base + span >= 65000:
            continue
        try:
            for p in range(base, base + span + 1, 10):
                with socket.socket() as t:
                    t.bind(("127.0.0.1", p))
            return base
        except OSError:
            continue
    raise RuntimeError("no free port block")


class Listener:
    """Records GLOBAL_POSITION_INT of each vehicle from its own TCP port."""

    def __init__(self, ports: dict[int, int]) -> None:
        self.samples: dict[int, list[tuple[int, float, float, float]]] = {i: [] for i in ports}
        self._stop = threading.Event()
        self._threads = [
            threading.Thread(target=self._run, args=(sysid, port), daemon=True)
            for sysid, port in ports.items()
        ]

    def _run(self, sysid: int, port: int) -> None:
        conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=201)
        try:
            while not self._stop.is_set():
                msg = conn.recv_match(type="GLOBAL_POSITION_INT", blocking=True, timeout=0.5)
                if msg is not None and msg.get_srcSystem() == sysid:
                    self.samples[sysid].append(
                        (msg.time_boot_ms, msg.lat * 1e-7, msg.lon * 1e-7, msg.alt * 1e-3)
                    )
        finally:
            conn.close()

    def __enter__(self) -> Listener:
        for t in self._threads:
            t.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(timeout=5)


def http(method: str, url: str, body: Any = None) -> tuple[int, Any]:
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(url, data=data, method=method,
                                 headers={"content-type": "application/json"})  # fmt: skip
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, json.loads(r.read() or b"null")
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read() or b"null")


@contextmanager
def process(args: list[str], log: Path, env: dict[str, str] | None = None) -> Iterator[None]:
    with log.open("w") as out:
        p = subprocess.Popen(args, stdout=out, stderr=subprocess.STDOUT, cwd=ROOT,
                             env={**os.environ, **(env or {})})  # fmt: skip
        try:
            yield
        finally:
            p.terminate()
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()


def wait_for(predicate: Any, timeout_s: float, what: str) -> Any:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.1)
    raise AssertionError(f"timed out waiting for {what}")


def tracks_enu(listener: Listener, mission: Mission) -> dict[int, np.ndarray]:
    """Per vehicle, [K,4] rows of (time_s, x, y, z) in the mission's ICS."""
    out = {}
    for sysid, rows in listener.samples.items():
        out[sysid] = np.array([(t / 1000.0, *geodetic_to_enu(la, lo, al, mission.origin))
                               for t, la, lo, al in rows])  # fmt: skip
    return out


def closest_pass(track: np.ndarray, point: np.ndarray) -> float:
    """Smallest distance from ``point`` to the polyline of ``track`` positions."""
    p = track[:, 1:4]
    a, b = p[:-1], p[1:]
    seg = b - a
    length2 = np.maximum((seg**2).sum(axis=1), 1e-12)
    s = np.clip(((point - a) * seg).sum(axis=1) / length2, 0.0, 1.0)
    return float(np.linalg.norm(a + s[:, None] * seg - point, axis=1).min())


def resample(tracks: dict[int, np.ndarray], t: np.ndarray) -> np.ndarray:
    """Positions [T,N,3] of every vehicle at common times t (linear interpolation)."""
    ids = sorted(tracks)
    return np.stack([
        np.stack([np.interp(t, tracks[i][:, 0], tracks[i][:, c]) for c in (1, 2, 3)], axis=1)
        for i in ids
    ], axis=1)  # fmt: skip


@pytest.mark.integration
def test_table3_flown_closed_loop_is_safe_and_survives_a_restart(tmp_path: Path) -> None:
    mission = load_mission_file(MISSION)
    base = free_port_block(10 * len(mission.vehicles))
    api_port = free_port_block(1)
    ports = {v.id: base + 10 * k for k, v in enumerate(mission.vehicles)}
    api = f"http://127.0.0.1:{api_port}"
    serve = [sys.executable, "-m", "gcs_ppf.cli", "serve", "--port", str(api_port),
             "--db", str(tmp_path / "gcs.db")] + [
        arg for p in ports.values() for arg in ("--link", f"tcp:127.0.0.1:{p}")]  # fmt: skip
    env = {"GCS_PPF_TLOG_DIR": str(tmp_path / "tlogs")}
    sitl = [sys.executable, "-m", "sitl", str(MISSION), "--speedup", str(SPEEDUP),
            "--base-port", str(base)]  # fmt: skip

    with process(sitl, tmp_path / "sitl.log"), process(serve, tmp_path / "gcs.log", env):
        wait_for(lambda: _vehicle_count(api) == len(ports), 60, "vehicles discovered")
        with Listener(ports) as listener:
            status, created = http("POST", f"{api}/missions", json.loads(MISSION.read_text()))
            assert status == 201
            mid = created["id"]
            status, started = http("POST", f"{api}/missions/{mid}/start")
            assert status == 202, started
            final = wait_for(lambda: _finished(api, mid), 120, "the mission to finish")
        assert final["state"] == "completed", final

    tracks = tracks_enu(listener, mission)
    start_s = min(t[0, 0] for t in tracks.values())
    end_s = min(t[-1, 0] for t in tracks.values())
    lim = mission.limits
    leader = tracks[mission.leader.id]
    assert closest_pass(leader, np.array(mission.target)) <= lim.target_accuracy
    t = np.arange(start_s, end_s, 0.05)
    pos = resample(tracks, t)
    flying = t <= start_s + final["mission_time_s"] + 5.0  # the run and its first seconds after
    gaps = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=-1)
    n = pos.shape[1]
    gaps[:, np.arange(n), np.arange(n)] = np.inf
    assert gaps[flying].min() >= lim.safe_distance_uav
    for o in mission.obstacles:
        clearance = np.linalg.norm(pos[flying] - np.array(o.center), axis=-1) - o.radius
        assert clearance.min() >= lim.safe_distance_obstacle

    # Figures for the record: flown time, and how far the flight strayed from the offline
    # plan made from the same start (the vehicles' state when the mission started).
    deviation = deviation_from_offline_plan(mission, tracks, start_s, final["mission_time_s"])
    print(
        f"\nflown: mission time {final['mission_time_s']:.1f} s, min separation "
        f"{gaps[flying].min():.1f} m, largest deviation from the offline plan "
        f"{deviation:.0f} m"
    )

    # A restarted service still has the mission and the finished run.
    with process(serve[: -2 * len(ports)], tmp_path / "gcs2.log", env):
        wait_for(lambda: _up(api), 60, "the restarted service")
        status, missions = http("GET", f"{api}/missions")
        assert [m["id"] for m in missions] == [mid]
        status, runs = http("GET", f"{api}/runs")
        assert [(r["mission_id"], r["state"]) for r in runs] == [(mid, "completed")]
        status, events = http("GET", f"{api}/missions/{mid}/events")
        assert events[-1]["kind"] == "run_completed"


def deviation_from_offline_plan(
    mission: Mission, tracks: dict[int, np.ndarray], start_s: float, duration_s: float
) -> float:
    """Largest distance between flown and offline-planned positions over the run."""
    from gcs_ppf.offline import plan_mission

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
    status, s = http("GET", f"{api}/missions/{mid}/status")
    return s if status == 200 and s["state"] in ("completed", "aborted", "failed") else None

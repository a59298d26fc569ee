"""``gcs-ppf demo``: the built-in SITL, the service, a mission flown live (``make run``).

Starts ``python -m sitl MISSION`` and ``gcs-ppf serve`` connected to every vehicle,
uploads and starts the mission over REST, prints progress, and stops both on Ctrl-C.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

from gcs_ppf.mission import Mission

FINISHED = ("completed", "completed_unsafe", "aborted", "failed", "interrupted")


def http_json(method: str, url: str, body: Any = None, token: str | None = None) -> tuple[int, Any]:
    """One JSON request, with ``token`` as its bearer token when given; (status, body)."""
    data = None if body is None else json.dumps(body).encode()
    headers = {"content-type": "application/json"}
    if token is not None:
        headers["authorization"] = f"Bearer {token}"
    req = urllib.request.Request(url, data=data, method=method, headers=headers)
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status, json.loads(r.read() or b"null")
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read() or b"null")


def _wait_vehicles(api: str, n: int, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            status, vehicles = http_json("GET", f"{api}/vehicles")
            if status == 200 and len(vehicles) >= n:
                return True
        except OSError:
            pass
        time.sleep(0.2)
    return False


def formation_line(formation: dict[str, Any] | None) -> str:
    """The formation now, from the status: the worst wingman's slot error and the hold."""
    if not formation or formation.get("worst_error_m") is None:
        return "formation -"
    mark = "formed" if formation.get("formed") else "not formed"
    worst, held = formation["worst_error_m"], formation.get("current_hold_s") or 0.0
    wingman = formation.get("worst_wingman_id")
    return f"formation {mark}: worst {worst:6.1f} m (wingman {wingman}), held {held:4.1f} s"


def formation_summary(formation: dict[str, Any] | None) -> str:
    """The run's formation figures, from the status at its end."""
    figures = formation or {}
    if figures.get("time_to_form_s") is None:
        return "formation: never formed"
    return (
        f"formation: formed after {figures['time_to_form_s']:.1f} s, in formation "
        f"{100 * (figures.get('fraction_in_formation') or 0):.0f} % of the flight after, "
        f"longest hold {figures.get('longest_hold_s', 0):.1f} s, "
        f"slot error while formed RMS {figures.get('rms_slot_error_m')} m, "
        f"p95 {figures.get('p95_slot_error_m')} m"
    )


def run_demo(
    mission_path: Path,
    mission: Mission,
    *,
    speedup: float,
    port: int,
    base_port: int,
    workdir: Path,
) -> int:
    api = f"http://127.0.0.1:{port}"
    workdir.mkdir(parents=True, exist_ok=True)
    links = [
        arg
        for k in range(len(mission.vehicles))
        for arg in ("--link", f"tcp:127.0.0.1:{base_port + 10 * k}")
    ]
    sitl_cmd = [
        sys.executable,
        "-m",
        "sitl",
        str(mission_path),
        "--speedup",
        str(speedup),
        "--base-port",
        str(base_port),
    ]
    serve_cmd = [
        sys.executable,
        "-m",
        "gcs_ppf.cli",
        "serve",
        "--port",
        str(port),
        "--db",
        str(workdir / "gcs_ppf.db"),
        *links,
    ]

    def stop(_signum: int, _frame: object) -> None:
        raise KeyboardInterrupt  # SIGTERM stops the demo like Ctrl-C

    signal.signal(signal.SIGTERM, stop)
    logs = [(workdir / "sitl.log").open("w"), (workdir / "gcs.log").open("w")]
    procs: list[subprocess.Popen[bytes]] = []
    try:
        procs.append(subprocess.Popen(sitl_cmd, stdout=logs[0], stderr=subprocess.STDOUT))
        procs.append(subprocess.Popen(serve_cmd, stdout=logs[1], stderr=subprocess.STDOUT))
        print(
            f"SITL: {len(mission.vehicles)} ArduPlane-like vehicles on TCP "
            f"127.0.0.1:{base_port}+10·i (speedup {speedup:g}); logs in {workdir}/"
        )
        if not _wait_vehicles(api, len(mission.vehicles), 60.0):
            print(f"the service did not see every vehicle; see {workdir}/gcs.log")
            return 1
        print(f"service: {api}  (API docs at {api}/docs, live state at ws://…/ws/telemetry)")
        status, created = http_json("POST", f"{api}/missions", json.loads(mission_path.read_text()))
        if status != 201:
            print(f"mission rejected ({status}): {created}")
            return 1
        mid = created["id"]
        status, _ = http_json("POST", f"{api}/missions/{mid}/start")
        print(f"mission {mid} {mission.name!r} started")
        last_print = 0.0
        while True:
            _, s = http_json("GET", f"{api}/missions/{mid}/status")
            now = time.monotonic()
            if now - last_print >= 1.0 or s["state"] in FINISHED:
                last_print = now
                sep, clear = s.get("min_separation_m"), s.get("min_obstacle_clearance_m")
                states = " ".join(f"{v['id']}:{v['ppf_state']}" for v in s.get("vehicles", []))
                print(
                    f"t={s.get('mission_time_s', 0):6.1f} s  {s['state']:<9} "
                    f"min separation {sep or float('nan'):6.1f} m  "
                    f"min clearance {clear or float('nan'):6.1f} m  "
                    f"{formation_line(s.get('formation'))}  PPF {states}"
                )
            if s["state"] in FINISHED:
                break
            time.sleep(0.2)
        print(f"mission {s['state']}; vehicles loiter. API still at {api}/docs — Ctrl-C stops.")
        print(formation_summary(s.get("formation")))
        while all(p.poll() is None for p in procs):
            time.sleep(0.5)
        return 0
    except KeyboardInterrupt:
        print("\nstopping SITL and service")
        return 0
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
        for f in logs:
            f.close()

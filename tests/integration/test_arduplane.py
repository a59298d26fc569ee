"""Real ArduPlane SITL: ``gcs-ppf arduplane-sitl`` starts one ArduPilot instance per vehicle,
``gcs-ppf serve`` flies the formation on their serial0 ports, and an independent pymavlink
observer on each instance's serial1 port judges the flight.

Needs an ArduPlane SITL binary (README, "Flying real ArduPlane SITL"):
``ARDUPLANE_SITL=…/build/sitl/bin/arduplane .venv/bin/pytest -m arduplane -s``; skipped
otherwise.  ``ARDUPLANE_SITL_SPEEDUP`` (default 5) sets the simulation speed-up.
"""

from __future__ import annotations

import json
import os
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import httpx
import numpy as np
import pytest
from pymavlink import mavutil

from gcs_ppf.geodesy import geodetic_to_enu
from gcs_ppf.mission import Mission
from tests.conftest import EXAMPLES
from tests.integration.test_service_sitl import (
    Flight,
    _finished,
    _vehicle_count,
    closest_pass,
    formation_offsets,
    free_port_block,
    process,
    resample,
    wait_for,
)

BINARY = os.environ.get("ARDUPLANE_SITL", "")
SPEEDUP = float(os.environ.get("ARDUPLANE_SITL_SPEEDUP", "5"))
AFTER_S = 30.0  # vehicle seconds watched after the run ends
AIRBORNE_M = 10.0  # "after takeoff": from a vehicle's first sample this high above its home
OBSERVER_SYSID = 202  # neither a vehicle's id nor the service's 255
PREARM_OK = 1 << 28  # MAV_SYS_STATUS_PREARM_CHECK in SYS_STATUS health

pytestmark = [
    pytest.mark.arduplane,
    pytest.mark.skipif(
        not (BINARY and Path(BINARY).is_file()),
        reason=f"ARDUPLANE_SITL={BINARY!r} does not name an ArduPlane SITL binary "
        "(set it to …/ardupilot/build/sitl/bin/arduplane to fly real ArduPlane)",
    ),
]


@dataclass
class Record:
    """What the observer heard from one vehicle.  ``pos`` rows: (arrival wall time s,
    time_boot_ms, lat deg, lon deg, alt AMSL m, height above home m); ``texts``: (the
    latest time_boot_ms heard before it, text)."""

    pos: list[tuple[float, int, float, float, float, float]] = field(default_factory=list)
    texts: list[tuple[int, str]] = field(default_factory=list)
    prearm_ok: bool = False


class Observer:
    """One pymavlink connection per vehicle to its observer port (serial1), independent of
    the service: asks the vehicle on that port for GLOBAL_POSITION_INT at 10 Hz and
    SYS_STATUS at 1 Hz (SET_MESSAGE_INTERVAL applies to the port it arrives on) and records
    them with every STATUSTEXT."""

    def __init__(self, ports: dict[int, int]) -> None:
        self.records = {sysid: Record() for sysid in ports}
        self._stop = threading.Event()
        self._threads = [threading.Thread(target=self._run, args=(sysid, port), daemon=True)
                         for sysid, port in ports.items()]  # fmt: skip

    def _run(self, sysid: int, port: int) -> None:
        rec = self.records[sysid]
        conn = mavutil.mavlink_connection(
            f"tcp:127.0.0.1:{port}", source_system=OBSERVER_SYSID, source_component=191
        )
        last_pos = asked = 0.0
        tbm = 0
        try:
            while not self._stop.is_set():
                now = time.monotonic()
                if now - last_pos > 1.0 and now - asked > 1.0:  # (re)ask until it streams
                    asked = now
                    conn.mav.heartbeat_send(6, 8, 0, 0, 0)  # a GCS, MAV_AUTOPILOT_INVALID
                    for msg_id, interval_us in ((33, 100_000), (1, 1_000_000)):
                        conn.mav.command_long_send(sysid, 1, 511, 0, msg_id, interval_us,
                                                   0, 0, 0, 0, 0)  # fmt: skip
                msg = conn.recv_match(type=["GLOBAL_POSITION_INT", "STATUSTEXT", "SYS_STATUS"],
                                      blocking=True, timeout=0.2)  # fmt: skip
                if msg is None or msg.get_srcSystem() != sysid:
                    continue
                kind = msg.get_type()
                if kind == "GLOBAL_POSITION_INT":
                    if msg.lat == 0 and msg.lon == 0:  # no GPS fix yet
                        continue
                    last_pos, tbm = time.monotonic(), int(msg.time_boot_ms)
                    rec.pos.append((last_pos, tbm, msg.lat * 1e-7, msg.lon * 1e-7,
                                    msg.alt * 1e-3, msg.relative_alt * 1e-3))  # fmt: skip
                elif kind == "STATUSTEXT":
                    rec.texts.append((tbm, str(msg.text)))
                else:
                    rec.prearm_ok = bool(msg.onboard_control_sensors_health & PREARM_OK)
        finally:
            conn.close()

    def latest_boot_ms(self) -> dict[int, int]:
        return {s: (r.pos[-1][1] if r.pos else 0) for s, r in self.records.items()}

    def __enter__(self) -> Observer:
        for t in self._threads:
            t.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(timeout=5)


def emission_wall_s(wall_s: np.ndarray, boot_ms: np.ndarray, window: int = 50) -> np.ndarray:
    """When each sample left its vehicle, on the observer's wall clock.  Every instance keeps
    its own boot clock, so the vehicles share only the wall clock; a sample arrives after it
    was sent (TCP delivers in bursts), so the earliest time consistent with the samples after
    it (each dated back along its boot clock at the speed-up) is taken."""
    out = wall_s.copy()
    for k in range(1, window):
        later = wall_s[k:] - (boot_ms[k:] - boot_ms[:-k]) / (1000.0 * SPEEDUP)
        out[:-k] = np.minimum(out[:-k], later)
    return out


def tracks_on_common_clock(
    obs: Observer, mission: Mission, t0_wall: float
) -> dict[int, np.ndarray]:
    """Per vehicle [K,5] rows of (vehicle seconds since ``t0_wall`` on the common clock,
    x, y, z in the mission's ICS, height above home) from ``t0_wall`` on:
    test_service_sitl's track format."""
    out = {}
    for sysid, rec in obs.records.items():
        rows = np.array(rec.pos)
        t = (emission_wall_s(rows[:, 0], rows[:, 1]) - t0_wall) * SPEEDUP
        rows, t = rows[t >= 0.0], t[t >= 0.0]
        enu = [geodetic_to_enu(la, lo, al, mission.origin) for la, lo, al in rows[:, 2:5]]
        out[sysid] = np.column_stack([t, np.array(enu), rows[:, 5]])
    return out


def fly_arduplane(tmp_path: Path, mission_path: Path) -> None:
    doc = json.loads(mission_path.read_text())
    mission = Mission.model_validate(doc)
    lim, n = mission.limits, len(mission.vehicles)
    base = free_port_block(10 * n)
    api_port = free_port_block(1)
    api = f"http://127.0.0.1:{api_port}"
    service_ports = {v.id: base + 10 * k for k, v in enumerate(mission.vehicles)}
    observer_ports = {v.id: p + 2 for v, p in zip(mission.vehicles, service_ports.values(),
                                                  strict=True)}  # fmt: skip
    launcher = [sys.executable, "-m", "gcs_ppf.cli", "arduplane-sitl", str(mission_path),
                "--binary", BINARY, "--speedup", f"{SPEEDUP:g}", "--base-port", str(base),
                "--workdir", str(tmp_path / "sitl")]  # fmt: skip
    links = [a for p in service_ports.values() for a in ("--link", f"tcp:127.0.0.1:{p}")]
    serve = [sys.executable, "-m", "gcs_ppf.cli", "serve", "--port", str(api_port),
             "--db", str(tmp_path / "gcs.db"), *links]  # fmt: skip
    env = {"GCS_PPF_TLOG_DIR": str(tmp_path / "tlogs")}
    launcher_log = tmp_path / "arduplane-sitl.log"
    wall_budget = (mission.planner.max_time + 120.0) / SPEEDUP + 60.0
    with process(launcher, launcher_log):
        wait_for(lambda: "ready" in launcher_log.read_text(), 60, f"the fleet ({launcher_log})")
        with process(serve, tmp_path / "gcs.log", env), Observer(observer_ports) as obs:
            wait_for(lambda: _vehicle_count(api) == n, 60, "the service to see every vehicle")
            t_ready = time.monotonic()
            try:  # GPS and EKF settle before ArduPlane will arm
                wait_for(lambda: all(r.prearm_ok for r in obs.records.values()), 120, "pre-arm")
            except AssertionError:
                late = [s for s, r in obs.records.items() if not r.prearm_ok]
                print(f"\nnot pre-arm healthy, started anyway: vehicles {late}")
            print(f"\n{n} vehicles ready after {time.monotonic() - t_ready:.1f} s wall")
            with httpx.Client(base_url=api, timeout=10) as client:
                r = client.post("/missions", json=doc)
                assert r.status_code == 201, r.text
                mid = r.json()["id"]
                t0_wall = time.monotonic()
                r = client.post(f"/missions/{mid}/start")
                assert r.status_code == 202, r.text
            final = wait_for(lambda: _finished(api, mid), wall_budget, "the run to end")
            end_s = (time.monotonic() - t0_wall) * SPEEDUP  # on the common clock
            end_ms = obs.latest_boot_ms()

            def watched_after() -> bool:
                now_ms = obs.latest_boot_ms()
                return all(now_ms[s] >= end_ms[s] + AFTER_S * 1000 for s in now_ms)

            wait_for(watched_after, 3 * AFTER_S / SPEEDUP + 10, "vehicle time after the end")

    record = {s: {"pos": r.pos, "texts": r.texts} for s, r in obs.records.items()}
    (tmp_path / "observer.json").write_text(json.dumps({"t0_wall": t0_wall, **record}))
    tracks = tracks_on_common_clock(obs, mission, t0_wall)
    start = max(tr[0, 0] for tr in tracks.values())
    end = min(tr[-1, 0] for tr in tracks.values())
    pos = resample(tracks, np.arange(start, end, 0.05))
    gaps = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=-1)
    gaps[:, np.arange(n), np.arange(n)] = np.inf
    separation = float(gaps.min())
    clearance = min(
        [float((np.linalg.norm(tr[:, 1:4] - np.array(o.center), axis=1) - o.radius).min())
         for tr in tracks.values() for o in mission.obstacles] or [np.inf]
    )  # fmt: skip
    hits = {}
    for sysid, rec in obs.records.items():
        up = [tbm for _, tbm, *_, h in rec.pos if h >= AIRBORNE_M]
        hits[sysid] = [t for b, t in rec.texts if "Hit ground" in t and up and b >= up[0]]
    flight = Flight(mission, api, mid, final, tracks, serve, env)
    # The run's clock starts once the vehicles are launched: its window ends at end_s.
    best, formation = formation_offsets(flight, end_s - final["mission_time_s"])
    to_target = closest_pass(tracks[mission.leader.id], np.array(mission.target))
    print(
        f"{mission.name} on ArduPlane SITL (×{SPEEDUP:g}): run {final['state']} "
        f"({final.get('outcome')}), flight time {final['mission_time_s']:.1f} s ({end_s:.1f} s "
        "from the start command, takeoff included); observer: "
        f"min separation {separation:.1f} m (safe {lim.safe_distance_uav:g}), min clearance "
        f"{clearance:.1f} m (safe {lim.safe_distance_obstacle:g}), leader's closest to the "
        f"target {to_target:.1f} m, formation error {formation:.1f} m (worst wingman at the "
        "best moment; each wingman's best "
        + ", ".join(f"{vid}: {d:.1f} m" for vid, d in best.items())
        + "), 'Hit ground' after takeoff: "
        + ", ".join(f"{s}: {len(h)}" for s, h in hits.items())
    )
    assert final["state"] == "completed", final
    assert separation >= lim.safe_distance_uav
    assert clearance >= lim.safe_distance_obstacle
    assert not any(hits.values()), hits
    assert formation <= lim.target_accuracy


@pytest.mark.arduplane
@pytest.mark.parametrize(
    "mission", ["arduplane_3", "arduplane_5", "arduplane_formation_takeoff_3",
                "arduplane_formation_takeoff_5"],
)  # fmt: skip
def test_formation_flown_on_arduplane_sitl(mission: str, tmp_path: Path) -> None:
    """From a ground start (line abreast 272 m apart, or a formation takeoff from runway
    positions at the slots): the run completes, separation and obstacle clearance stay safe,
    no vehicle hits the ground once airborne, and every wingman is within the target
    accuracy of its local target point (Eq. 6, from the observer's tracks) at one moment."""
    fly_arduplane(tmp_path, EXAMPLES / f"{mission}.json")

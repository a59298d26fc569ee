"""Other ground stations beside the service (``--forward``): two pymavlink ground stations,
one on a ``udpout`` endpoint (as QGroundControl listens on udp 14550), one connected to a
``tcpin`` endpoint, watch Table 3 flown; one reads a parameter and takes a wingman over with a
mode change; the operator hands it back."""

from __future__ import annotations

import json
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any

import pytest
from pymavlink import mavutil

from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.service.store import Store
from gcs_ppf.tools.demo import http_json as http
from gcs_ppf.tools.observer import free_port
from tests.checks import wait_for
from tests.conftest import EXAMPLES
from tests.integration.test_service_sitl import SPEEDUP, check_safety, fly

MISSION = EXAMPLES / "paper_table3.json"
TAKEN = 5  # the wingman the other GCS takes over


class GroundStation:
    """A pymavlink ground station of its own system id, recording every frame it hears
    (system, message type, vehicle time or None) in a thread, sending its heartbeat at 1 Hz."""

    def __init__(self, url: str, system_id: int) -> None:
        self.conn = mavutil.mavlink_connection(url, source_system=system_id, source_component=190)
        self.heard: list[tuple[int, str, int | None, float]] = []
        self.params: list[tuple[int, str]] = []
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._listen, daemon=True)
        self._thread.start()

    def _listen(self) -> None:
        beat = 0.0
        while not self._stop.is_set():
            if time.monotonic() - beat >= 1.0:
                beat = time.monotonic()
                with self._lock:
                    self.conn.mav.heartbeat_send(6, 8, 0, 0, 4)  # MAV_TYPE_GCS, no autopilot
            msg = self.conn.recv_match(blocking=True, timeout=0.1)
            if msg is None or msg.get_type() == "BAD_DATA":
                continue
            boot = getattr(msg, "time_boot_ms", None)
            self.heard.append((msg.get_srcSystem(), msg.get_type(), boot, time.monotonic()))
            if msg.get_type() == "PARAM_VALUE":
                self.params.append((msg.get_srcSystem(), msg.param_id))

    def send(self, send: Any) -> None:
        with self._lock:
            send(self.conn.mav)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)
        self.conn.close()

    def count(self, sysid: int, kind: str) -> int:
        return sum(1 for s, k, _, _ in self.heard if s == sysid and k == kind)


def _events(api: str, mid: int) -> list[dict[str, Any]]:
    status, body = http("GET", f"{api}/missions/{mid}/events")
    return list(body) if status == 200 else []


def _mission_time(api: str, mid: int) -> float:
    status, body = http("GET", f"{api}/missions/{mid}/status")
    return float(body.get("mission_time_s") or 0.0) if status == 200 else 0.0


@pytest.mark.integration
def test_two_ground_stations_beside_the_service_watch_read_and_take_over(tmp_path: Path) -> None:
    udp_port, tcp_port = free_port(), free_port()
    qgc = GroundStation(f"udpin:127.0.0.1:{udp_port}", 254)  # listens, as QGroundControl
    seen: dict[str, Any] = {}
    others: list[GroundStation] = []

    def during(api: str, mid: int) -> None:
        others.append(GroundStation(f"tcp:127.0.0.1:{tcp_port}", 253))
        wait_for(lambda: _mission_time(api, mid) >= 45.0, 60, "45 s of the mission")
        qgc.send(lambda mav: mav.param_request_read_send(4, 1, b"SYSID_THISMAV", -1))
        wait_for(lambda: (4, "SYSID_THISMAV") in qgc.params, 10, "vehicle 4's parameter")
        qgc.send(
            lambda mav: mav.command_long_send(
                TAKEN, 1, 176, 0, 1, int(PlaneMode.LOITER), 0, 0, 0, 0, 0
            )
        )
        taken = wait_for(
            lambda: [e for e in _events(api, mid) if e["kind"] == "vehicle_taken_over"],
            10,
            "vehicle_taken_over",
        )
        seen["taken"] = taken
        time.sleep(5.0 / SPEEDUP)  # five of the vehicles' seconds in LOITER
        status, body = http("POST", f"{api}/missions/{mid}/vehicles/{TAKEN}/hand-back")
        seen["hand_back"] = (status, body)
        status, body = http("POST", f"{api}/missions/{mid}/vehicles/{TAKEN}/hand-back")
        seen["hand_back_again"] = status

    def after(api: str, mid: int) -> None:
        seen["forwards"] = http("GET", f"{api}/forwards")[1]

    forward = [f"udpout:127.0.0.1:{udp_port}", f"tcpin:127.0.0.1:{tcp_port}"]
    try:
        flight = fly(
            tmp_path,
            json.loads(MISSION.read_text()),
            env_extra={"GCS_PPF_FORWARD": json.dumps(forward)},
            during=during,
            after=after,
        )
    finally:
        qgc.close()
        for gcs in others:
            gcs.close()
    (tcp_gcs,) = others
    # what the other ground stations saw: every vehicle, its heartbeat and positions at the
    # stream rate (10 Hz of its clock), each position once, and each other's heartbeats
    for gcs in (qgc, tcp_gcs):
        for vid in range(1, 6):
            assert gcs.count(vid, "HEARTBEAT") >= 5, vid
            boots = [
                b
                for s, k, b, _ in gcs.heard
                if s == vid and k == "GLOBAL_POSITION_INT" and b is not None
            ]
            assert boots, vid
            assert max(Counter(boots).values()) == 1, f"vehicle {vid}: a position twice"
            span_s = (max(boots) - min(boots)) / 1000.0
            assert len(boots) / span_s >= 8.0, (vid, len(boots), span_s)
        assert gcs.count(255, "COMMAND_LONG") + gcs.count(255, "COMMAND_INT") == 0
    assert tcp_gcs.count(254, "HEARTBEAT") >= 1  # the other GCS's, relayed
    assert qgc.count(253, "HEARTBEAT") >= 1
    assert (4, "SYSID_THISMAV") in qgc.params
    # answered by the vehicle asked only (the service never asks it; the PARAM_VALUEs of
    # its own asks, broadcast by the vehicles, are relayed too)
    assert {s for s, name in qgc.params if name == "SYSID_THISMAV"} == {4}
    # the takeover: an event, the vehicle out of the run's command, handed back
    (taken,) = seen["taken"]
    assert taken["vehicle_id"] == TAKEN
    assert taken["detail"]["by_system"] == 254
    assert taken["detail"]["message"] == "COMMAND_LONG 176"
    status, body = seen["hand_back"]
    assert status == 200, body
    assert seen["hand_back_again"] == 409
    store = Store(tmp_path / "gcs.db")
    run = store.runs(flight.mission_id)[0]
    events = store.events(run.id)
    kinds = [(e.kind, e.vehicle_id) for e in events]
    assert kinds.index(("vehicle_taken_over", TAKEN)) < kinds.index(("vehicle_handed_back", TAKEN))
    # while another GCS flew it, vehicle 5 was its own: a violation of its own is the run's
    # to report, and only it may have one
    unsafe = [e for e in events if e.kind == "safety_violation"]
    assert all(e.vehicle_id == TAKEN for e in unsafe), unsafe
    assert flight.final["state"] == ("completed_unsafe" if unsafe else "completed"), flight.final
    _, separation, clearance = check_safety(flight, exclude=[TAKEN] if unsafe else [])
    forwards = {f["url"]: f for f in seen["forwards"]}
    print(
        f"\nforwarded: udpout {forwards[forward[0]]['frames_out']} frames out, tcpin "
        f"{forwards[forward[1]]['frames_out']}; positions heard by the second GCS: "
        f"{[qgc.count(v, 'GLOBAL_POSITION_INT') for v in range(1, 6)]}; separation "
        f"{separation:.1f} m, clearance {clearance:.1f} m"
    )

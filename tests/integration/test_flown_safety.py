"""Flown safety on loopback (issue 10): what the run does when the leader's link dies, as an
independent listener and the service's own record see it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from pymavlink import mavutil

from gcs_ppf.service.store import Store
from gcs_ppf.tools.demo import http_json as http
from tests.checks import wait_for
from tests.integration.test_service_sitl import MISSION, SPEEDUP, fly


def mission_time(api: str, mid: int) -> float:
    try:
        _, status = http("GET", f"{api}/missions/{mid}/status")
    except OSError:
        return 0.0
    return float(status.get("mission_time_s") or 0.0)


@pytest.mark.integration
def test_the_leaders_link_dying_fails_the_run_within_the_lost_vehicle_timeout(
    tmp_path: Path,
) -> None:
    """The leader goes silent 10 s into the run (SIM_KILL): the run notices although
    its ticks run on the leader's clock (it used to stay ``running`` for ever) —
    ``vehicle_lost`` for the leader, then the run ``failed`` ("leader lost"), while the
    others still fly and report."""

    def kill_the_leader(api: str, mid: int) -> None:
        """10 s of mission time into the run, the leader goes silent (SIM_KILL)."""
        wait_for(lambda: mission_time(api, mid) >= 10.0, 120, "10 s of the run")
        port = next(int(line.rsplit(":", 1)[1]) for line in (tmp_path / "sitl.log").open()
                    if line.startswith("vehicle 1:"))  # fmt: skip
        conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=201)
        try:
            conn.wait_heartbeat(timeout=10)
            for _ in range(10):  # until it falls silent (a second without a message)
                conn.mav.param_set_send(1, 1, b"SIM_KILL", 1.0, 2)
                if conn.recv_match(blocking=True, timeout=1.0) is None:
                    break
                while conn.recv_match(blocking=False) is not None:
                    pass
        finally:
            conn.close()

    flight = fly(tmp_path, json.loads(MISSION.read_text()), during=kill_the_leader)
    assert flight.final["state"] == "failed", flight.final
    assert flight.final["outcome"] == "leader lost"
    store = Store(tmp_path / "gcs.db")  # the service's record, read after it stopped
    run = store.runs(flight.mission_id)[0]
    kinds = [(e.kind, e.vehicle_id) for e in store.events(run.id)]
    assert ("vehicle_lost", 1) in kinds
    assert kinds.index(("vehicle_lost", 1)) < kinds.index(("run_failed", None))
    silent_from_s = flight.tracks[1][-1, 0]  # the leader's last position, on its clock
    others_last_s = min(t[-1, 0] for vid, t in flight.tracks.items() if vid != 1)
    assert others_last_s > silent_from_s  # the others were heard after the leader fell silent
    print(f"\nleader silent from {silent_from_s:.1f} s of vehicle time; the others heard to "
          f"{others_last_s:.1f} s; SITL at {SPEEDUP}x")  # fmt: skip

"""The mission's zones as the vehicles' own fences (issue 27 items 3 and 4) on loopback:
the service uploads them at the launch and verifies them, a third party (pymavlink on the
vehicle's own port) reads back what was sent, a zone added mid-run goes up too, and after
the run the vehicles' own lists (here: none) are back.  ``make campaign-check``."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import pytest
from pymavlink import mavutil

from gcs_ppf.mavlink.fences import FenceItem, fence_items
from gcs_ppf.mission import Mission
from gcs_ppf.tools.demo import http_json as http
from tests.checks import wait_for
from tests.conftest import EXAMPLES
from tests.integration.test_service_sitl import check_safety, fly

MISSION = EXAMPLES / "paper_table3_fenced.json"
THIRD_PARTY_SYSID = 204


def read_fence(port: int, vid: int) -> list[FenceItem]:
    """The vehicle's fence list, downloaded by a client of its own (not the service)."""
    conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=THIRD_PARTY_SYSID)
    try:
        conn.mav.mission_request_list_send(vid, 1, 1)
        count = conn.recv_match(type="MISSION_COUNT", blocking=True, timeout=5)
        assert count is not None
        assert count.mission_type == 1
        out = []
        for seq in range(count.count):
            conn.mav.mission_request_int_send(vid, 1, seq, 1)
            msg = None
            while msg is None or msg.seq != seq:
                msg = conn.recv_match(type="MISSION_ITEM_INT", blocking=True, timeout=5)
                assert msg is not None, f"item {seq}"
            out.append(FenceItem(msg.command, msg.x, msg.y, msg.param1))
        conn.mav.mission_ack_send(vid, 1, 0, 1)
        return out
    finally:
        conn.close()


def kinds(api: str, mid: int, kind: str) -> list[dict[str, Any]]:
    _, events = http("GET", f"{api}/missions/{mid}/events")
    return [e for e in events if e["kind"] == kind]


@pytest.mark.integration
@pytest.mark.campaign
def test_the_zones_are_each_vehicle_s_fence_for_the_run(tmp_path: Path) -> None:
    doc = json.loads(MISSION.read_text())
    mission = Mission.model_validate(doc)
    sent, _ = fence_items(mission)
    seen: dict[str, Any] = {}

    def ports(api: str) -> dict[int, int]:
        _, links = http("GET", f"{api}/links")
        return {v: int(link["url"].rsplit(":", 1)[1]) for link in links for v in link["vehicles"]}

    def during(api: str, mid: int) -> None:
        wait_for(lambda: len(kinds(api, mid, "fence_set")) == len(mission.vehicles), 30,
                 "every vehicle's fence")  # fmt: skip
        seen["set"] = kinds(api, mid, "fence_set")
        seen["read"] = {v: read_fence(p, v) for v, p in ports(api).items()}
        # a no-fly circle added mid-run (GeoJSON, ~6.7 km south-west of the origin)
        added = {"type": "FeatureCollection", "features": [{"type": "Feature",
                 "properties": {"name": "added", "radius": 300.0},
                 "geometry": {"type": "Point", "coordinates": [8.50, 47.35]}}]}  # fmt: skip
        status, _ = http("POST", f"{api}/missions/{mid}/zones", added)
        assert status == 200
        wait_for(lambda: len(kinds(api, mid, "fence_set")) == 2 * len(mission.vehicles), 30,
                 "every vehicle's fence put up again")  # fmt: skip
        _, revised = http("GET", f"{api}/missions/{mid}")
        seen["sent_again"], _ = fence_items(Mission.model_validate(revised["mission"]))
        seen["read_again"] = {v: read_fence(p, v) for v, p in ports(api).items()}

    def after(api: str, mid: int) -> None:
        wait_for(lambda: len(kinds(api, mid, "fence_restored")) == len(mission.vehicles), 60,
                 "every vehicle's own fence back")  # fmt: skip
        time.sleep(0.2)
        seen["after"] = {v: read_fence(p, v) for v, p in ports(api).items()}

    flight = fly(tmp_path, doc, during=during, after=after)
    assert flight.final["state"] == "completed", flight.final
    check_safety(flight)
    assert all(e["detail"]["verified"] and e["detail"]["fence_enable"] == 1 for e in seen["set"])
    assert all(int(e["detail"]["fence_type"]) & 4 for e in seen["set"])  # polygons, circles
    assert seen["read"] == {v.id: sent for v in mission.vehicles}  # read back as sent
    assert len(seen["sent_again"]) == len(sent) + 1
    assert seen["read_again"] == {v.id: seen["sent_again"] for v in mission.vehicles}
    assert seen["after"] == {v.id: [] for v in mission.vehicles}  # they had none before
    print(f"\n{len(sent)} fence items on each of {len(mission.vehicles)} vehicles, read back "
          "by a third party as sent; cleared after the run")  # fmt: skip

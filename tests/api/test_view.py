"""The operator's page and its read-only routes (``api/view.py``): served, offline, correct."""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from api.app import create_app
from api.view import STATIC_DIR, vehicle_view, with_formation
from gcs_ppf.mission import Mission
from gcs_ppf.planning.ppf.primitives import influence_radius
from gcs_ppf.service.settings import Settings
from gcs_ppf.service.store import Store
from tests.conftest import EXAMPLES


def table3() -> dict[str, Any]:
    doc: dict[str, Any] = json.loads((EXAMPLES / "paper_table3.json").read_text())
    return doc


@pytest.fixture
def client(tmp_path: Path) -> Iterator[TestClient]:
    with TestClient(create_app(Settings(db=tmp_path / "gcs.db", tlog_dir=None))) as c:
        yield c


def test_the_page_and_every_file_it_names_are_served(client: TestClient) -> None:
    page = client.get("/")
    assert page.status_code == 200
    assert page.headers["content-type"].startswith("text/html")
    names = set(re.findall(r'(?:src|href)="(/ui/[^"]+)"', page.text))
    for js in STATIC_DIR.glob("js/*.js"):  # the modules import each other relatively
        names |= {f"/ui/js/{m}" for m in re.findall(r'from "\./([\w.]+)"', js.read_text())}
    assert "/ui/js/main.js" in names
    assert "/ui/js/client.js" in names
    for name in names:
        assert client.get(name).status_code == 200, name


def test_the_page_fetches_nothing_from_elsewhere() -> None:
    """No CDN, no tile server: no absolute URL in any file the page is made of."""
    files = [p for p in STATIC_DIR.rglob("*") if p.is_file()]
    assert len(files) >= 6
    for path in files:
        assert not re.search(r"(?:https?:)?//[\w.-]+\.\w+/", path.read_text()), path


def test_the_page_is_not_in_the_api_schema(client: TestClient) -> None:
    paths = client.get("/openapi.json").json()["paths"]
    assert "/" not in paths
    assert "/runs/{run_id}/telemetry" in paths


def test_a_runs_telemetry_for_replay(tmp_path: Path) -> None:
    store = Store(tmp_path / "gcs.db")
    stored = store.add_mission(Mission.model_validate(table3()))
    run = store.add_run(stored.id, "running")
    store.add_telemetry(run.id, [
        (0.0, 1, 47.4, 8.5, 788.0, 1500.0, 2000.0, 300.0, 100.0),
        (0.0, 2, 47.4, 8.5, 488.0, 2000.0, 1500.0, 0.0, float("nan")),
        (0.5, 1, 47.4, 8.5, 788.0, 1550.0, 2000.0, 300.0, 101.0),
    ])  # fmt: skip
    store.close()
    with TestClient(create_app(Settings(db=tmp_path / "gcs.db", tlog_dir=None))) as client:
        body = client.get(f"/runs/{run.id}/telemetry").json()
        assert body["mission_id"] == stored.id
        assert body["vehicles"]["1"] == {
            "t": [0.0, 0.5],
            "position_m": [[1500.0, 2000.0, 300.0], [1550.0, 2000.0, 300.0]],
            "speed_m_s": [100.0, 101.0],
        }
        assert body["vehicles"]["2"]["speed_m_s"] == [None]  # NaN is not JSON
        missing = client.get("/runs/999/telemetry")
        assert missing.status_code == 404
        assert "run 999" in missing.json()["detail"]
        assert client.get("/runs/0/telemetry").status_code == 422


def test_the_view_stream_without_and_with_a_mission(client: TestClient) -> None:
    with client.websocket_connect("/ws/view") as ws:
        frame = ws.receive_json()
    assert frame["type"] == "frame"
    assert frame["mission_id"] is None
    assert frame["vehicles"] == []
    assert frame["obstacles"] == []

    mid = client.post("/missions", json=table3()).json()["id"]
    with client.websocket_connect(f"/ws/view?mission_id={mid}") as ws:
        frame = ws.receive_json()
        ws.send_text('{"start": 1}')  # read and dropped: the socket changes nothing
        ws.send_bytes(b"\x00")
        again = ws.receive_json()  # frames keep coming while nothing flies
    assert client.get(f"/missions/{mid}/status").json()["state"] == "pending"
    assert again["type"] == "frame"
    assert frame["mission_id"] == mid
    assert frame["run"]["state"] == "pending"
    assert frame["target_m"] == [6000.0, 7000.0, 300.0]
    lim = Mission.model_validate(table3()).limits
    first = frame["obstacles"][0]
    assert first["keep_out_m"] == 350.0 + lim.safe_distance_obstacle
    expected = influence_radius(lim.v_max, lim.max_yaw_rate, first["keep_out_m"])
    assert first["influence_m"] == pytest.approx(expected, abs=0.01)


def row(system_id: int) -> dict[str, Any]:
    return {"system_id": system_id, "link_id": 1, "mode": "GUIDED", "armed": True,
            "lost": False, "seconds_since_heard": 0.1, "attitude": {"yaw_rad": 0.0}}  # fmt: skip


def test_a_vehicle_in_the_ics_with_its_course() -> None:
    north = vehicle_view(row(1), (10.0, 20.0, 300.0), (100.0, 0.0, 0.0))
    assert north["yaw_rad"] == pytest.approx(math.pi / 2, abs=1e-4)
    assert north["speed_m_s"] == pytest.approx(100.0)
    climbing_east = vehicle_view(row(1), (0.0, 0.0, 0.0), (0.0, 100.0, -100.0))
    assert climbing_east["yaw_rad"] == pytest.approx(0.0, abs=1e-4)
    assert climbing_east["pitch_rad"] == pytest.approx(math.pi / 4, abs=1e-4)
    # Standing still (on the runway): the heading is the attitude's, north → ICS yaw π/2.
    parked = vehicle_view(row(1), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert parked["yaw_rad"] == pytest.approx(math.pi / 2, abs=1e-4)
    assert vehicle_view(row(1), None, (None, None, None))["pos_m"] is None


def test_each_wingmans_local_target_point_turns_with_the_leader() -> None:
    """Eq. 6: slot (-100, 100, 0) is 100 m behind and 100 m left of the leader."""
    mission = Mission.model_validate(table3())
    slot = next(v for v in mission.vehicles if v.id == 2).slot
    assert slot is not None
    leader_north = vehicle_view(row(1), (1000.0, 2000.0, 300.0), (100.0, 0.0, 0.0))
    wingman = vehicle_view(row(2), (0.0, 0.0, 300.0), (100.0, 0.0, 0.0))
    other = vehicle_view(row(42), None, (None, None, None))
    status = {"vehicles": [{"id": 2, "ppf_state": "s3", "avoiding": False, "formed": False,
                            "local_target_distance_m": 1234.5, "lost": False,
                            "nearest_keep_out": "zones[1]", "clearance_m": 88.4}]}  # fmt: skip
    views = {v["id"]: v for v in with_formation([leader_north, wingman, other], mission, status)}
    # Heading north, the leader's left is west: behind (south) and left (west).
    expected = [1000.0 - slot[1], 2000.0 + slot[0], 300.0 + slot[2]]
    assert views[2]["local_target_m"] == pytest.approx(expected)
    assert views[2]["ppf_state"] == "s3"
    assert views[2]["local_target_distance_m"] == 1234.5
    assert (views[2]["nearest_keep_out"], views[2]["clearance_m"]) == ("zones[1]", 88.4)
    assert views[1]["role"] == "leader"
    assert views[1]["local_target_m"] is None
    assert views[42]["role"] == "other"
    east = vehicle_view(row(1), (1000.0, 2000.0, 300.0), (0.0, 100.0, 0.0))
    views = {v["id"]: v for v in with_formation([east, wingman], mission, None)}
    assert views[2]["local_target_m"] == pytest.approx([1000.0 + slot[0], 2000.0 + slot[1], 300.0])


def test_a_run_whose_leader_was_lost_shows_its_new_leader_and_slots() -> None:
    """After a succession the run's status names wingman 2 the leader and carries the
    slots moved to it: the page draws those, not the uploaded document's."""
    mission = Mission.model_validate(table3())
    lead = vehicle_view(row(2), (1000.0, 2000.0, 300.0), (0.0, 100.0, 0.0))  # flying east
    old = vehicle_view(row(1), None, (None, None, None))
    wingman = vehicle_view(row(3), (0.0, 0.0, 300.0), (0.0, 100.0, 0.0))
    status = {"leader_id": 2, "slots": {"1": [100.0, -100.0, 0.0], "3": [-100.0, 100.0, 0.0]}}
    views = {v["id"]: v for v in with_formation([lead, old, wingman], mission, status)}
    assert views[2]["role"] == "leader"
    assert views[2]["slot_m"] is None
    assert views[1]["role"] == "wingman"
    assert views[3]["slot_m"] == [-100.0, 100.0, 0.0]
    assert views[3]["local_target_m"] == pytest.approx([900.0, 2100.0, 300.0])


def test_the_view_frame_carries_the_zones_in_the_ics(client: TestClient) -> None:
    """Table 3's zones example, one polygon given in lat/lon instead: the page gets every
    footprint in metres (the lat/lon one converted back to within a few cm), the band and
    the kind, and none for a mission without zones."""
    from gcs_ppf.geodesy import enu_to_geodetic

    doc = json.loads((EXAMPLES / "paper_table3_zones.json").read_text())
    hexagon = doc["zones"][1]
    origin = Mission.model_validate(doc).origin
    hexagon["vertices_latlon"] = [
        list(enu_to_geodetic(x, y, 0.0, origin)[:2]) for x, y in hexagon.pop("vertices")
    ]
    mid = client.post("/missions", json=doc).json()["id"]
    with client.websocket_connect(f"/ws/view?mission_id={mid}") as ws:
        zones = ws.receive_json()["zones"]
    assert [z["name"] for z in zones] == ["tower", "hexagon", "restricted L", "dome"]
    tower, hexagon_view, ell, _ = zones
    assert tower["center_m"] == [3000.0, 3000.0]
    assert tower["radius_m"] == 350.0
    assert tower["floor_m"] is None
    assert tower["ceiling_m"] == 450.0
    assert tower["inclusion"] is False
    assert tower["kind"] == "cylinder"
    expected = [[4150.0, 4500.0], [3825.0, 5062.9], [3175.0, 5062.9], [2850.0, 4500.0],
                [3175.0, 3937.1], [3825.0, 3937.1]]  # fmt: skip
    assert np.allclose(hexagon_view["vertices_m"], expected, atol=0.05)
    assert ell["vertices_m"][0] == [4500.0, 3900.0]
    assert ell["floor_m"] == -200.0
    mid = client.post("/missions", json=table3()).json()["id"]
    with client.websocket_connect(f"/ws/view?mission_id={mid}") as ws:
        assert ws.receive_json()["zones"] == []

"""The REST API with its lifespan running: bad input answers 4xx and changes nothing."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from api.app import create_app
from gcs_ppf.service.settings import Settings
from tests.conftest import EXAMPLES
from tests.unit.test_zone_import import item
from tests.unit.test_zone_import import plan as plan_of


@pytest.fixture
def client(tmp_path: Path) -> Iterator[TestClient]:
    settings = Settings(db=tmp_path / "gcs.db", tlog_dir=None)
    with TestClient(create_app(settings)) as c:
        yield c


def table3() -> dict[str, Any]:
    doc: dict[str, Any] = json.loads((EXAMPLES / "paper_table3.json").read_text())
    return doc


def test_mission_round_trip(client: TestClient) -> None:
    created = client.post("/missions", json=table3())
    assert created.status_code == 201
    mid = created.json()["id"]
    assert client.get(f"/missions/{mid}").json()["mission"]["target"] == [6000.0, 7000.0, 300.0]
    assert [m["id"] for m in client.get("/missions").json()] == [mid]
    assert client.get(f"/missions/{mid}/status").json()["state"] == "pending"


def test_offline_plan_from_the_api(client: TestClient) -> None:
    mid = client.post("/missions", json=table3()).json()["id"]
    plan = client.post(f"/missions/{mid}/plan").json()
    assert plan["metrics"]["reached"] is True
    assert plan["metrics"]["collisions"] == 0
    assert set(plan["trajectories"]) == {"1", "2", "3", "4", "5"}


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"target": [0, 0, "x"]}, "target"),
        ({**table3(), "colour": "red"}, "colour"),
        ({**table3(), "vehicles": []}, "vehicles"),
    ],
)
def test_bad_missions_are_422_with_the_field(
    client: TestClient, body: dict[str, Any], field: str
) -> None:
    r = client.post("/missions", json=body)
    assert r.status_code == 422
    assert field in json.dumps(r.json()["detail"])
    assert client.get("/missions").json() == []


def test_malformed_json_is_422(client: TestClient) -> None:
    r = client.post("/missions", content=b"{not json", headers={"content-type": "application/json"})
    assert r.status_code == 422
    assert client.get("/missions").json() == []


def test_unknown_ids_are_404(client: TestClient) -> None:
    for method, url in [("get", "/missions/9"), ("get", "/missions/9/status"),
                        ("get", "/missions/9/events"), ("post", "/missions/9/start"),
                        ("post", "/missions/9/abort"), ("delete", "/links/4")]:  # fmt: skip
        r = client.request(method.upper(), url)
        assert r.status_code == 404, url
        assert "9" in r.json()["detail"] or "4" in r.json()["detail"]
    assert client.get("/missions/abc").status_code == 422
    # beyond SQLite's integers: a validation error, not a server error (schemathesis found it)
    assert client.post(f"/missions/{2**81}/abort").status_code == 422


def test_start_without_vehicles_is_409_naming_them(client: TestClient) -> None:
    mid = client.post("/missions", json=table3()).json()["id"]
    r = client.post(f"/missions/{mid}/start")
    assert r.status_code == 409
    assert r.json()["info"]["missing_ids"] == [1, 2, 3, 4, 5]
    assert client.get(f"/missions/{mid}/status").json()["state"] == "pending"
    assert client.get("/runs").json() == []


def test_abort_when_not_running_is_409(client: TestClient) -> None:
    mid = client.post("/missions", json=table3()).json()["id"]
    assert client.post(f"/missions/{mid}/abort").status_code == 409


def test_obstacles_replaced_or_rejected_whole(client: TestClient) -> None:
    mid = client.post("/missions", json=table3()).json()["id"]
    bad = client.put(f"/missions/{mid}/obstacles", json=[{"center": [0, 0, 0], "radius": -1}])
    assert bad.status_code == 422
    inside = client.put(f"/missions/{mid}/obstacles",
                        json=[{"center": [1500, 2000, 300], "radius": 100}])  # fmt: skip
    assert inside.status_code == 400
    assert "vehicles[0].position" in inside.json()["detail"]
    assert len(client.get(f"/missions/{mid}").json()["mission"]["obstacles"]) == 4
    ok = client.put(f"/missions/{mid}/obstacles", json=[{"center": [0, 0, 0], "radius": 50}])
    assert ok.status_code == 200
    assert len(ok.json()["mission"]["obstacles"]) == 1


def test_zones_imported_from_geojson_or_a_plan_or_refused_whole(client: TestClient) -> None:
    """POST …/zones takes the file's JSON: the zones are added; a file with one bad feature,
    or zones the mission cannot have (over a vehicle's start), adds none."""
    mid = client.post("/missions", json=table3()).json()["id"]
    plan = {"fileType": "Plan", "geoFence": {"polygons": [], "circles": [
        {"circle": {"center": [47.43, 8.58], "radius": 300}, "inclusion": False}]}}  # fmt: skip
    ok = client.post(f"/missions/{mid}/zones", json=plan)
    assert ok.status_code == 200
    assert [z["kind"] for z in ok.json()["mission"]["zones"]] == ["cylinder"]
    point = {"type": "Point", "coordinates": [8.57, 47.42]}
    features = [{"type": "Feature", "geometry": point, "properties": {"radius": 100}},
                {"type": "Feature", "geometry": point, "properties": {}}]  # fmt: skip
    bad = client.post(
        f"/missions/{mid}/zones", json={"type": "FeatureCollection", "features": features}
    )
    assert bad.status_code == 422
    assert "features[1].properties.radius" in bad.json()["detail"]
    assert "nothing imported" in bad.json()["detail"]
    start = {"type": "Point", "coordinates": [8.565469, 47.415727]}  # vehicle 1's start
    over = client.post(f"/missions/{mid}/zones", json={"type": "Feature", "geometry": start,
                                                        "properties": {"radius": 300}})  # fmt: skip
    assert over.status_code == 400
    assert len(client.get(f"/missions/{mid}").json()["mission"]["zones"]) == 1
    assert client.post("/missions/999/zones", json=plan).status_code == 404


def test_a_plans_route_comes_with_its_zones_when_asked(client: TestClient) -> None:
    """POST …/zones?route=true with a .plan: its geofence added and its waypoints the route
    and target; an item that cannot be read names it, and nothing is imported."""
    mid = client.post("/missions", json=table3()).json()["id"]
    doc = plan_of(item(22, z=50), item(16, 4000, 1000, 300), item(16, 6000, 7000, 300))
    doc["geoFence"] = {"polygons": [], "circles": [
        {"circle": {"center": [47.43, 8.58], "radius": 300}, "inclusion": False}]}  # fmt: skip
    without = client.post(f"/missions/{mid}/zones", json=doc)
    assert without.json()["mission"]["route"] == []
    ok = client.post(f"/missions/{mid}/zones?route=true", json=doc)
    assert ok.status_code == 200, ok.text
    mission = ok.json()["mission"]
    assert len(mission["zones"]) == 2
    assert [round(c) for c in mission["route"][0]["position"]] == [4000, 1000, 300]
    assert [round(c) for c in mission["target"]] == [6000, 7000, 300]
    doc["mission"]["items"].append({"type": "ComplexItem"})
    bad = client.post(f"/missions/{mid}/zones?route=true", json=doc)
    assert bad.status_code == 422
    assert "mission.items[3].type" in bad.json()["detail"]
    assert len(client.get(f"/missions/{mid}").json()["mission"]["zones"]) == 2


def test_zones_in_the_missions_own_form_as_the_page_draws_them(client: TestClient) -> None:
    """POST …/zones takes ``{"zones": [...]}`` in ICS metres (a polygon drawn on the page);
    one that cannot be a zone names its index and field, and nothing is added."""
    mid = client.post("/missions", json=table3()).json()["id"]
    corners = [[4000, 1000], [4400, 1000], [4400, 1300], [4000, 1300]]
    drawn = {"kind": "polygon", "name": "drawn", "vertices": corners}
    ok = client.post(f"/missions/{mid}/zones", json={"zones": [drawn]})
    assert ok.status_code == 200, ok.text
    (zone,) = ok.json()["mission"]["zones"]
    assert (zone["kind"], zone["name"], zone["vertices"][1]) == ("polygon", "drawn", [4400, 1000])
    line = {"kind": "polygon", "vertices": [[0, 0], [10, 0]]}
    bad = client.post(f"/missions/{mid}/zones", json={"zones": [drawn, line]})
    assert bad.status_code == 422
    assert "zones[1]: vertices" in bad.json()["detail"]
    kindless = client.post(f"/missions/{mid}/zones", json={"zones": [{"radius": 5}]})
    assert kindless.status_code == 422
    assert "zones[0].kind" in kindless.json()["detail"]
    assert len(client.get(f"/missions/{mid}").json()["mission"]["zones"]) == 1


def test_a_body_that_is_not_utf8_is_a_422_and_stores_nothing(client: TestClient) -> None:
    """FastAPI answers an undecodable body 400, undocumented (schemathesis found it)."""
    r = client.post(
        "/missions", content=b"\xff\x53\xfe", headers={"Content-Type": "application/json"}
    )
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body"]
    assert client.get("/missions").json() == []


def test_links_validate_their_url(client: TestClient) -> None:
    assert client.post("/links", json={"url": "carrier-pigeon:1"}).status_code == 400
    r = client.post("/links", json={"url": "tcp:127.0.0.1:9"})
    assert r.status_code == 201
    assert client.post("/links", json={"url": "tcp:127.0.0.1:9"}).status_code == 409
    assert [link["url"] for link in client.get("/links").json()] == ["tcp:127.0.0.1:9"]
    assert client.delete(f"/links/{r.json()['id']}").status_code == 204
    assert client.get("/links").json() == []


def test_websocket_sends_a_snapshot(client: TestClient) -> None:
    with client.websocket_connect("/ws/telemetry") as ws:
        snap = ws.receive_json()
    assert snap["vehicles"] == []
    assert "mission" in snap


def test_links_say_whether_they_sign_and_setup_signing_needs_a_key(client: TestClient) -> None:
    link = client.post("/links", json={"url": "tcp:127.0.0.1:9"}).json()
    assert (link["signing"], link["allow_unsigned"]) == (False, False)
    assert (link["refused_unsigned"], link["refused_bad_signature"]) == (0, 0)
    r = client.post("/vehicles/1/signing")
    assert r.status_code == 409
    assert "no signing key" in r.json()["detail"]
    assert client.post("/vehicles/0/signing").status_code == 422
    assert client.post("/vehicles/256/signing").status_code == 422


def test_signing_links_and_setup_signing_never_answer_the_key(tmp_path: Path) -> None:
    passphrase = "api test passphrase"
    settings = Settings(
        db=tmp_path / "gcs.db",
        tlog_dir=None,
        signing_key=passphrase,
        unsigned_links=["tcp:127.0.0.1:11"],
    )
    with TestClient(create_app(settings)) as c:
        signed = c.post("/links", json={"url": "tcp:127.0.0.1:9"}).json()
        assert (signed["signing"], signed["allow_unsigned"]) == (True, False)
        lenient = c.post("/links", json={"url": "tcp:127.0.0.1:10", "allow_unsigned": True})
        assert lenient.json()["allow_unsigned"] is True
        listed = c.post("/links", json={"url": "tcp:127.0.0.1:11"}).json()
        assert listed["allow_unsigned"] is True  # from the settings' unsigned_links
        r = c.post("/vehicles/7/signing")
        assert r.status_code == 404
        assert "vehicle 7 has not been heard" in r.json()["detail"]
        answers = [c.get(p).text for p in ("/links", "/vehicles", "/openapi.json")]
    key_hex = settings.signing_key_bytes.hex() if settings.signing_key_bytes else ""
    for text in answers:
        assert passphrase not in text
        assert key_hex not in text

"""The authenticated API (issue 26, item 5): bearer tokens with scopes on every route but
/health and the WebSockets, the audit log of command requests, size limits, the link
allow-list, and the refusal of an open API off loopback."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from api.app import create_app
from api.auth import ExposureError
from gcs_ppf.service.settings import Settings
from gcs_ppf.tokens import new_token
from tests.conftest import EXAMPLES

READER, READER_ENTRY = new_token("viewer", ("read",))
COMMANDER, COMMANDER_ENTRY = new_token("ops", ("read", "command"))
OPEN_ROUTES = {"/health", "/", "/docs", "/docs/oauth2-redirect", "/redoc", "/openapi.json"}


def bearer(token: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {token}"}


def table3() -> dict[str, Any]:
    doc: dict[str, Any] = json.loads((EXAMPLES / "paper_table3.json").read_text())
    return doc


@pytest.fixture
def settings(tmp_path: Path) -> Settings:
    return Settings(
        db=tmp_path / "gcs.db",
        tlog_dir=None,
        tokens=[READER_ENTRY, COMMANDER_ENTRY],
        link_allow=["192.0.2.0/24", "gcs-sitl.example"],
        max_body_bytes=200_000,
        max_vehicles=5,
        max_obstacles=4,
    )


@pytest.fixture
def client(settings: Settings) -> Iterator[TestClient]:
    with TestClient(create_app(settings)) as c:
        yield c


def audit_lines(settings: Settings) -> list[dict[str, Any]]:
    path = settings.audit_path()
    assert path is not None
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines()]


def every_route(client: TestClient) -> list[tuple[str, str]]:
    """(method, path) of every route of the OpenAPI schema, ids filled in as 1."""
    out = []
    for path, methods in client.app.openapi()["paths"].items():  # type: ignore[attr-defined]
        for method in methods:
            for name in ("{mission_id}", "{link_id}", "{run_id}"):
                path = path.replace(name, "1")
            out.append((method.upper(), path))
    return out


def test_every_route_but_health_needs_a_token(client: TestClient) -> None:
    routes = every_route(client)
    assert len(routes) >= 15
    for method, path in routes:
        r = client.request(method, path)
        if path in OPEN_ROUTES:
            assert r.status_code == 200, path
            continue
        assert r.status_code == 401, (method, path, r.status_code)
        assert r.headers["www-authenticate"].startswith("Bearer"), path
        assert "token" in r.json()["detail"]
    assert client.get("/health").json() == {"status": "ok"}


def test_unknown_or_malformed_tokens_are_401(client: TestClient) -> None:
    for headers in (
        bearer("not-a-token"),
        bearer(COMMANDER + "x"),
        {"Authorization": f"Basic {COMMANDER}"},
        {"Authorization": COMMANDER},
    ):
        r = client.get("/missions", headers=headers)
        assert r.status_code == 401, headers
    assert client.get("/missions", headers=bearer(READER)).status_code == 200


def test_a_read_token_reads_and_commands_nothing(client: TestClient) -> None:
    mid = client.post("/missions", json=table3(), headers=bearer(COMMANDER)).json()["id"]
    for method, path in every_route(client):
        if path in OPEN_ROUTES:
            continue
        path = path.replace("/missions/1", f"/missions/{mid}")
        r = client.request(method, path, headers=bearer(READER))
        if method == "GET" or path.endswith("/plan"):
            assert r.status_code in (200, 404), (method, path, r.status_code)
        else:
            assert r.status_code == 403, (method, path, r.status_code)
            assert "'viewer' lacks the scope 'command'" in r.json()["detail"]
            assert "insufficient_scope" in r.headers["www-authenticate"]
    # nothing changed: the mission as it was, no run, no link
    stored = client.get(f"/missions/{mid}", headers=bearer(READER)).json()["mission"]
    assert len(stored["obstacles"]) == 4
    assert client.get("/runs", headers=bearer(READER)).json() == []
    assert client.get("/links", headers=bearer(READER)).json() == []


def test_a_command_token_does_what_it_did_without_tokens(client: TestClient) -> None:
    h = bearer(COMMANDER)
    created = client.post("/missions", json=table3(), headers=h)
    assert created.status_code == 201
    mid = created.json()["id"]
    one = [{"center": [0, 0, 0], "radius": 50}]
    ok = client.put(f"/missions/{mid}/obstacles", json=one, headers=h)
    assert ok.status_code == 200
    start = client.post(f"/missions/{mid}/start", headers=h)
    assert start.status_code == 409  # no vehicles heard: the service's answer, not the auth's
    assert start.json()["info"]["missing_ids"] == [1, 2, 3, 4, 5]
    assert client.post(f"/missions/{mid}/abort", headers=h).status_code == 409
    link = client.post("/links", json={"url": "tcp:127.0.0.1:9"}, headers=h)
    assert link.status_code == 201
    assert client.delete(f"/links/{link.json()['id']}", headers=h).status_code == 204


def test_websockets_need_a_token(client: TestClient) -> None:
    for path in ("/ws/telemetry", "/ws/view"):
        for kwargs in ({}, {"headers": bearer("wrong")}, {"subprotocols": ["gcs-ppf", "bearer.x"]}):
            with (
                pytest.raises(WebSocketDisconnect) as refused,
                client.websocket_connect(path, **kwargs) as ws,
            ):
                ws.receive_json()
            assert refused.value.code == 1008, (path, kwargs)
        with client.websocket_connect(path, headers=bearer(READER)) as ws:
            assert "vehicles" in ws.receive_json()
        # the browser's way: the token as a subprotocol, answered with gcs-ppf
        with client.websocket_connect(path, subprotocols=["gcs-ppf", f"bearer.{READER}"]) as ws:
            assert ws.accepted_subprotocol == "gcs-ppf"
            assert "vehicles" in ws.receive_json()


def test_the_audit_log_holds_one_line_per_command_request(
    client: TestClient, settings: Settings
) -> None:
    h = bearer(COMMANDER)
    mid = client.post("/missions", json=table3(), headers=h).json()["id"]
    client.get("/missions", headers=h)  # a read: not audited
    client.post(f"/missions/{mid}/start", headers=h)
    client.post(f"/missions/{mid}/abort", headers=bearer(READER))
    client.post(f"/missions/{mid}/abort")
    client.post("/links", json={"url": "tcp:127.0.0.1:9"}, headers=h)
    lines = audit_lines(settings)
    assert [(x["method"], x["path"], x["token_id"], x["status"]) for x in lines] == [
        ("POST", "/missions", "ops", 201),
        ("POST", f"/missions/{mid}/start", "ops", 409),
        ("POST", f"/missions/{mid}/abort", "viewer", 403),
        ("POST", f"/missions/{mid}/abort", None, 401),
        ("POST", "/links", "ops", 201),
    ]
    assert lines[0]["outcome"] == "ok"
    assert lines[0]["body"] == table3()  # small enough to be kept whole
    assert lines[1]["outcome"].startswith("vehicles not connected: [1, 2, 3, 4, 5]")
    assert "lacks the scope" in lines[2]["outcome"]
    assert lines[4]["body"] == {"url": "tcp:127.0.0.1:9"}
    assert all(x["time"].endswith("+00:00") for x in lines)
    # no token is ever written
    text = settings.audit_path().read_text()  # type: ignore[union-attr]
    assert COMMANDER not in text
    assert READER not in text


def test_bodies_beyond_the_limit_are_413_and_change_nothing(
    client: TestClient, settings: Settings
) -> None:
    h = bearer(COMMANDER)
    big = json.dumps({**table3(), "name": "x" * 300_000}).encode()
    r = client.post("/missions", content=big, headers={**h, "content-type": "application/json"})
    assert r.status_code == 413
    assert "200000 bytes" in r.json()["detail"]
    assert "GCS_PPF_MAX_BODY_BYTES" in r.json()["detail"]

    def chunks() -> Iterator[bytes]:  # no Content-Length: counted as it comes
        for _ in range(30):
            yield b" " * 10_000

    r = client.post("/missions", content=chunks(), headers=h)
    assert r.status_code == 413
    assert client.get("/missions", headers=h).json() == []
    assert [x["status"] for x in audit_lines(settings)] == [413, 413]


def test_documents_beyond_the_limits_are_413_naming_the_list(client: TestClient) -> None:
    h = bearer(COMMANDER)
    doc = table3()
    extra = {**doc["vehicles"][-1], "id": 6, "position": [9000, 9000, 300], "slot": [-400, 400, 0]}
    r = client.post("/missions", json={**doc, "vehicles": [*doc["vehicles"], extra]}, headers=h)
    assert r.status_code == 413
    assert r.json()["detail"].startswith("vehicles: 6 vehicles, the service takes at most 5")
    obstacles = [{"center": [0, 0, 1000 * i], "radius": 10} for i in range(5)]
    r = client.post("/missions", json={**doc, "obstacles": obstacles}, headers=h)
    assert r.status_code == 413
    assert r.json()["detail"].startswith("obstacles: 5 obstacles")
    mid = client.post("/missions", json=doc, headers=h).json()["id"]
    r = client.put(f"/missions/{mid}/obstacles", json=obstacles, headers=h)
    assert r.status_code == 413
    assert r.json()["info"] == {"field": "obstacles", "count": 5, "limit": 4}
    assert len(client.get(f"/missions/{mid}", headers=h).json()["mission"]["obstacles"]) == 4
    assert [m["id"] for m in client.get("/missions", headers=h).json()] == [mid]


def test_a_422_does_not_echo_a_large_input(client: TestClient) -> None:
    doc = {**table3(), "target": "y" * 100_000}
    r = client.post("/missions", json=doc, headers=bearer(COMMANDER))
    assert r.status_code == 422
    assert len(r.content) < 2000
    assert "target" in json.dumps(r.json()["detail"])


def test_links_beyond_loopback_only_to_the_allow_list(client: TestClient) -> None:
    h = bearer(COMMANDER)
    refused = (
        "tcp:10.1.2.3:5760",
        "udpin:0.0.0.0:14550",
        "tcp:x.example:80",
        "udp:[2001:db8::1]:1",
    )
    for url in (*refused, "serial:/dev/sda:57600", "serial:/etc/passwd:9600"):
        r = client.post("/links", json={"url": url}, headers=h)
        assert r.status_code == 403, url
        assert "link_allow" in r.json()["detail"]
    assert client.get("/links", headers=h).json() == []
    allowed = (
        "tcp:192.0.2.7:5760",
        "tcp:GCS-SITL.example:5760",
        "tcp:localhost:9",
        "tcp:[::1]:9",
        "serial:/dev/ttyUSB9:57600",  # a terminal, tried again until it is there
    )
    for url in allowed:
        r = client.post("/links", json={"url": url}, headers=h)
        assert r.status_code == 201, (url, r.text)
        assert client.delete(f"/links/{r.json()['id']}", headers=h).status_code == 204
    assert client.post("/links", json={"url": "carrier-pigeon:1"}, headers=h).status_code == 400


def test_an_open_api_only_on_loopback(tmp_path: Path) -> None:
    for host in ("0.0.0.0", "::", "192.168.1.10", "gcs.example"):
        with pytest.raises(ExposureError, match=r"no API token is configured.*gcs-ppf token"):
            create_app(Settings(host=host, db=tmp_path / "a.db", tlog_dir=None))
    secured = Settings(host="0.0.0.0", db=tmp_path / "a.db", tlog_dir=None, tokens=[READER_ENTRY])
    assert create_app(secured).state.keyring.by_hash
    # open on loopback: every request passes, audited as "open"
    settings = Settings(db=tmp_path / "b.db", tlog_dir=None)
    with TestClient(create_app(settings)) as c:
        assert c.post("/missions", json=table3()).status_code == 201
        with c.websocket_connect("/ws/telemetry") as ws:
            assert "vehicles" in ws.receive_json()
    assert [x["token_id"] for x in audit_lines(settings)] == ["open"]


def test_tokens_from_a_file(tmp_path: Path) -> None:
    token_file = tmp_path / "tokens.json"
    token_file.write_text(json.dumps([COMMANDER_ENTRY.model_dump(mode="json")]))
    settings = Settings(db=tmp_path / "c.db", tlog_dir=None, token_file=token_file)
    with TestClient(create_app(settings)) as c:
        assert c.get("/missions").status_code == 401
        assert c.get("/missions", headers=bearer(COMMANDER)).status_code == 200
        assert c.get("/missions", headers=bearer(READER)).status_code == 401

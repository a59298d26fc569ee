"""Signed MAVLink on the whole product: ``python -m sitl`` and ``gcs-ppf serve`` share a key
(a file for the SITL, ``GCS_PPF_SIGNING_KEY`` for the service); Table 3 is flown; intruders
on the vehicle's port and on a link of the service, unsigned or with another key, change
nothing; the key is in no process's arguments and in no file the run wrote."""

from __future__ import annotations

import hashlib
import json
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from pymavlink import mavutil

from gcs_ppf.tools.campaign import process
from gcs_ppf.tools.demo import http_json as http
from gcs_ppf.tools.observer import free_port, free_port_block
from tests.checks import wait_for
from tests.integration.test_service_sitl import (
    MISSION,
    _vehicle_count,
    check_safety,
    commands_sent,
    fly,
)
from tests.sitl.sitl_helpers import TWO, Client

PASSPHRASE = "integration signing passphrase 26"
KEY = hashlib.sha256(PASSPHRASE.encode()).digest()
WRONG_KEY = hashlib.sha256(b"a wrong key").digest()
GUIDED, RTL = 15, 11


def _intruder(url: str, key: bytes | None) -> Any:
    conn = mavutil.mavlink_connection(url, source_system=255, source_component=190)
    if key is not None:
        conn.setup_signing(key, sign_outgoing=True)
        conn.mav.signing.timestamp += 10**12  # far ahead of the real streams
    return conn


def _modes(port: int, seconds: float) -> list[int]:
    """The leader's HEARTBEAT modes heard for ``seconds`` by a listener that sends nothing."""
    conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=251)
    modes = []
    deadline = time.monotonic() + seconds
    try:
        while time.monotonic() < deadline:
            hb = conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.2)
            if hb is not None and hb.get_srcSystem() == 1:
                modes.append(int(hb.custom_mode))
    finally:
        conn.close()
    return modes


def _processes_showing(secrets: list[bytes]) -> list[str]:
    """Every process whose command line (what ``ps`` shows) holds one of ``secrets``."""
    found = []
    for cmdline in Path("/proc").glob("[0-9]*/cmdline"):
        try:
            args = cmdline.read_bytes()
        except OSError:
            continue
        if any(s in args for s in secrets):
            found.append(args.replace(b"\0", b" ").decode(errors="replace"))
    return found


@pytest.mark.integration
def test_table3_signed_intruders_refused_and_the_key_nowhere(tmp_path: Path) -> None:
    secrets = [PASSPHRASE.encode(), KEY, KEY.hex().encode(), KEY.hex().upper().encode()]
    key_dir = tmp_path / "secret"
    key_dir.mkdir()
    key_file = key_dir / "sitl.key"
    key_file.write_text(PASSPHRASE + "\n")
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    seen: dict[str, Any] = {}

    def intrude(api: str, mid: int) -> None:
        time.sleep(0.5)  # ~5 s into the flight at the SITL's 10×
        status, links = http("GET", f"{api}/links")
        assert status == 200
        assert all(link["signing"] and not link["allow_unsigned"] for link in links)
        leader = next(link for link in links if 1 in link["vehicles"])
        port = int(leader["url"].rsplit(":", 1)[1])
        seen["ps"] = _processes_showing(secrets)
        # On the vehicle's own port, as the GCS's ids: RTL twice over and a course west.
        for key in (None, WRONG_KEY):
            bad = _intruder(f"tcp:127.0.0.1:{port}", key)
            bad.mav.command_long_send(1, 1, 176, 0, 1, RTL, 0, 0, 0, 0, 0)
            bad.mav.set_mode_send(1, 1, RTL)
            bad.mav.command_int_send(1, 1, 0, 43002, 0, 0, 0, 270.0, 100.0, 0, 0, 0, 0)
            seen.setdefault("acks", []).append(
                bad.recv_match(type="COMMAND_ACK", blocking=True, timeout=1.0)
            )
            bad.close()
        seen["modes"] = _modes(port, 1.5)
        # On a link of the service's: forged heartbeats and positions of the leader.
        udp = free_port()
        status, added = http("POST", f"{api}/links", {"url": f"udpin:127.0.0.1:{udp}"})
        assert status == 201, added
        # (sent until refused: the first datagrams may come before the socket is bound)
        for key, count in ((None, "refused_unsigned"), (WRONG_KEY, "refused_bad_signature")):
            forger = _intruder(f"udpout:127.0.0.1:{udp}", key)
            forger.mav.srcSystem, forger.mav.srcComponent = 1, 1  # as the leader
            deadline = time.monotonic() + 10.0
            while time.monotonic() < deadline:
                forger.mav.heartbeat_send(1, 3, 129, RTL, 4)
                forger.mav.global_position_int_send(1000, 0, 0, 500_000, 10_000, 0, 0, 0, 0)
                time.sleep(0.1)
                _, links = http("GET", f"{api}/links")
                link = next(link for link in links if link["id"] == added["id"])
                if link[count] >= 10:
                    break
            forger.close()
        time.sleep(1.5)  # the service's next heartbeat tells what was refused last
        _, links = http("GET", f"{api}/links")
        seen["forged_link"] = next(link for link in links if link["id"] == added["id"])
        status, vehicles = http("GET", f"{api}/vehicles")
        seen["leader"] = next(v for v in vehicles if v["system_id"] == 1)

    env = {"GCS_PPF_SIGNING_KEY": PASSPHRASE, "GCS_PPF_TLOG_DIR": str(run_dir / "tlogs")}
    flight = fly(
        run_dir,
        json.loads(MISSION.read_text()),
        sitl_extra=["--signing-key-file", str(key_file)],
        env_extra=env,
        during=intrude,
    )
    assert flight.final["state"] == "completed", flight.final
    _, separation, clearance = check_safety(flight)
    assert {43001, 43002} <= commands_sent(run_dir / "tlogs")  # the service was obeyed

    assert seen["ps"] == []
    assert seen["acks"] == [None, None]  # an unsigned SITL answers every one of them
    assert seen["modes"]
    assert set(seen["modes"]) == {GUIDED}
    forged = seen["forged_link"]
    assert forged["vehicles"] == []
    assert forged["refused_unsigned"] >= 10
    assert forged["refused_bad_signature"] >= 10
    assert seen["leader"]["link_id"] != forged["id"]
    assert seen["leader"]["mode"] == "GUIDED"

    log = (run_dir / "gcs.log").read_text()
    refused = [line for line in log.splitlines() if "wrongly signed or replayed" in line]
    assert any("udpin:127.0.0.1:" in line and "refused 0 unsigned" not in line for line in refused)
    assert any("and 0 wrongly signed" not in line for line in refused), refused
    written = [p for p in run_dir.rglob("*") if p.is_file()]
    assert len(written) >= 4  # logs, tlogs, the database
    for path in written:
        data = path.read_bytes()
        for s in secrets:
            assert s not in data, f"{path} holds the key"
    print(
        f"\nsigned Table 3: mission time {flight.final['mission_time_s']:.1f} s, separation "
        f"{separation:.1f} m, clearance {clearance:.1f} m; forged frames refused on the "
        f"service's link: {forged['refused_unsigned']} unsigned, "
        f"{forged['refused_bad_signature']} wrongly signed; files checked: {len(written)}"
    )


@pytest.mark.integration
def test_setup_signing_from_the_operator_makes_an_unsigned_vehicle_sign(tmp_path: Path) -> None:
    """A SITL without a key on a link that allows unsigned frames; ``POST /vehicles/1/signing``
    installs the service's key: from then on the vehicle signs (the service still hears it
    and counts no refusal) and an unsigned client's command is not answered."""
    base, api_port = free_port_block(20), free_port_block(1)
    api = f"http://127.0.0.1:{api_port}"
    links = [f"tcp:127.0.0.1:{base}", f"tcp:127.0.0.1:{base + 10}"]
    serve = [sys.executable, "-m", "gcs_ppf.cli", "serve", "--port", str(api_port)]
    serve += ["--db", str(tmp_path / "gcs.db"), *(a for u in links for a in ("--link", u))]
    env = {
        "GCS_PPF_SIGNING_KEY": PASSPHRASE,
        "GCS_PPF_UNSIGNED_LINKS": json.dumps(links),
        "GCS_PPF_TLOG_DIR": str(tmp_path / "tlogs"),
    }
    sitl = [sys.executable, "-m", "sitl", str(TWO), "--speedup", "10", "--base-port", str(base)]
    with process(sitl, tmp_path / "sitl.log"), process(serve, tmp_path / "gcs.log", env):
        wait_for(lambda: _vehicle_count(api) == 2, 60, "vehicles discovered")
        with Client(base) as plain:  # before: unsigned commands are obeyed
            assert plain.set_mode(1, GUIDED).result == 0
        status, body = http("POST", f"{api}/vehicles/1/signing")
        assert status == 200, body
        assert body == {"system_id": 1, "link_id": 1, "sent": True}
        with Client(base) as plain:
            plain.mav.command_long_send(1, 1, 176, 0, 1, 12, 0, 0, 0, 0, 0)
            with pytest.raises(TimeoutError):
                plain.wait("COMMAND_ACK", timeout=1.0)
            plain.drain()
            hb = plain.wait("HEARTBEAT", lambda m: m.get_srcSystem() == 1)
            assert hb.get_msgbuf()[2] & 0x01  # MAVLINK_IFLAG_SIGNED
        time.sleep(1.0)
        _, vehicles = http("GET", f"{api}/vehicles")
        heard = {v["system_id"]: v for v in vehicles}
        assert heard[1]["seconds_since_heard"] < 1.0
        assert not heard[1]["lost"]
        _, listed = http("GET", f"{api}/links")
        assert listed[0]["refused_bad_signature"] == 0
    for path in [p for p in tmp_path.rglob("*") if p.is_file()]:
        assert KEY not in path.read_bytes(), path
        assert PASSPHRASE.encode() not in path.read_bytes(), path

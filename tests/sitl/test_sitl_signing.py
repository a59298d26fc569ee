"""The built-in SITL signing as ArduPlane does: a key from a file or the environment (never
needed on the command line), SETUP_SIGNING, and commands from unsigned or wrongly signed
clients refused without effect."""

from __future__ import annotations

import hashlib
import math
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from tests.sitl.sitl_helpers import REPO, TWO, Client, run_sitl

pytestmark = pytest.mark.realtime  # `python -m sitl` processes over UDP

PASSPHRASE = "sitl signing test passphrase"
KEY = hashlib.sha256(PASSPHRASE.encode()).digest()
GUIDED, RTL = 15, 11
HEADING = 43002  # MAV_CMD_GUIDED_CHANGE_HEADING


@contextmanager
def signed_client(port: int, key: bytes = KEY, **kw: Any) -> Iterator[Client]:
    with Client(port, **kw) as c:
        c.conn.setup_signing(key, sign_outgoing=True)
        yield c


def course_deg(c: Client) -> float:
    """The vehicle's course over ground from its GLOBAL_POSITION_INT (deg from north)."""
    m = c.wait("GLOBAL_POSITION_INT")
    return math.degrees(math.atan2(m.vy, m.vx)) % 360.0


def mode_of(c: Client) -> int:
    return int(c.wait("HEARTBEAT", lambda m: m.get_srcSystem() == 1).custom_mode)


def set_course(c: Client, heading_deg: float) -> Any:
    return c.command_int(1, HEADING, 0, 0, heading_deg, 100.0, 0, 0, 0, 0)


def attack(port: int) -> None:
    """An intruder on the vehicle's port, as the GCS's own ids: RTL by COMMAND_LONG and by
    SET_MODE, and a course due west; none of it may be answered or acted on."""
    with Client(port) as bad:
        bad.mav.command_long_send(1, 1, 176, 0, 1, RTL, 0, 0, 0, 0, 0)
        bad.mav.set_mode_send(1, 1, RTL)
        bad.mav.command_int_send(1, 1, 0, HEADING, 0, 0, 0, 270.0, 100.0, 0, 0, 0, 0)
        with pytest.raises(TimeoutError):
            bad.wait("COMMAND_ACK", timeout=1.0)


def attack_with_wrong_key(port: int) -> None:
    with Client(port) as bad:
        bad.conn.setup_signing(hashlib.sha256(b"not the key").digest(), sign_outgoing=True)
        bad.mav.signing.timestamp += 10**12  # far ahead: must not lock out the real GCS
        bad.mav.command_long_send(1, 1, 176, 0, 1, RTL, 0, 0, 0, 0, 0)
        bad.mav.set_mode_send(1, 1, RTL)
        bad.mav.command_int_send(1, 1, 0, HEADING, 0, 0, 0, 270.0, 100.0, 0, 0, 0, 0)
        with pytest.raises(TimeoutError):
            bad.wait("COMMAND_ACK", timeout=1.0)


def check_refuses_intruders(port: int) -> None:
    with signed_client(port) as gcs:
        assert gcs.set_mode(1, GUIDED).result == 0
        assert set_course(gcs, 90.0).result == 0  # east, as it flies
        attack(port)
        attack_with_wrong_key(port)
        time.sleep(1.0)  # 10 s of the vehicle's time at ×10: a turn west takes ~3 s
        gcs.drain()
        assert mode_of(gcs) == GUIDED
        assert abs(math.remainder(course_deg(gcs) - 90.0, 360.0)) < 5.0
        # The real GCS is still obeyed on the same stream ids after the forger's frames.
        assert gcs.set_mode(1, 12).result == 0  # LOITER
        assert mode_of(gcs) == 12


def test_key_from_a_file_refuses_unsigned_and_wrongly_signed_commands(tmp_path: Path) -> None:
    key_file = tmp_path / "key"
    key_file.write_text(PASSPHRASE + "\n")
    with run_sitl(TWO, "--signing-key-file", str(key_file)) as sitl:
        cmdline = Path(f"/proc/{sitl.proc.pid}/cmdline").read_bytes()
        assert PASSPHRASE.encode() not in cmdline
        assert KEY.hex().encode() not in cmdline
        check_refuses_intruders(sitl.port(0))


def test_key_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("SITL_SIGNING_KEY", KEY.hex())
    with run_sitl(TWO) as sitl:
        assert KEY.hex().encode() not in Path(f"/proc/{sitl.proc.pid}/cmdline").read_bytes()
        with Client(sitl.port(0)) as plain:
            plain.mav.command_long_send(1, 1, 176, 0, 1, GUIDED, 0, 0, 0, 0, 0)
            with pytest.raises(TimeoutError):
                plain.wait("COMMAND_ACK", timeout=1.0)
        with signed_client(sitl.port(0)) as gcs:
            assert gcs.set_mode(1, GUIDED).result == 0


def test_two_key_sources_are_an_error(tmp_path: Path) -> None:
    key_file = tmp_path / "key"
    key_file.write_text(PASSPHRASE)
    env = {**os.environ, "SITL_SIGNING_KEY": PASSPHRASE}
    args = [sys.executable, "-m", "sitl", str(TWO), "--signing-key-file", str(key_file)]
    done = subprocess.run(args, cwd=REPO, env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 2
    assert "--signing-key-file and SITL_SIGNING_KEY" in done.stderr
    assert PASSPHRASE not in done.stderr


def test_setup_signing_installs_the_key_and_only_its_holder_can_change_it() -> None:
    with run_sitl(TWO) as sitl:
        port = sitl.port(0)
        with Client(port) as gcs:
            assert gcs.set_mode(1, GUIDED).result == 0  # no key yet: unsigned is obeyed
            gcs.mav.setup_signing_send(1, 1, list(KEY), 0)
            time.sleep(0.3)
            gcs.mav.command_long_send(1, 1, 176, 0, 1, 12, 0, 0, 0, 0, 0)
            with pytest.raises(TimeoutError):  # now unsigned commands are refused
                gcs.wait("COMMAND_ACK", timeout=1.0)
            # An unsigned SETUP_SIGNING cannot take the key away again.
            gcs.mav.setup_signing_send(1, 1, [0] * 32, 0)
        check_refuses_intruders(port)
        with signed_client(port) as holder:
            holder.mav.setup_signing_send(1, 1, [0] * 32, 0)  # all zeros: signing off
            time.sleep(0.3)
        with Client(port) as plain:
            assert plain.set_mode(1, GUIDED).result == 0

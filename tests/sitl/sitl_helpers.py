"""Helpers of the SITL tests: run ``python -m sitl`` as a subprocess and talk to it."""

from __future__ import annotations

import os

os.environ.setdefault("MAVLINK20", "1")  # before mavutil is imported: MAVLink 2 clients

import contextlib
import random
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from pymavlink import mavutil

HERE = Path(__file__).parent
REPO = HERE.parent.parent
PAPER = HERE / "mission_paper.json"
TWO = HERE / "mission_two.json"
SLOW = HERE / "mission_slow.json"


def free_base_port(n_vehicles: int) -> int:
    """A base port P such that P + 10·i is free for every vehicle i."""
    for _ in range(200):
        base = random.randrange(20000, 60000, 10)
        socks = []
        try:
            for i in range(n_vehicles):
                s = socket.socket()
                socks.append(s)
                s.bind(("127.0.0.1", base + 10 * i))
            return base
        except OSError:
            continue
        finally:
            for s in socks:
                s.close()
    raise RuntimeError("no free ports")


class Sitl:
    """A running ``python -m sitl`` subprocess."""

    def __init__(self, proc: subprocess.Popen[str], base_port: int) -> None:
        self.proc = proc
        self.base_port = base_port
        self.lines: list[str] = []

    def port(self, index: int = 0) -> int:
        return self.base_port + 10 * index

    def stop(self, timeout: float = 10.0) -> int:
        if self.proc.poll() is None:
            self.proc.terminate()
        try:
            return self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(5)
            raise


@contextlib.contextmanager
def run_sitl(
    mission: Path = TWO, *args: str, speedup: float = 10.0, n_vehicles: int = 2
) -> Iterator[Sitl]:
    base = free_base_port(n_vehicles)
    cmd = [sys.executable, "-m", "sitl", str(mission), "--speedup", str(speedup)]
    cmd += ["--base-port", str(base), *args]
    proc = subprocess.Popen(
        cmd, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    sitl = Sitl(proc, base)
    try:
        deadline = time.monotonic() + 15
        assert proc.stdout is not None
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                raise RuntimeError(f"sitl exited: {proc.stderr.read() if proc.stderr else ''}")
            sitl.lines.append(line.strip())
            if line.startswith("sitl ready"):
                break
        else:
            raise RuntimeError("sitl did not get ready")
        yield sitl
    finally:
        code = sitl.stop()
        assert code == 0, f"sitl exit code {code}"


class Client:
    """A pymavlink GCS connection to one vehicle port (blocking, for tests)."""

    def __init__(self, port: int, sysid: int = 255, compid: int = 190, **kw: Any) -> None:
        self.conn = mavutil.mavlink_connection(
            f"tcp:127.0.0.1:{port}", source_system=sysid, source_component=compid, **kw
        )
        self.mav = self.conn.mav

    def close(self) -> None:
        self.conn.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def wait(
        self,
        mtype: str | list[str],
        cond: Callable[[Any], bool] = lambda m: True,
        timeout: float = 5.0,
    ) -> Any:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            msg = self.conn.recv_match(type=mtype, blocking=True, timeout=0.2)
            if msg is not None and cond(msg):
                return msg
        raise TimeoutError(f"no {mtype} within {timeout} s")

    def drain(self) -> None:
        while self.conn.recv_match(blocking=False) is not None:
            pass

    def command_long(self, target: int, command: int, *params: float, timeout: float = 5.0) -> Any:
        p = [*params, *([0.0] * (7 - len(params)))]
        self.mav.command_long_send(target, 1, command, 0, *p)
        return self.wait("COMMAND_ACK", lambda m: m.command == command, timeout)

    def command_int(
        self, target: int, command: int, frame: int, p1: float, p2: float, p3: float, p4: float,
        x: int, y: int, z: float, timeout: float = 5.0,
    ) -> Any:  # fmt: skip
        self.mav.command_int_send(target, 1, frame, command, 0, 0, p1, p2, p3, p4, x, y, z)
        return self.wait("COMMAND_ACK", lambda m: m.command == command, timeout)

    def set_mode(self, target: int, mode: int) -> Any:
        return self.command_long(target, 176, 1, mode)

    def heartbeat(self) -> None:
        self.mav.heartbeat_send(6, 8, 0, 0, 4)

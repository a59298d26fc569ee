"""Tick latency of the service (telemetry received → commands sent), p50 / p99, and where the
tick's time goes.

``python -m gcs_ppf.tools.service_benchmark [--vehicles 5 50] [--seconds 20] [--burner]``
flies a synthetic formation (a leader and wingmen in rows of ten, no obstacles) on the
built-in SITL at 1× (with ``--burner``, beside a process that keeps one core busy) with
the service at its default 10 Hz tick, and prints the latency percentiles the service
measured, the tick's cost per vehicle, and each phase's p50 and mean
(``gcs_ppf.service.tick_phases``; the status's ``tick_phases_ms``).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import tempfile
import time
import urllib.error
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from gcs_ppf.tools.demo import _wait_vehicles, http_json


def formation_mission(n: int) -> dict[str, Any]:
    vehicles = [{"id": 1, "role": "leader", "position": [0.0, 0.0, 500.0], "yaw": 0.0}]
    for k in range(1, n):
        row, col = (k - 1) // 10 + 1, (k - 1) % 10 - 4.5
        vehicles.append(
            {
                "id": k + 1,
                "role": "wingman",
                "yaw": 0.0,
                "position": [-150.0 * row - 200.0, 150.0 * col, 500.0],
                "slot": [-150.0 * row, 150.0 * col, 0.0],
            }
        )
    return {"name": f"bench-{n}", "target": [30_000.0, 0.0, 500.0], "vehicles": vehicles}


def measure(n: int, seconds: float, port: int, base_port: int) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "mission.json"
        path.write_text(json.dumps(formation_mission(n)))
        links = [a for k in range(n) for a in ("--link", f"tcp:127.0.0.1:{base_port + 10 * k}")]
        procs = [
            subprocess.Popen(
                [sys.executable, "-m", "sitl", str(path), "--base-port", str(base_port)],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            ),
            subprocess.Popen(
                [
                    sys.executable,
                    "-m",
                    "gcs_ppf.cli",
                    "serve",
                    "--port",
                    str(port),
                    "--db",
                    str(Path(tmp) / "db.sqlite"),
                    *links,
                ],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                env={
                    **os.environ,
                    "GCS_PPF_TLOG_DIR": str(Path(tmp) / "tlogs"),
                    "GCS_PPF_MAX_VEHICLES": str(max(n, 100)),  # its default takes 100
                },
            ),
        ]
        api = f"http://127.0.0.1:{port}"
        try:
            if not _wait_vehicles(api, n, DISCOVERY_S + DISCOVERY_PER_VEHICLE_S * n):
                heard = _heard(api)
                return {"vehicles": n, "error": f"{heard} of {n} vehicles heard: not measured"}
            code, created = http_json("POST", f"{api}/missions", formation_mission(n))
            if code != 201:
                return {"vehicles": n, "error": f"mission refused ({code}): {created}"}
            code, started = http_json("POST", f"{api}/missions/{created['id']}/start")
            if code != 202:
                return {"vehicles": n, "error": f"start refused ({code}): {started}"}
            cpu_before = cpu_s(procs[1].pid)
            time.sleep(seconds)
            cpu = cpu_s(procs[1].pid) - cpu_before
            try:
                _, status = http_json("GET", f"{api}/missions/{created['id']}/status")
                http_json("POST", f"{api}/missions/{created['id']}/abort")
            except (TimeoutError, urllib.error.URLError):  # the service too busy to answer
                return {"vehicles": n, "error": "no status (the service did not answer)"}
            return {
                "vehicles": n,
                **(status.get("tick_latency_ms") or {}),
                "phases": status.get("tick_phases_ms") or {},
                "cpu_s_per_s": cpu / seconds,
                "rate": status.get("tick_rate") or {},
            }
        finally:
            for p in procs:
                p.terminate()
                p.wait(timeout=10)


DISCOVERY_S = 60.0
DISCOVERY_PER_VEHICLE_S = 0.5
"""How long the service may take to hear every vehicle: a minute, and half a second more a
vehicle (the SITL's and the service's start, 250 links opened)."""


def _heard(api: str) -> int | str:
    """How many vehicles the service has heard ("?" if it does not answer)."""
    try:
        _, vehicles = http_json("GET", f"{api}/vehicles")
        return len(vehicles)
    except (OSError, ValueError):
        return "?"


def cpu_s(pid: int) -> float:
    """The CPU seconds (user + system) process ``pid`` has used (Linux's /proc; NaN
    elsewhere): what the service costs, whatever else the machine runs meanwhile."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return float("nan")
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--vehicles", type=int, nargs="+", default=[5, 50])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--port", type=int, default=18500)
    parser.add_argument(
        "--base-port",
        type=int,
        default=21760,
        help="the SITL's first port (below Linux's ephemeral 32768-60999: 250 vehicles' ports "
        "there met one a connection had taken)",
    )
    parser.add_argument(
        "--burner", action="store_true", help="a CPU burner on one core throughout (a busy machine)"
    )
    args = parser.parse_args(argv)
    print(
        "service tick latency, telemetry received → commands sent (10 Hz tick, SITL 1×"
        + (", a CPU burner on one core)" if args.burner else ")")
    )
    with burning(args.burner):
        rows = run_rows(args)
    print(summary(rows))


@contextlib.contextmanager
def burning(on: bool) -> Iterator[None]:
    """A process spinning on one core while the block runs (``on``), killed after."""
    burner = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if on else None
    try:
        yield
    finally:
        if burner is not None:
            burner.kill()
            burner.wait()


def run_rows(args: argparse.Namespace) -> list[dict[str, Any]]:
    rows = []
    for n in args.vehicles:
        r = measure(n, args.seconds, args.port, args.base_port)
        rows.append(r)
        if "error" in r:
            print(f"{n:>8} {r['error']}")
            continue
        print(HEADER + "  target p99")
        print(row(r) + f"  {target(n)}")
        print_phases(r["phases"])
    return rows


TARGETS_P99_MS = ((5, 10.0), (50, 20.0), (100, 50.0), (250, 100.0))
"""Issue 29's targets: the tick's p99 at up to this many vehicles (ms)."""


def target(n: int) -> str:
    for most, ms in TARGETS_P99_MS:
        if n <= most:
            return f"< {ms:g} ms"
    return "–"


def print_phases(phases: dict[str, dict[str, float]]) -> None:
    """Each phase's p50 and mean (ms) and its share of the tick's mean."""
    total = sum(p["mean"] for p in phases.values()) or float("nan")
    for name, p in phases.items():
        print(
            f"{'':>8} {name:<13} p50 {p['p50']:>8.2f}  mean {p['mean']:>8.2f} ms "
            f"({100 * p['mean'] / total:4.1f} %)  p99 {p['p99']:>8.2f}"
        )


HEADER = (
    f"{'vehicles':>8} {'ticks':>6} {'Hz':>5} {'p50 ms':>8} {'p99 ms':>8} "
    f"{'µs/vehicle':>10} {'CPU %':>6}"
)
"""A row's columns: ticks in the window, the rate measured (vehicle seconds), the latency's
p50 and p99, the p50 per vehicle, and the service's CPU over the window (% of one core)."""


def row(r: dict[str, Any]) -> str:
    n, nan = r["vehicles"], float("nan")
    p50 = r.get("p50", nan)
    hz = r.get("rate", {}).get("measured_hz")
    return (
        f"{n:>8} {r.get('ticks', 0):>6} {nan if hz is None else hz:>5.1f} {p50:>8.2f} "
        f"{r.get('p99', nan):>8.2f} {1e3 * p50 / n:>10.0f} "
        f"{100 * r.get('cpu_s_per_s', nan):>6.0f}"
    )


def summary(rows: list[dict[str, Any]]) -> str:
    """The rows again, one line each, for a table."""
    lines = [HEADER]
    for r in rows:
        lines.append(f"{r['vehicles']:>8} {r['error']}" if "error" in r else row(r))
    return "\n".join(lines)


if __name__ == "__main__":
    main()

"""Tick latency of the service (telemetry received → commands sent), p50 / p99.

``python -m gcs_ppf.tools.service_benchmark [--vehicles 5 50] [--seconds 20]`` flies a synthetic
formation (a leader and wingmen in rows of ten, no obstacles) on the built-in SITL at 1×
with the service at its default 10 Hz tick, and prints the latency percentiles the
service measured.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from gcs_ppf.tools.demo import _wait_vehicles, http_json


def formation_mission(n: int) -> dict[str, Any]:
    vehicles = [{"id": 1, "role": "leader", "position": [0.0, 0.0, 500.0], "yaw": 0.0}]
    for k in range(1, n):
        row, col = (k - 1) // 10 + 1, (k - 1) % 10 - 4.5
        vehicles.append({"id": k + 1, "role": "wingman", "yaw": 0.0,
                         "position": [-150.0 * row - 200.0, 150.0 * col, 500.0],
                         "slot": [-150.0 * row, 150.0 * col, 0.0]})  # fmt: skip
    return {"name": f"bench-{n}", "target": [30_000.0, 0.0, 500.0], "vehicles": vehicles}


def measure(n: int, seconds: float, port: int, base_port: int) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "mission.json"
        path.write_text(json.dumps(formation_mission(n)))
        links = [a for k in range(n) for a in ("--link", f"tcp:127.0.0.1:{base_port + 10 * k}")]
        procs = [
            subprocess.Popen([sys.executable, "-m", "sitl", str(path), "--base-port",
                              str(base_port)], stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL),
            subprocess.Popen([sys.executable, "-m", "gcs_ppf.cli", "serve", "--port", str(port),
                              "--db", str(Path(tmp) / "db.sqlite"), *links],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                             env={**os.environ, "GCS_PPF_TLOG_DIR": str(Path(tmp) / "tlogs")}),
        ]  # fmt: skip
        api = f"http://127.0.0.1:{port}"
        try:
            if not _wait_vehicles(api, n, 90.0):
                raise RuntimeError("vehicles not discovered")
            _, created = http_json("POST", f"{api}/missions", formation_mission(n))
            http_json("POST", f"{api}/missions/{created['id']}/start")
            time.sleep(seconds)
            _, status = http_json("GET", f"{api}/missions/{created['id']}/status")
            http_json("POST", f"{api}/missions/{created['id']}/abort")
            return {"vehicles": n, **(status.get("tick_latency_ms") or {})}
        finally:
            for p in procs:
                p.terminate()
                p.wait(timeout=10)


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--vehicles", type=int, nargs="+", default=[5, 50])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--port", type=int, default=18500)
    parser.add_argument("--base-port", type=int, default=36760)
    args = parser.parse_args(argv)
    print("service tick latency, telemetry received → commands sent (10 Hz tick, SITL 1×)")
    print(f"{'vehicles':>8} {'ticks':>6} {'p50 ms':>8} {'p99 ms':>8}  target p99")
    for n in args.vehicles:
        r = measure(n, args.seconds, args.port, args.base_port)
        target = "< 20 ms" if n <= 5 else "< 100 ms"
        print(f"{n:>8} {r.get('ticks', 0):>6} {r.get('p50', float('nan')):>8.2f} "
              f"{r.get('p99', float('nan')):>8.2f}  {target}")  # fmt: skip


if __name__ == "__main__":
    main()

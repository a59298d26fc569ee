"""``python -m sitl.benchmark``: how fast the SITL runs on one core.

Drives the real engine and the real per-client codecs (one client per vehicle, every message
packed as it would be for a TCP client; the socket write itself is replaced by a byte
counter) as fast as possible, single-threaded, and reports the real-time factor
(simulated seconds per wall second). A fleet is sustained at 1× when that factor is ≥ 1.
Physics runs at 50 Hz; telemetry is the default stream set (GLOBAL_POSITION_INT and
ATTITUDE at 10 Hz, VFR_HUD 4 Hz, GPS_RAW_INT 2 Hz, six more at 1 Hz), vehicles loitering.
"""

from __future__ import annotations

import argparse
import asyncio
import math
import time

from gcs_ppf.mission import Mission, Vehicle
from sitl.engine import ParamOverride, Simulation
from sitl.server import Peer, VehicleLink


def fleet_mission(n: int) -> Mission:
    """n vehicles on a 1 km grid, the first one leader, all loitering at 300 m."""
    side = math.ceil(math.sqrt(n))
    vehicles = []
    for k in range(n):
        pos = (1000.0 * (k % side), 1000.0 * (k // side), 300.0)
        if k == 0:
            vehicles.append(Vehicle(id=1, role="leader", position=pos))
        else:
            slot = (-100.0 * (k % 50 + 1), 100.0 * (k // 50 + 1), 0.0)
            vehicles.append(Vehicle(id=k + 1, role="wingman", position=pos, slot=slot))
    return Mission(target=(0.0, 0.0, 300.0), vehicles=vehicles)


class _Counter:
    def __init__(self) -> None:
        self.bytes = 0

    def __call__(self, data: bytes) -> None:
        self.bytes += len(data)


def real_time_factor(n: int, sim_seconds: float) -> tuple[float, int]:
    """(simulated s per wall s, bytes sent per simulated s) for a fleet of n vehicles."""

    async def run() -> tuple[float, int]:
        sim = Simulation(fleet_mission(n), params=[ParamOverride(None, "INITIAL_MODE", 12)])
        counter = _Counter()
        links = []
        for i in range(n):
            link = VehicleLink(sim, i, 1.0, 0, None, None)
            link.peers.append(Peer(link, counter, "bench"))
            links.append(link)
        steps = round(sim_seconds / 0.02)
        t0 = time.perf_counter()
        for _ in range(steps):
            for i, out in sim.step(0.0):
                links[i].send(out, None)
        wall = time.perf_counter() - t0
        return sim.sim_s / wall, round(counter.bytes / sim.sim_s)

    return asyncio.run(run())


#: MAVLink system ids 1–254 are vehicles (255 is the GCS): one process hosts at most 254.
MAX_FLEET = 254


def max_vehicles_at_1x(sim_seconds: float) -> tuple[int, float, int]:
    """(largest fleet ≤ MAX_FLEET with real-time factor ≥ 1, the factor of the full
    254-vehicle fleet, the fleet size one core would carry at 1× by linear extrapolation)."""
    rtf_full, _ = real_time_factor(MAX_FLEET, sim_seconds)
    extrapolated = int(MAX_FLEET * rtf_full)
    if rtf_full >= 1.0:
        return MAX_FLEET, rtf_full, extrapolated
    lo, hi = 1, MAX_FLEET
    while hi - lo > 2:
        mid = (lo + hi) // 2
        if real_time_factor(mid, sim_seconds)[0] >= 1.0:
            lo = mid
        else:
            hi = mid
    return lo, rtf_full, extrapolated


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m sitl.benchmark", description=__doc__)
    p.add_argument("--seconds", type=float, default=20.0, help="simulated seconds per trial")
    args = p.parse_args(argv)
    rtf5, bps5 = real_time_factor(5, max(args.seconds, 60.0))
    print(f"5 vehicles (paper scene size): max speedup {rtf5:.0f}x ({bps5} B/s of MAVLink at 1x)")
    n, rtf, extrapolated = max_vehicles_at_1x(args.seconds)
    print(
        f"vehicles sustained at 1x on one core: {n} "
        f"({MAX_FLEET} vehicles run at {rtf:.2f}x real time; "
        f"by linear extrapolation one core carries ~{extrapolated} at 1x)"
    )
    print("targets: >= 200 vehicles at 1x, >= 50x for 5 vehicles")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

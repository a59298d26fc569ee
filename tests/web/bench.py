"""The operator's page under load: N vehicles at H Hz, frames per second and JS heap measured
in headless chromium over a period (a benchmark that prints figures, not a test).

    python -m tests.web.bench [--minutes 10] [--vehicles 50] [--hz 10] [--size 1280x720]

The page is served as the service serves it (``api/static``, ``GET /``) with a synthetic
``/ws/view``: frames built by ``api.view.frame`` (so the same fields, local target points
and obstacle radii) for a formation of N vehicles flying a 6 km circle at 100 m/s, wingmen
weaving about their slots, PPF states and avoidance changing, an event every few seconds.
Every ``--sample-s`` it reads the page's own counters (animation frames drawn, time spent
drawing, frames received) and the JS heap (``performance.memory`` with precise memory info,
and the DevTools heap after a forced garbage collection at the start and the end).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import math
import statistics
import threading
import time
from collections.abc import Iterator
from typing import Any

import uvicorn
from fastapi import FastAPI, WebSocket, WebSocketDisconnect
from fastapi.responses import FileResponse
from fastapi.staticfiles import StaticFiles

from api.view import STATIC_DIR, frame
from gcs_ppf.mission import Mission
from tests.web.harness import browser, chromium_missing, free_port, screenshot, wait_for

RADIUS_M = 6000.0
SPEED_M_S = 100.0


def synthetic_mission(n: int) -> Mission:
    """A leader and n-1 wingmen in rows of ten behind it; six spheres about the circle."""
    vehicles: list[dict[str, Any]] = [
        {"id": 1, "role": "leader", "position": [RADIUS_M, 0.0, 500.0], "yaw": math.pi / 2}
    ]
    for k in range(1, n):
        row, col = divmod(k - 1, 10)
        slot = [-150.0 * (row + 1), 120.0 * (col - 4.5), 0.0]
        start = [RADIUS_M + 300.0 * (col - 4.5), -300.0 * (row + 1), 500.0]
        vehicles.append({"id": k + 1, "role": "wingman", "slot": slot, "yaw": math.pi / 2,
                         "position": start})  # fmt: skip
    obstacles = [
        {"center": [1.35 * RADIUS_M * math.cos(a), 1.35 * RADIUS_M * math.sin(a), 300.0],
         "radius": 600.0}
        for a in [i * math.pi / 3 for i in range(6)]
    ]  # fmt: skip
    return Mission.model_validate({
        "name": f"bench-{n}", "target": [0.0, 0.0, 3000.0], "vehicles": vehicles,
        "obstacles": obstacles, "limits": {"v_min": 50.0, "v_init": 100.0},
    })  # fmt: skip


KINDS = ("avoidance_entered", "avoidance_left", "formation_broken", "formation_formed",
         "conflict_resolution_began", "conflict_resolution_ended")  # fmt: skip


def synthetic_frame(mission: Mission, t: float, events: list[dict[str, Any]]) -> dict[str, Any]:
    """The view frame at mission time ``t``: the leader on the circle, each wingman near its
    slot (Eq. 6, leader's yaw), weaving by up to 60 m."""
    omega = SPEED_M_S / RADIUS_M
    a = omega * t
    yaw = a + math.pi / 2
    lx, ly = RADIUS_M * math.cos(a), RADIUS_M * math.sin(a)
    views, per_vehicle = [], []
    for k, v in enumerate(mission.vehicles):
        if v.slot is None:
            x, y, z = lx, ly, 500.0
        else:
            sx, sy, sz = v.slot
            wobble = 60.0 * math.sin(0.2 * t + k)
            x = lx + sx * math.cos(yaw) - (sy + wobble) * math.sin(yaw)
            y = ly + sx * math.sin(yaw) + (sy + wobble) * math.cos(yaw)
            z = 500.0 + sz + 20.0 * math.sin(0.1 * t + k)
        state = ("s1", "s1", "s1", "s3", "s2")[int(t / 5 + k) % 5]
        lost = k == len(mission.vehicles) - 1 and int(t / 30) % 2 == 1
        views.append({
            "id": v.id, "link_id": 1 + k // 10, "mode": "GUIDED", "armed": True, "lost": lost,
            "seconds_since_heard": 0.05, "pos_m": [round(x, 2), round(y, 2), round(z, 2)],
            "yaw_rad": round(yaw, 4), "pitch_rad": 0.0, "speed_m_s": SPEED_M_S,
        })  # fmt: skip
        off = None if v.slot is None else abs(60.0 * math.sin(0.2 * t + k))
        per_vehicle.append({
            "id": v.id, "ppf_state": state, "avoiding": state == "s2",
            "formed": bool(k) and state == "s1", "local_target_distance_m": off, "lost": lost,
        })  # fmt: skip
    status = {
        "mission_id": 1, "run_id": 1, "state": "running", "outcome": None,
        "mission_time_s": round(t, 3), "formation_formed": False, "min_separation_m": 95.0,
        "min_obstacle_clearance_m": 210.0, "safety_violations": 0, "tick_latency_ms": None,
        "vehicles": per_vehicle,
    }  # fmt: skip
    return frame(1, mission, status, views, events, time.time())


def app(mission: Mission, hz: float) -> FastAPI:
    """The page's files and the read-only routes it calls, over the synthetic formation."""
    web = FastAPI()
    started = time.monotonic()
    detail = {"id": 1, "name": mission.name, "created_s": 0.0,
              "vehicle_ids": [v.id for v in mission.vehicles],
              "mission": mission.model_dump(mode="json")}  # fmt: skip

    @web.get("/")
    async def page() -> FileResponse:
        return FileResponse(STATIC_DIR / "index.html")

    web.mount("/ui", StaticFiles(directory=STATIC_DIR), name="ui")

    @web.get("/links")
    async def links() -> list[dict[str, Any]]:
        return [{"id": 1, "url": "tcp:127.0.0.1:5760", "connected": True, "vehicles": [1]}]

    @web.get("/missions")
    async def missions() -> list[dict[str, Any]]:
        return [{k: detail[k] for k in ("id", "name", "created_s", "vehicle_ids")}]

    @web.get("/missions/1")
    async def mission_1() -> dict[str, Any]:
        return detail

    @web.get("/runs")
    async def runs() -> list[dict[str, Any]]:
        return []

    @web.websocket("/ws/view")
    async def view(ws: WebSocket) -> None:
        await ws.accept()
        t0 = time.monotonic()
        n = 0
        try:
            while True:
                t = time.monotonic() - started
                events = []
                if n % int(3 * hz) == 0:  # an event every 3 s
                    kind = KINDS[(n // int(3 * hz)) % len(KINDS)]
                    vid = 1 + n % len(mission.vehicles)
                    events.append({"run_id": 1, "mission_time_s": round(t, 3), "kind": kind,
                                   "vehicle_id": vid, "detail": None})  # fmt: skip
                await ws.send_json(synthetic_frame(mission, t, events))
                n += 1
                await asyncio.sleep(max(0.0, t0 + n / hz - time.monotonic()))
        except (WebSocketDisconnect, RuntimeError, OSError):
            pass

    return web


@contextlib.contextmanager
def serving(web: FastAPI, port: int) -> Iterator[None]:
    server = uvicorn.Server(uvicorn.Config(web, host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    try:
        wait_for(lambda: server.started, 20, "the benchmark's server")
        yield
    finally:
        server.should_exit = True
        thread.join(timeout=10)


def heap_after_gc_mb(driver: Any) -> float:
    driver.execute_cdp_cmd("HeapProfiler.enable", {})
    driver.execute_cdp_cmd("HeapProfiler.collectGarbage", {})
    metrics = driver.execute_cdp_cmd("Performance.getMetrics", {})["metrics"]
    used = next(m["value"] for m in metrics if m["name"] == "JSHeapUsedSize")
    return float(used) / 2**20


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--vehicles", type=int, default=50)
    parser.add_argument("--hz", type=float, default=10.0)
    parser.add_argument("--size", default="1280x720", help="window, e.g. 3840x2160")
    parser.add_argument("--sample-s", type=float, default=30.0)
    parser.add_argument("--warm-up-s", type=float, default=10.0)
    args = parser.parse_args()
    reason = chromium_missing()
    if reason:
        raise SystemExit(reason)
    width, height = (int(c) for c in args.size.split("x"))
    mission = synthetic_mission(args.vehicles)
    port = free_port()
    print(f"page benchmark: {args.vehicles} vehicles at {args.hz:g} Hz for {args.minutes:g} min, "
          f"window {width}x{height}, headless chromium", flush=True)  # fmt: skip
    extra = ("--enable-precise-memory-info",)
    with serving(app(mission, args.hz), port), browser(width, height, extra) as driver:
        driver.execute_cdp_cmd("Performance.enable", {})
        driver.get(f"http://127.0.0.1:{port}/")
        arrived = "return window.gcs && window.gcs.perf.messages > 20"
        wait_for(lambda: driver.execute_script(arrived), 30, "frames reaching the page")
        driver.execute_script("window.gcs.top.fit()")
        time.sleep(args.warm_up_s)
        heap_start = heap_after_gc_mb(driver)
        reset = (
            "const p = window.gcs.perf; const r = {...p}; "
            "p.frames = p.draws = p.drawMs = p.drawMaxMs = p.messages = 0; return r;"
        )
        driver.execute_script(reset)
        print(f"{'t (s)':>6} {'fps':>6} {'draws/s':>7} {'draw ms':>8} {'max ms':>7} {'msg/s':>6} "
              f"{'heap MB':>8} {'trail pts':>9}", flush=True)  # fmt: skip
        rows = []
        begin = last = time.monotonic()
        while time.monotonic() - begin < args.minutes * 60:
            time.sleep(min(args.sample_s, max(0.1, begin + args.minutes * 60 - time.monotonic())))
            p = driver.execute_script(reset)
            now = time.monotonic()
            heap = driver.execute_script("return performance.memory.usedJSHeapSize") / 2**20
            points = driver.execute_script(
                "return [...window.gcs.state.trails.values()].reduce((a, t) => a + t.length, 0)"
            )
            span = now - last
            last = now
            fps = p["frames"] / span
            row = (now - begin, fps, p["drawMs"] / max(p["draws"], 1), p["drawMaxMs"],
                   p["messages"] / span, heap, points, p["draws"] / span)  # fmt: skip
            rows.append(row)
            print(f"{row[0]:6.0f} {fps:6.1f} {row[7]:7.1f} {row[2]:8.2f} {row[3]:7.1f} "
                  f"{row[4]:6.1f} {heap:8.1f} {points:9d}", flush=True)  # fmt: skip
        heap_end = heap_after_gc_mb(driver)
        vehicles_drawn = driver.execute_script("return window.gcs.state.frame.vehicles.length")
        shot = screenshot(driver, f"bench-{args.vehicles}-{width}x{height}")
    fps_all = [r[1] for r in rows]
    print(
        f"\n{args.vehicles} vehicles ({vehicles_drawn} drawn) at {args.hz:g} Hz, "
        f"{args.minutes:g} min: fps min {min(fps_all):.1f}, median "
        f"{statistics.median(fps_all):.1f}; redraws {statistics.fmean(r[7] for r in rows):.1f}/s, "
        f"each {statistics.fmean(r[2] for r in rows):.2f} ms on average, worst "
        f"{max(r[3] for r in rows):.1f} ms; frames received "
        f"{statistics.fmean(r[4] for r in rows):.1f}/s; JS heap after GC "
        f"{heap_start:.1f} MB at the start, {heap_end:.1f} MB at the end "
        f"({heap_end - heap_start:+.1f} MB); used heap between "
        f"{min(r[5] for r in rows):.1f} and {max(r[5] for r in rows):.1f} MB; screenshot {shot}"
    )


if __name__ == "__main__":
    main()

"""Integration: MAVSDK (native binding, ``mavsdk.asyncio``) against ``python -m sitl``."""

from __future__ import annotations

import asyncio
import math
from collections.abc import Awaitable
from typing import Any, TypeVar

import pytest

from gcs_ppf.geodesy import enu_to_geodetic, geodetic_to_enu
from gcs_ppf.mission import load_mission_file
from tests.sitl.sitl_helpers import SLOW, run_sitl

mavsdk_asyncio = pytest.importorskip("mavsdk.asyncio")
from mavsdk.asyncio import ComponentType, Configuration, Mavsdk  # noqa: E402
from mavsdk.asyncio.plugins.action import ActionAsync  # noqa: E402
from mavsdk.asyncio.plugins.mission_raw import MissionRawAsync  # noqa: E402
from mavsdk.asyncio.plugins.param import ParamAsync  # noqa: E402
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync  # noqa: E402
from mavsdk.plugins.mission_raw import MissionItem  # noqa: E402

pytestmark = pytest.mark.realtime  # `python -m sitl` and mavsdk_server, at x10

T = TypeVar("T")
ORIGIN = load_mission_file(SLOW).origin


async def within(aw: Awaitable[T], seconds: float = 10.0) -> T:
    return await asyncio.wait_for(aw, seconds)


def item(seq: int, east: float, north: float, up: float, current: int = 0) -> Any:
    lat, lon, _ = enu_to_geodetic(east, north, 0.0, ORIGIN)
    return MissionItem(seq, 3, 16, current, 1, 0.0, 0.0, 0.0, 0.0,
                       round(lat * 1e7), round(lon * 1e7), up, 0)  # fmt: skip


async def scenario(port: int) -> None:
    cfg = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
    async with Mavsdk(cfg) as sdk:
        await within(sdk.add_any_connection(f"tcpout://127.0.0.1:{port}"))
        system = await within(sdk.first_autopilot(timeout_s=10.0), 15)
        assert system is not None
        assert await system.get_system_id() == 1
        tel, act, mission = TelemetryAsync(system), ActionAsync(system), MissionRawAsync(system)

        await asyncio.sleep(1.0)
        pos = await within(tel.position())
        e, n, u = geodetic_to_enu(
            pos.latitude_deg, pos.longitude_deg, pos.absolute_altitude_m, ORIGIN
        )
        assert e > 0
        assert abs(n) < 5
        assert u == pytest.approx(100, abs=2)
        att = await within(tel.attitude_euler())
        assert att.yaw_deg == pytest.approx(90, abs=1)
        assert (await within(tel.flight_mode())).name == "MANUAL"
        assert await within(tel.armed()) is True
        assert await within(tel.in_air()) is True

        params = ParamAsync(system)
        await within(params.set_param_int("WP_RADIUS", 120))  # an INT16 sent as a plain float
        assert await within(params.get_param_int("WP_RADIUS")) == 120
        await within(params.set_param_float("AIRSPEED_CRUISE", 25.0))
        assert await within(params.get_param_float("AIRSPEED_CRUISE")) == pytest.approx(25.0)

        plan = [item(0, 0, 0, 0, current=1), item(1, 600, 0, 120), item(2, 600, 500, 120)]
        await within(mission.upload_mission(plan))
        back = await within(mission.download_mission())
        assert [(i.seq, i.command, i.x, i.y, i.z) for i in back[1:]] == [
            (p.seq, p.command, p.x, p.y, p.z) for p in plan[1:]
        ]
        await within(act.arm())
        progress: list[int] = []

        async def watch() -> None:
            async for p in mission.subscribe_mission_progress():
                progress.append(p.current)
                if p.current >= 2 and len(progress) > 1:
                    return

        watcher = asyncio.create_task(watch())
        try:
            await within(mission.start_mission())
            await within(watcher, 30)
        finally:
            watcher.cancel()
        assert progress[-1] >= 2
        assert progress == sorted(progress)
        assert (await within(tel.flight_mode())).name == "MISSION"

        # goto: DO_REPOSITION (COMMAND_INT) switches to GUIDED and flies there.
        lat, lon, _ = enu_to_geodetic(-300.0, 300.0, 0.0, ORIGIN)
        await within(act.goto_location(lat, lon, ORIGIN.alt + 150.0, 0.0))
        for _ in range(100):
            pos = await within(tel.position())
            e, n, u = geodetic_to_enu(
                pos.latitude_deg, pos.longitude_deg, pos.absolute_altitude_m, ORIGIN
            )
            if math.hypot(e + 300, n - 300) < 120:
                break
            await asyncio.sleep(0.2)
        assert math.hypot(e + 300, n - 300) < 120
        # ArduPlane GUIDED has no MAVSDK FlightMode of its own; it is no longer the mission.
        assert (await within(tel.flight_mode())).name != "MISSION"


def test_mavsdk_connect_telemetry_mission_goto() -> None:
    with run_sitl(SLOW, speedup=10) as sitl:
        asyncio.run(asyncio.wait_for(scenario(sitl.port(0)), 80))

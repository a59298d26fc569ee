"""Starting a run: the request is answered at once, the fleet launches once the kernels
are loaded."""

from __future__ import annotations

import asyncio
import threading
import time
from pathlib import Path

import pytest

from gcs_ppf.mavlink.telemetry import VehicleTelemetry
from gcs_ppf.mission import Mission
from gcs_ppf.service import flight, runs
from gcs_ppf.service.fleet import Vehicle
from gcs_ppf.service.run import Run
from gcs_ppf.service.runs import FormationService
from gcs_ppf.service.settings import Settings
from gcs_ppf.service.store import Store
from tests.conftest import EXAMPLES


def test_start_answers_while_the_kernels_load_and_launch_waits_for_them(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """On a cold numba cache the kernels take minutes to compile; the start request awaited
    them and an HTTP client timed out (fly_check, session 4). The run must answer
    ``starting`` at once and launch nothing until they are loaded."""
    loaded = threading.Event()
    launched: list[int] = []

    def slow_load(planner_dt_s: float) -> None:
        assert loaded.wait(30)

    async def launch_fleet(station: object, run: Run) -> None:
        launched.append(run.mission_id)
        raise RuntimeError("launch stops here")  # the run fails; enough for this test

    monkeypatch.setattr(runs, "load_kernels", slow_load)
    monkeypatch.setattr(flight, "launch_fleet", launch_fleet)
    mission = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())

    async def scenario() -> None:
        settings = Settings(db=tmp_path / "gcs.db", tlog_dir=None)
        service = FormationService(settings, Store(settings.db))
        async with service.running():
            for v in mission.vehicles:  # as if their links had reported them
                service.fleet.by_id[v.id] = Vehicle(
                    v.id, 0, VehicleTelemetry(v.id, 1), last_heard_s=time.monotonic() + 60
                )
            mid = service.create_mission(mission).id
            status = await asyncio.wait_for(service.start(mid), 1.0)
            assert status["state"] == "starting"
            await asyncio.sleep(0.3)
            assert launched == []  # still loading: nothing launched
            loaded.set()
            for _ in range(100):
                if launched:
                    break
                await asyncio.sleep(0.05)
            assert launched == [mid]
            service.fleet.by_id.clear()

    asyncio.run(scenario())

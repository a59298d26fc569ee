"""What a run uses of the ground-station service: its fleet, settings and store, its task
group and live stream, with the run's events and its vehicles' reported positions.

``FormationService`` (``service.runs``) builds one and hands it to the flying of a run
(``service.flight``), its end (``service.ending``) and the safety watch (``service.watch``),
so that they see no more of the service than this.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable, Coroutine, Iterator
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np

from gcs_ppf.geodesy import geodetic_to_enu_many
from gcs_ppf.mission import Mission
from gcs_ppf.planning.scene import FloatArray
from gcs_ppf.service.confirmation import EventSink
from gcs_ppf.service.fleet import Fleet, Vehicle
from gcs_ppf.service.run import Run
from gcs_ppf.service.settings import Settings
from gcs_ppf.service.store import Store

log = logging.getLogger("gcs_ppf.service.runs")  # the runs' log, under its name of old


@dataclass(frozen=True)
class Station:
    """The service's parts a run is flown with (shared, not copied)."""

    settings: Settings
    store: Store
    fleet: Fleet
    runs: dict[int, Run]
    """Mission id → its current or last run (``FormationService``'s own)."""
    spawn: Callable[[Coroutine[Any, Any, Any]], asyncio.Task[Any]]
    """A task in the service's task group."""
    publish: Callable[[], None]
    """A snapshot to every live-stream subscriber."""
    kernels_loaded: Callable[[], Awaitable[None]]
    """Returns once the planner's and the assurance's compiled kernels are loaded."""

    def event(self, run: Run, kind: str, vehicle_id: int | None = None, **detail: Any) -> None:
        """One of the run's events, stored and logged."""
        with run.phases.phase("events"):
            with run.phases.phase("storage"):
                self.store.add_event(
                    run.record.id,
                    kind,
                    mission_time_s=round(run.mission_time_s, 3),
                    vehicle_id=vehicle_id,
                    detail=detail or None,
                )
            log.info(
                "mission %d t=%.1f s: %s%s %s",
                run.mission_id,
                run.mission_time_s,
                kind,
                f" (vehicle {vehicle_id})" if vehicle_id else "",
                detail or "",
            )

    def events_of(self, run: Run) -> EventSink:
        """``event`` for this run, as the launch and commanding take it."""
        return partial(self.event, run)

    def rates_hz(self, mission: Mission) -> tuple[float, float]:
        """(ticks, positions) a vehicle second for ``mission``'s vehicles: the settings', or
        the slowest rate a vehicle's positions were asked for (less where a radio carries
        it: ``Fleet.stream_rate_hz``)."""
        wanted = self.settings.stream_rate_hz
        asked = (self.fleet.by_id.get(v.id) for v in mission.vehicles)
        positions = min(
            (v.stream_rate_hz for v in asked if v is not None and v.stream_rate_hz is not None),
            default=wanted,
        )
        return min(self.settings.tick_hz, positions), positions

    def located(self, run: Run) -> Iterator[tuple[Vehicle, tuple[float, float, float]]]:
        """The run's vehicles that have reported a position, with it in the ICS (all
        converted in one call)."""
        return self.located_of(run.mission)

    def located_of(self, mission: Mission) -> Iterator[tuple[Vehicle, tuple[float, float, float]]]:
        """``located`` for the vehicles of ``mission``, in its ICS."""
        found: list[tuple[Vehicle, tuple[float, float, float]]] = []
        for v in mission.vehicles:
            vehicle = self.fleet.by_id.get(v.id)
            if vehicle is None:
                continue
            t = vehicle.telemetry
            if t.lat_deg is not None and t.lon_deg is not None and t.alt_amsl_m is not None:
                found.append((vehicle, (t.lat_deg, t.lon_deg, t.alt_amsl_m)))
        if not found:
            return
        enu = geodetic_to_enu_many(np.array([g for _, g in found]), mission.origin)
        for (vehicle, _), (e, n, u) in zip(found, enu.tolist(), strict=True):
            yield vehicle, (e, n, u)

    def path_since(
        self, mission: Mission, vehicle_id: int, since_ms: int | None
    ) -> tuple[FloatArray, int | None]:
        """The vehicle's reported positions (ICS, [K,3], oldest first) newer than vehicle
        time ``since_ms`` (None: its latest only), and the newest one's time.  A tick late
        under load sees several at once; the chord from the last tick's to the latest cuts
        inside a turn (at ×10, a second of flight between ticks)."""
        vehicle = self.fleet.by_id.get(vehicle_id)
        fixes = () if vehicle is None else vehicle.telemetry.recent_fixes
        newer = [f for f in fixes if since_ms is None or f.boot_ms > since_ms]
        if since_ms is None or not newer:  # first look, or a clock gone back: the latest
            newer = list(fixes[-1:])
        if not newer:
            return np.zeros((0, 3)), since_ms
        geodetic = np.array([(f.lat_deg, f.lon_deg, f.alt_amsl_m) for f in newer])
        return geodetic_to_enu_many(geodetic, mission.origin), newer[-1].boot_ms

    def fleet_time_s(self) -> float | None:
        """The latest vehicle time any vehicle still heard has reported (seconds)."""
        times = [
            v.telemetry.time_boot_ms
            for v in self.fleet.by_id.values()
            if not v.lost and v.telemetry.time_boot_ms is not None
        ]
        return max(times) / 1000.0 if times else None

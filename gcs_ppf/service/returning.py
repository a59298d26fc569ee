"""A mission's end in RTL (``at_end: "rtl"``): each vehicle, on its holding circle at a level
over every keep-out, sent home in ArduPlane's RTL at that level where the way is clear
(``guidance.failsafe.ways_home``), its RTL_ALTITUDE set to the level first and read back,
the mode confirmed; where the way is not clear, or its home is not known, it holds."""

from __future__ import annotations

import asyncio
from functools import partial

from gcs_ppf.geodesy import geodetic_to_enu
from gcs_ppf.guidance import failsafe, holding
from gcs_ppf.mavlink import commands
from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.service import confirmation, launch
from gcs_ppf.service.run import Run
from gcs_ppf.service.station import Station

HOME_ASKS = 5
"""Times a vehicle is asked where its home is (HOME_POSITION), a vehicle second apart."""


def home_heights(station: Station, run: Run) -> dict[int, float]:
    """Each located vehicle's home's ICS z: where it is less its height above home."""
    homes = {}
    for vehicle, pos in station.located(run):
        h = vehicle.telemetry.relative_alt_m
        if h is not None:
            homes[vehicle.system_id] = pos[2] - h
    return homes


def home_of(station: Station, run: Run, vehicle_id: int) -> tuple[float, float, float] | None:
    """The vehicle's home (HOME_POSITION) in the mission's ICS; None until it has said."""
    t = station.fleet.telemetry(vehicle_id)
    if t is None or t.home_lat_deg is None or t.home_lon_deg is None or t.home_alt_amsl_m is None:
        return None
    return geodetic_to_enu(t.home_lat_deg, t.home_lon_deg, t.home_alt_amsl_m, run.mission.origin)


async def return_home(station: Station, run: Run, circles: dict[int, holding.Hold]) -> None:
    """Every vehicle of ``circles`` (holding there) sent home in RTL where its way is clear:
    a ``returning_home`` event with its RTL_ALTITUDE as read back and the way's clearance;
    ``return_not_clear`` (it holds) where the way is not clear, its home is not known or
    the altitude did not read back."""
    ids = sorted(circles)
    rate = station.fleet.clock_rate()
    for _ in range(HOME_ASKS):  # asked again each vehicle second (a lossy link)
        unknown = [vid for vid in ids if home_of(station, run, vid) is None]
        if not unknown:
            break
        for vid in unknown:
            await station.fleet.send(
                vid, commands.request_message(vid, commands.MAVLINK_MSG_ID_HOME_POSITION)
            )
        await confirmation.wait_until(
            lambda: all(home_of(station, run, vid) is not None for vid in ids), 1.0 / rate, 0.05
        )
    homes = {vid: h for vid in ids if (h := home_of(station, run, vid)) is not None}
    ways = failsafe.ways_home(
        run.mission,
        {vid: ((c.x_m, c.y_m, c.z_m), c.radius_m) for vid, c in circles.items()},
        homes,
        run.mission_time_s,
    )

    async def one(vid: int) -> None:
        way = ways.get(vid)
        if way is None or not way.clear:
            reason = "home unknown" if way is None else "way not clear"
            clearance = None if way is None else round(way.clearance_m, 1)
            station.event(run, "return_not_clear", vid, reason=reason, clearance_m=clearance)
            return
        events = station.events_of(run)
        read = await launch.set_param(
            station.fleet, vid, "RTL_ALTITUDE", way.rtl_altitude_m, events
        )
        if read is None or abs(read - way.rtl_altitude_m) > 1.0:
            station.event(run, "return_not_clear", vid, reason="RTL_ALTITUDE not set", read=read)
            return
        rtl = confirmation.Order(
            vid,
            partial(commands.set_mode, vid, PlaneMode.RTL),
            commands.MAV_CMD_DO_SET_MODE,
            "return home: mode RTL",
            lambda t: t.custom_mode == PlaneMode.RTL,
        )
        failed = await confirmation.confirm_all(station.fleet, [rtl], events)
        if not failed:
            station.event(
                run,
                "returning_home",
                vid,
                rtl_altitude_m=read,
                clearance_m=round(way.clearance_m, 1),
            )

    await asyncio.gather(*(one(vid) for vid in ids))

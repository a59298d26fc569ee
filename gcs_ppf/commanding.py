"""From one tick's guidance to each vehicle's MAVLink commands (course or guided point,
altitude, speed), every one through run-time assurance (``gcs_ppf.assurance``) first.

The shell between the pure planner and the fleet: what the commands carry is
``gcs_ppf.slew``; a command the assurance replaces is sent as its escape instead, with an
``assurance_override`` event (vehicle, keep-out, how deep the planned one would have gone).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from gcs_ppf import assurance, slew
from gcs_ppf.airframe import Airframe
from gcs_ppf.geodesy import enu_to_geodetic
from gcs_ppf.mavlink import commands
from gcs_ppf.mavlink.telemetry import VehicleTelemetry
from gcs_ppf.mission import Mission
from gcs_ppf.online import Guidance, VehicleState

#: Without TECS limits, climb and sink are taken as this fraction of the speed (~24°).
DEFAULT_PATH_SLOPE = 0.4
#: A guided point for an escape is put this far along its course (point guidance).
ESCAPE_POINT_M = 1500.0


class Sender(Protocol):
    """What commanding needs of the fleet."""

    def telemetry(self, system_id: int) -> VehicleTelemetry | None: ...

    async def send(self, system_id: int, msg: Any) -> None: ...


@dataclass(frozen=True)
class Orders:
    """How this run commands its vehicles (fixed for the run)."""

    mission: Mission
    guidance_mode: str
    """``course`` (GUIDED_CHANGE_HEADING + ALTITUDE) or ``point`` (DO_REPOSITION)."""
    lookahead_s: float


def motion(state: VehicleState, airframe: Airframe, mission: Mission) -> assurance.Motion:
    """A vehicle's response model for the assurance, from its airframe's parameters (the
    mission's limits where it reports none)."""
    v = state.speed_m_s
    turn = min(airframe.max_turn_rate(v) or math.inf, mission.limits.max_yaw_rate)
    climb = airframe.climb_max_m_s or DEFAULT_PATH_SLOPE * v
    sink = airframe.sink_max_m_s or DEFAULT_PATH_SLOPE * v
    tau = airframe.heading_time_constant_s(v) or 1.0
    return assurance.Motion(state.pos_m, state.yaw_rad, v, turn, climb, sink, tau)


def planned_commands(
    g: Guidance, states: dict[int, VehicleState], airframes: list[Airframe], orders: Orders,
    turn_accel_m_s2: float,
) -> list[slew.SlewCommand]:  # fmt: skip
    """Each vehicle's course and altitude as the plan asks (in ``g``'s order); in point
    guidance the course is the bearing to the guided point."""
    out = []
    for i, vid in enumerate(g.ids):
        if orders.guidance_mode == "point":
            x, y, z = (float(c) for c in g.guided_point_m[i])
            px, py, _ = states[vid].pos_m
            out.append(slew.SlewCommand(math.atan2(y - py, x - px), 0.0, z, 0.0))
            continue
        out.append(slew.slew_command(g, i, airframes[i], states[vid].pos_m[2], turn_accel_m_s2,
                                     orders.lookahead_s))  # fmt: skip
    return out


async def command_fleet(
    fleet: Sender,
    g: Guidance,
    active: set[int],
    states: dict[int, VehicleState],
    airframes: list[Airframe],
    orders: Orders,
    keep: assurance.KeepOut,
    hold_s: float,
    commanded_speed: dict[int, float],
    event: Callable[..., None],
) -> list[assurance.Verdict]:
    """Send every active vehicle its commands for this tick, each assured first; returns
    the verdicts (in the order of the active vehicles in ``g``)."""
    mission = orders.mission
    turn_accel = mission.limits.v_max * mission.limits.max_yaw_rate  # the plan limits turns
    planned = planned_commands(g, states, airframes, orders, turn_accel)
    idx = [i for i, vid in enumerate(g.ids) if vid in active]
    motions = [motion(states[g.ids[i]], airframes[i], mission) for i in idx]
    wanted = [assurance.Command(planned[i].course_rad, planned[i].z_m) for i in idx]
    verdicts = assurance.assure(motions, wanted, hold_s, keep)
    for i, m, v in zip(idx, motions, verdicts, strict=True):
        vid = g.ids[i]
        if v.replaced:
            event("assurance_override", vid, keep_out=v.reason,
                  planned_margin_m=round(v.margin_m, 1), sent_margin_m=round(v.chosen_margin_m, 1),
                  course_deg=round(90.0 - math.degrees(v.command.course_rad), 1))  # fmt: skip
        await _send_course(fleet, vid, planned[i], v, m, orders, g.guided_point_m[i])
        await _send_speed(fleet, vid, g, i, airframes[i], commanded_speed)
    return verdicts


async def _send_course(
    fleet: Sender, vid: int, cmd: slew.SlewCommand, v: assurance.Verdict, m: assurance.Motion,
    orders: Orders, guided_point: np.ndarray,
) -> None:  # fmt: skip
    origin = orders.mission.origin
    if orders.guidance_mode == "point":
        x, y, z = (float(c) for c in guided_point)
        if v.replaced:
            x = m.pos_m[0] + ESCAPE_POINT_M * math.cos(v.command.course_rad)
            y = m.pos_m[1] + ESCAPE_POINT_M * math.sin(v.command.course_rad)
            z = v.command.z_m
        lat, lon, alt = enu_to_geodetic(x, y, z, origin)
        await fleet.send(vid, commands.reposition(vid, lat, lon, alt))
        return
    accel = cmd.lateral_accel_m_s2
    if v.replaced:  # an escape turns as hard as the airframe can
        accel = max(accel, m.speed_m_s * m.turn_rate_rad_s)
    _, _, alt = enu_to_geodetic(m.pos_m[0], m.pos_m[1], v.command.z_m, origin)
    course_deg = 90.0 - math.degrees(v.command.course_rad)  # ENU yaw → compass
    await fleet.send(vid, commands.guided_change_heading(vid, course_deg, accel))
    rate = 0.0 if v.replaced else cmd.rate_m_s
    await fleet.send(vid, commands.guided_change_altitude(vid, slew.sendable_altitude(alt), rate))


async def _send_speed(
    fleet: Sender, vid: int, g: Guidance, i: int, airframe: Airframe,
    commanded_speed: dict[int, float],
) -> None:  # fmt: skip
    """DO_CHANGE_SPEED when the airspeed to fly changes by half a metre per second."""
    t = fleet.telemetry(vid)
    if t is None:
        return
    ahead = g.speed_m_s if g.speed_ahead_m_s is None else g.speed_ahead_m_s
    speed = slew.airspeed_command(float(ahead[i]), t.airspeed_m_s, t.groundspeed_m_s, airframe)
    if abs(commanded_speed.get(vid, -1.0) - speed) >= 0.5:
        commanded_speed[vid] = speed
        await fleet.send(vid, commands.change_speed(vid, speed))

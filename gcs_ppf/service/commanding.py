"""From one tick's guidance to each vehicle's MAVLink commands (course or guided point,
altitude, speed), every one through run-time assurance (``gcs_ppf.guidance.assurance``) first.

The shell between the pure planner and the fleet: what the commands carry is
``gcs_ppf.guidance.slew``; a command the assurance replaces is sent as its escape instead, with an
``assurance_override`` event (vehicle, keep-out, how deep the planned one would have gone).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from contextlib import nullcontext
from dataclasses import dataclass, replace
from functools import partial
from typing import Any, Protocol

import numpy as np

from gcs_ppf.geodesy import enu_to_geodetic, enu_to_geodetic_many
from gcs_ppf.guidance import assurance, holding, prediction, slew, speed_reference, vehicle_motion
from gcs_ppf.guidance.airframe import Airframe
from gcs_ppf.guidance.online import Guidance, VehicleState
from gcs_ppf.mavlink import commands
from gcs_ppf.mavlink.ardupilot import (
    CLIMB_LAG_PER_TECS_TCONST,
    HEIGHT_GAIN_TIMES_TECS_TCONST,
    ROLL_LAG_PER_TCONST,
    ROLL_RATE_MAX_RAD_S,
    PlaneMode,
)
from gcs_ppf.mavlink.telemetry import VehicleTelemetry
from gcs_ppf.mission import Mission
from gcs_ppf.planning.scene import Obstacles, obstacles_from_mission
from gcs_ppf.planning.zones import Zones, zones_from_mission
from gcs_ppf.service import confirmation
from gcs_ppf.service.tick_phases import TickPhases

LOITER_AHEAD_M = 800.0
"""After the mission each vehicle circles a point this far ahead (or further, to clear)…"""
LOITER_STACK_M = 100.0
"""… vehicle k of the mission this much above the target (after completion)."""
HOLD_TURN_RADII = 1.5
"""A holding circle is this many of the vehicle's tightest turns wide …"""
HOLD_MIN_RADIUS_M = 80.0
"""… and at least ArduPlane's WP_LOITER_RAD."""
STACK_LEVELS_MAX = 10
"""A fleet of more vehicles holds on circles spread apart (``holding.spread_holds``), each at
its own height, not stacked: climbing to a stack of 100 levels (15 km at Table 3's 150 m)
the vehicles climbed side by side for minutes on crossing circles, and two pairs came to
47.9 and 49.6 m after the end in 2 of 5 runs of ``examples/formation_100.json``; the
campaigns flew stacks of up to 9."""
HOLD_RETRY = confirmation.Retry(attempts=10, copies=3)
"""A hold is sent, three copies at a time, until it is ACCEPTED (×5 with 20 % loss each
way and 300 ms of latency, a leader's hold got through at its fourth send: it flew its last
run command for 12 s of its time meanwhile, and came to 27 m of a wingman turning onto
its own hold) …"""
HOLD_ACK_VEHICLE_S = 2.0
"""… again when unanswered for this long (vehicle seconds; within 0.2–1.5 of ours)."""

#: Without TECS limits, climb and sink are taken as this fraction of the speed (~24°).
DEFAULT_PATH_SLOPE = 0.4
#: A guided point for an escape is put this far along its course (point guidance).
ESCAPE_POINT_M = 1500.0
SIDE_MEMORY_S = 3.0
"""The way a vehicle's last escape turned binds its next one for this long after it went
back to its plan (mission seconds; ``assurance.SIDE_SWITCH_S``): a wingman flew its plan
and escapes to either side by turns, each for a few ticks, and flew straight on."""
STATION_KEEPING_REACH = 3.0
"""Target accuracies: a wingman this near its slot keeps station on it and is led for its
leader's turn (``planned_commands``); farther off it is joining, led for its own."""


SPEED_ACK_VEHICLE_S = 1.0
"""An airspeed (DO_CHANGE_SPEED) not acknowledged within this many of the vehicle's seconds
is sent again (``_send_speed``): a round trip on a telemetry radio with 300 ms each way,
and the autopilot's answer, take less."""


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


def motion(
    state: VehicleState, airframe: Airframe, mission: Mission, speed_m_s: float = 0.0
) -> vehicle_motion.Motion:
    """A vehicle's response model for the assurance, from its airframe's parameters (the
    mission's limits where it reports none), at its speed or ``speed_m_s`` if faster (the
    speed it is told to reach: a faster vehicle turns wider).  Its climb and sink are what
    its pitch limits and TECS's rates give at that speed (TECS_CLMB_MAX alone, 102.6 m/s
    for the paper's airframe, made a leader at 100 m/s, climbing 36 m/s at its 20° pitch
    limit, count on climbing over a sphere it then entered); its vertical speed answers
    with TECS's lag and gain from the one it reports."""
    v = max(state.speed_m_s, speed_m_s)
    turn = min(airframe.max_turn_rate(v) or math.inf, mission.limits.max_yaw_rate)
    climb_angle, dive_angle = airframe.max_climb_angle(v), airframe.max_dive_angle(v)
    climb = DEFAULT_PATH_SLOPE * v if climb_angle is None else v * math.sin(climb_angle)
    sink = DEFAULT_PATH_SLOPE * v if dive_angle is None else v * math.sin(dive_angle)
    tau = airframe.heading_time_constant_s(v) or 1.0
    tconst = airframe.roll_time_constant_s  # None: not ArduPlane, the bank at once
    roll_lag = 0.0 if tconst is None else ROLL_LAG_PER_TCONST * tconst
    roll_rate = math.inf if tconst is None else ROLL_RATE_MAX_RAD_S
    vz = state.climb_rate_m_s
    if vz is None:
        vz = state.speed_m_s * math.sin(state.pitch_rad)
    tecs = airframe.tecs_time_constant_s  # None: not ArduPlane, the vertical speed at once
    climb_lag = 0.0 if tecs is None else CLIMB_LAG_PER_TECS_TCONST * tecs
    gain = math.inf if tecs is None else HEIGHT_GAIN_TIMES_TECS_TCONST / tecs
    return vehicle_motion.Motion(
        state.pos_m,
        state.yaw_rad,
        v,
        turn,
        climb,
        sink,
        tau,
        state.yaw_rate_rad_s,
        roll_lag,
        roll_rate,
        vz,
        climb_lag,
        gain,
    )


def planned_commands(
    g: Guidance,
    states: dict[int, VehicleState],
    airframes: list[Airframe],
    orders: Orders,
    turn_accel_m_s2: float,
    cut: bool,
    trims: dict[int, slew.ClimbTrim] | None = None,
) -> list[slew.SlewCommand]:
    """Each vehicle's course and altitude as the plan asks (in ``g``'s order); in point
    guidance the course is the bearing to the guided point.  In missions at ArduPlane's
    scale (``cut``: ``speed_reference.follows_speed_plan``) a wingman keeping station (within
    ``STATION_KEEPING_REACH`` target accuracies of its slot) and not avoiding is led for its
    leader's planned turn, the formation's (each slot's course turns with it), not for its
    own: its own plan turns back from the correction it makes at once, faster than
    ArduPlane's P-controller turns, and leading that turn back sent it the other way (the
    loiter route: wingmen 8–16 m inside their leader's turns for 30–40 s).  The leader, a
    wingman avoiding and one still joining are led for their own turns, the lead ``cut``
    against the correction (``slew.opposing_lead_rad``): a wingman hundreds of metres from
    its slot turns to join it, and led for its leader's turn instead it lagged its own (the
    line abreast of five: its outer wingmen 250–450 m off their slots, formed at 178 s or
    never where they had formed at 40 s).  At the paper's 100–300 m/s the P-controller's
    and the pursuit's time constants are far apart and the lead is flown as before."""
    out = []
    leader_id = orders.mission.leader.id
    leader = g.ids.index(leader_id) if leader_id in g.ids else None
    station_m = STATION_KEEPING_REACH * orders.mission.limits.target_accuracy
    for i, vid in enumerate(g.ids):
        if orders.guidance_mode == "point":  # the point's altitude led as the course mode's
            x, y, z = (float(c) for c in g.guided_point_m[i])
            px, py, pz = states[vid].pos_m
            tecs = airframes[i].tecs_time_constant_s
            if tecs is not None and math.isfinite(float(g.climb_rate_m_s[i])):
                z = slew.tecs_altitude_demand(g, i, pz, tecs) or z
            out.append(slew.SlewCommand(math.atan2(y - py, x - px), 0.0, z, 0.0))
            continue
        s = states[vid]
        trim = 0.0 if trims is None or vid not in trims else trims[vid].trim_m_s
        course = s.yaw_rad if cut else None
        formation_turn = None
        off_m = g.local_target_distance_m[i]  # None for the leader
        keeping_station = off_m is not None and off_m <= station_m
        avoiding = bool(g.avoiding and g.avoiding[i])
        if cut and i != leader and leader is not None and keeping_station and not avoiding:
            formation_turn = float(g.turn_rate_rad_s[leader])
        out.append(
            slew.slew_command(
                g,
                i,
                airframes[i],
                s.pos_m[2],
                turn_accel_m_s2,
                orders.lookahead_s,
                course,
                trim,
                formation_turn,
            )
        )
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
    escaping: dict[int, assurance.Escape],
    now_s: float,
    trims: dict[int, slew.ClimbTrim] | None = None,
    *,
    phases: TickPhases | None = None,
    speed_sent_s: dict[int, float] | None = None,
    speed_ack_wait_s: float = SPEED_ACK_VEHICLE_S,
) -> dict[int, assurance.Verdict]:
    """Send every active vehicle its commands for this tick, each assured first; returns
    each one's verdict (the command it was sent).  ``escaping`` holds each vehicle's escape
    in force, or the way its last one turned for ``SIDE_MEMORY_S`` after it ended (mission
    time ``now_s``), updated here; ``trims`` each vehicle's climb trim
    (``slew.climb_trim``), updated here too.  ``phases``: the assurance's time is timed
    apart (``service.tick_phases``).  ``speed_sent_s``: when (our monotonic seconds) each
    vehicle was last sent its airspeed, updated here; with it, an airspeed not acknowledged
    within ``speed_ack_wait_s`` (ours) is sent again (``_send_speed``)."""
    mission = orders.mission
    turn_accel = mission.limits.v_max * mission.limits.max_yaw_rate  # the plan limits turns
    follows = speed_reference.follows_speed_plan(mission.limits.accel, mission.limits.decel)
    if trims is not None:
        for i, vid in enumerate(g.ids):
            if vid in active and vid in trims:
                trims[vid] = slew.climb_trim(
                    trims[vid], states[vid].climb_rate_m_s, now_s, airframes[i]
                )
    planned = planned_commands(g, states, airframes, orders, turn_accel, follows, trims)
    idx = [i for i, vid in enumerate(g.ids) if vid in active]
    ahead = g.speed_m_s if g.speed_ahead_m_s is None else g.speed_ahead_m_s
    motions = [motion(states[g.ids[i]], airframes[i], mission, float(ahead[i])) for i in idx]
    wanted = [vehicle_motion.Command(planned[i].course_rad, planned[i].z_m) for i in idx]
    previous = [escaping.get(g.ids[i]) for i in idx]
    with nullcontext() if phases is None else phases.phase("assurance"):
        verdicts = assurance.assure(motions, wanted, hold_s, keep, previous)
    points = [
        _course_point(planned[i], v, m, orders, g.guided_point_m[i])
        for i, m, v in zip(idx, motions, verdicts, strict=True)
    ]
    lats, lons, alts = enu_to_geodetic_many(np.array(points).reshape(-1, 3), mission.origin)
    for k, (i, m, v) in enumerate(zip(idx, motions, verdicts, strict=True)):
        vid = g.ids[i]
        remember(escaping, vid, v, now_s)
        if v.replaced:
            course_deg = round(90.0 - math.degrees(v.command.course_rad), 1)
            override_event(event, vid, v, [g.ids[j] for j in idx], course_deg=course_deg)
        where = (float(lats[k]), float(lons[k]), float(alts[k]))
        if trims is not None:  # what the vertical channel asked, to learn from next tick
            held = trims.get(vid, slew.ClimbTrim())
            asked = None if v.replaced else planned[i].climb_m_s
            trims[vid] = slew.ClimbTrim(held.trim_m_s, asked, now_s)
        await _send_course(fleet, vid, planned[i], v, m, orders, where)
        slowest = mission.limits.v_min if v.replaced else None
        await _send_speed(
            fleet,
            vid,
            g,
            i,
            airframes[i],
            commanded_speed,
            follows,
            slowest,
            speed_sent_s,
            speed_ack_wait_s,
        )
    return {g.ids[i]: v for i, v in zip(idx, verdicts, strict=True)}


def override_event(
    event: Callable[..., None], vid: int, v: assurance.Verdict, ids: list[int], **detail: Any
) -> None:
    """The ``assurance_override`` event of a replaced command: the keep-out, the margins of
    the planned and the sent command, the way it turns, and the teammate it gives way to
    (``assurance.Verdict.gives_way_to``, ``ids`` the vehicles assured, in order)."""
    if v.gives_way_to is not None:
        detail["gives_way_to"] = ids[v.gives_way_to]
    event(
        "assurance_override",
        vid,
        keep_out=v.reason,
        planned_margin_m=round(v.margin_m, 1),
        sent_margin_m=round(v.chosen_margin_m, 1),
        turn={1: "left", -1: "right"}.get(v.side, "straight"),
        **detail,
    )


def remember(
    escaping: dict[int, assurance.Escape], vid: int, v: assurance.Verdict, now_s: float
) -> None:
    """``escaping`` after ``vid``'s verdict: its escape in force, or the way the last one
    turned, until ``SIDE_MEMORY_S`` after it ended."""
    last = escaping.get(vid)
    if v.replaced:
        escaping[vid] = assurance.Escape(v.command, v.side)
    elif last is not None and last.ended_s is None:
        escaping[vid] = assurance.Escape(None, last.side, now_s)
    elif last is not None and last.ended_s is not None and now_s - last.ended_s > SIDE_MEMORY_S:
        del escaping[vid]


def along(m: vehicle_motion.Motion, c: vehicle_motion.Command) -> tuple[float, float, float]:
    """A guided point for course ``c`` (point guidance): ``ESCAPE_POINT_M`` along it from
    the vehicle, at its altitude."""
    return (
        m.pos_m[0] + ESCAPE_POINT_M * math.cos(c.course_rad),
        m.pos_m[1] + ESCAPE_POINT_M * math.sin(c.course_rad),
        c.z_m,
    )


def _course_point(
    cmd: slew.SlewCommand,
    v: assurance.Verdict,
    m: vehicle_motion.Motion,
    orders: Orders,
    guided_point: np.ndarray,
) -> tuple[float, float, float]:
    """Where a vehicle's command points (ICS): the guided point (an escape's point
    ``ESCAPE_POINT_M`` along its course), or in course guidance, above the vehicle at the
    altitude it is sent."""
    if orders.guidance_mode == "point":
        if v.replaced:
            return along(m, v.command)
        x, y, _ = (float(c) for c in guided_point)
        return x, y, cmd.z_m  # the altitude assured (``planned_commands``)
    return m.pos_m[0], m.pos_m[1], v.command.z_m


async def _send_course(
    fleet: Sender,
    vid: int,
    cmd: slew.SlewCommand,
    v: assurance.Verdict,
    m: vehicle_motion.Motion,
    orders: Orders,
    where: tuple[float, float, float],
) -> None:
    """The vehicle's course and altitude commands (``where``: ``_course_point`` on WGS-84)."""
    lat, lon, alt = where
    if orders.guidance_mode == "point":
        await fleet.send(vid, commands.reposition(vid, lat, lon, alt))
        return
    accel = cmd.lateral_accel_m_s2
    if v.replaced:  # an escape turns as hard as the airframe can
        accel = max(accel, m.speed_m_s * m.turn_rate_rad_s)
    course_deg = 90.0 - math.degrees(v.command.course_rad)  # ENU yaw → compass
    await fleet.send(vid, commands.guided_change_heading(vid, course_deg, accel))
    rate = 0.0 if v.replaced else cmd.rate_m_s
    await fleet.send(vid, commands.guided_change_altitude(vid, slew.sendable_altitude(alt), rate))


async def _send_speed(
    fleet: Sender,
    vid: int,
    g: Guidance,
    i: int,
    airframe: Airframe,
    commanded_speed: dict[int, float],
    follows: bool = True,
    slowest_m_s: float | None = None,
    sent_s: dict[int, float] | None = None,
    ack_wait_s: float = SPEED_ACK_VEHICLE_S,
) -> None:
    """DO_CHANGE_SPEED when the airspeed to fly (``speed_reference.speed_to_command``, over
    the averaged airspeed / ground speed ratio) changes by ``SPEED_DEADBAND_M_S``; the
    legacy lead and deadband where the vehicles do not follow the plan's speed
    (``speed_reference.follows_speed_plan``).  During an escape, ``slowest_m_s`` instead
    (the tightest turn; the assurance predicts it at the speed the vehicle has, or is told,
    whichever is faster: Table 3, ×5 on a lossy link, a leader accelerating from 102 to
    160 m/s through an escape turned wider than predicted, each tick's margin 5–10 m less
    than the last, and went 17.6 m into a sphere).

    With ``sent_s`` (when each vehicle was last sent one, our monotonic seconds), an airspeed
    not acknowledged within ``ack_wait_s`` is sent again: sent only when it changes, one
    lost on the link was never sent again while the plan's speed stayed within the deadband
    of it (the loiter route at 20 % loss: the leader sent 20.44 m/s flew on at 20.09 for
    295 s)."""
    t = fleet.telemetry(vid)
    if t is None:
        return
    lead, deadband = speed_reference.SPEED_COMMAND_LEAD_S, speed_reference.SPEED_DEADBAND_M_S
    if i > 0:
        lead = speed_reference.WINGMAN_SPEED_COMMAND_LEAD_S
    if not follows:
        lead, deadband = speed_reference.LEGACY_COMMAND_LEAD_S, speed_reference.LEGACY_DEADBAND_M_S
    planned = speed_reference.speed_to_command(g, i, lead) if slowest_m_s is None else slowest_m_s
    path_speed = None  # along the flight path, as the airspeed (VFR_HUD's is horizontal)
    if t.groundspeed_m_s is not None:
        path_speed = math.hypot(t.groundspeed_m_s, t.climb_m_s or 0.0)
    speed = slew.airspeed_command(planned, t.airspeed_m_s, path_speed, airframe, t.speed_ratio_mean)
    if abs(commanded_speed.get(vid, -1.0) - speed) >= deadband:
        commanded_speed[vid] = speed
    elif sent_s is None or not _speed_unacknowledged(t, sent_s.get(vid), ack_wait_s):
        return
    if sent_s is not None:
        sent_s[vid] = time.monotonic()
    await fleet.send(vid, commands.change_speed(vid, commanded_speed[vid]))


def _speed_unacknowledged(t: VehicleTelemetry, sent_s: float | None, wait_s: float) -> bool:
    """Whether the airspeed last sent at ``sent_s`` (our monotonic seconds) has had no
    COMMAND_ACK for ``wait_s`` since (any result: one refused is not sent again)."""
    if sent_s is None or time.monotonic() - sent_s < wait_s:
        return False
    ack = t.ack(commands.MAV_CMD_DO_CHANGE_SPEED)
    return ack is None or ack.received_s < sent_s


def hold_retry(clock_rate: float) -> confirmation.Retry:
    """``HOLD_RETRY`` with its ACK wait in the vehicles' time (``clock_rate``: theirs per
    ours)."""
    wait = min(1.5, max(0.2, HOLD_ACK_VEHICLE_S / clock_rate))
    return replace(HOLD_RETRY, ack_timeout_s=wait)


def _leader_yaw(states: dict[int, VehicleState], mission: Mission) -> float:
    """The heading the holds are laid out towards: the leader's (another's if it has no
    state; 0 without any)."""
    reference = states.get(mission.leader.id) or next(iter(states.values()), None)
    return 0.0 if reference is None else reference.yaw_rad


def _holds(
    requests: dict[int, holding.HoldRequest],
    states: dict[int, VehicleState],
    mission: Mission,
    obstacles: Obstacles,
    keep_out: float,
    zones: Zones | None = None,
) -> dict[int, holding.Hold]:
    """The formation's present layout translated (``holding.formation_holds``, towards the
    leader's heading), or, where no translation clears the obstacles, each vehicle's own
    circle clear of those chosen before it."""
    yaw = _leader_yaw(states, mission)
    ids = list(requests)
    together = holding.formation_holds(
        [requests[i] for i in ids], yaw, LOITER_AHEAD_M, obstacles, keep_out, zones
    )
    if together is not None:
        return dict(zip(ids, together, strict=True))
    taken: list[tuple[holding.Hold, float]] = []  # the circles chosen so far, flown this wide
    out = {}
    for vid, r in requests.items():
        hold = holding.holding_circle(
            r.pos_m,
            r.yaw_rad,
            r.z_m,
            r.radius_m,
            LOITER_AHEAD_M,
            obstacles,
            keep_out,
            r.motion,
            taken,
            mission.limits.safe_distance_uav,
            zones,
        )
        taken.append((hold, holding.flown_width_m(r.radius_m, r.motion)))
        out[vid] = hold
    return out


def _spread(
    requests: dict[int, holding.HoldRequest],
    heights: dict[int, float],
    states: dict[int, VehicleState],
    mission: Mission,
    obstacles: Obstacles,
    keep_out: float,
    zones: Zones | None,
) -> dict[int, holding.Hold] | None:
    """Each vehicle's circle at the height it levels off at (``heights``), on a grid whose
    rings are a stack level apart (``holding.spread_holds``, towards the leader's heading);
    None where no grid clears the obstacles."""
    yaw = _leader_yaw(states, mission)
    ids = list(requests)
    level = [replace(requests[i], z_m=heights[i]) for i in ids]
    spacing = stack_spacing_m(mission)
    spread = holding.spread_holds(level, yaw, LOITER_AHEAD_M, spacing, obstacles, keep_out, zones)
    return None if spread is None else dict(zip(ids, spread, strict=True))


def levelling_height(state: VehicleState, airframe: Airframe, mission: Mission) -> float:
    """Where a vehicle would level off, told to hold its height now: its altitude and the
    lead TECS's height demand has at the vertical speed it flies
    (``prediction.height_demand_now``)."""
    vector = vehicle_motion.motion_vector(motion(state, airframe, mission))
    return float(prediction.height_demand_now(vector))


def stack_level(vehicle_id: int, heights: dict[int, float]) -> int:
    """A vehicle's level in the holding stack: how many vehicles are lower than it (ties by
    id), by ``heights`` (``levelling_height``), so that the order of heights is kept on the
    way to the holds."""
    z = heights[vehicle_id]
    return sum(1 for vid, h in heights.items() if vid != vehicle_id and (h, vid) < (z, vehicle_id))


@dataclass(frozen=True)
class HoldPlan:
    """Where each vehicle holds (``circles``) and the orders that hand the holds to the
    autopilots (``orders``: each circle's GUIDED loiter, speed and altitude; LOITER mode
    for a vehicle without a state)."""

    circles: dict[int, holding.Hold]
    orders: list[confirmation.Order]


def stack_spacing_m(mission: Mission) -> float:
    """The height between two levels of the holding stack: ``LOITER_STACK_M``, and at least
    twice the safe distance and the assurance's slack at v_min (``assurance.SLACK_S``), so
    that vehicles flying their circles one level apart are recoverable with the slack to
    spare wherever they are on them (at Table 3's 100 m/s and 50 m, 100 m apart left the
    margin exactly at the slack: an escape every time two circles crossed)."""
    lim = mission.limits
    return max(LOITER_STACK_M, 2.0 * lim.safe_distance_uav + assurance.SLACK_S * lim.v_min)


def hold_plan(
    orders: Orders,
    states: dict[int, VehicleState],
    airframes: dict[int, Airframe],
    mission_time_s: float,
    stacked: bool,
    event: Callable[..., None],
    heard: set[int],
    floor_z_m: float = -math.inf,
) -> HoldPlan:
    """Each vehicle to a holding circle (``gcs_ppf.guidance.holding``) that cuts no obstacle's
    or zone's keep-out (twice the safe distance), at ``HOLD_TURN_RADII`` turn radii at its
    speed: the formation's present layout translated (``_holds``), else each circle clear of
    its teammates' by the safe distance; flown at the mission's v_min (GUIDED keeps the last
    DO_CHANGE_SPEED: a wingman left at 218 m/s crossed its circle's centre and swung 1.4 km
    out, into a sphere, 11 s after a Table 3 run under two CPU burners). The k-th lowest
    vehicle (``levelling_height``: where it levels off) holds ``stack_spacing_m``·k above
    the target after completion (``stacked``), above the highest vehicle after an abort or a
    failure: no two circles at one height (held at their own heights after a failure, a
    leader and a wingman came to 42.5 m on crossing circles), and no two climbs or descents
    to them crossing (stacked by the mission's order, a wingman descending to its level met
    one climbing through it to a higher one, 14.2 m apart, 3.9 s after the end of a Table 3
    run; stacked by the heights they had, a wingman 20 m above another but diving at 50 m/s
    got the higher level, dived 70 m more before it climbed, and climbed through the other's
    level 42 m from it, 7.7 s after a run, ×5 on a lossy link). More than
    ``STACK_LEVELS_MAX`` vehicles (but a completion that flies home from the stack, one level
    each) hold each at its own levelling height on circles spread apart instead, where such
    a grid clears the obstacles (``_spread``). A vehicle without a state is put in LOITER;
    one not ``heard`` (lost) is not commanded. A ``hold_not_clear`` event when no circle
    keeps the keep-out.  The stack's lowest level is at least ``floor_z_m``
    (a return home over every keep-out: ``failsafe.return_floor_m``)."""
    mission = orders.mission
    obstacles = obstacles_from_mission(mission).at(mission_time_s)
    keep_out = 2.0 * mission.limits.safe_distance_obstacle
    out: list[confirmation.Order] = []
    highest = max((st.pos_m[2] for st in states.values()), default=mission.target[2])
    heights = {
        vid: st.pos_m[2] if vid not in airframes else levelling_height(st, airframes[vid], mission)
        for vid, st in states.items()
    }
    spacing = stack_spacing_m(mission)
    requests: dict[int, holding.HoldRequest] = {}
    for v in mission.vehicles:
        if v.id not in heard:
            continue
        s = states.get(v.id)
        if s is None or v.id not in airframes:
            out.append(
                confirmation.Order(
                    v.id,
                    partial(commands.set_mode, v.id, PlaneMode.LOITER),
                    commands.MAV_CMD_DO_SET_MODE,
                    "hold: mode LOITER",
                    lambda t: t.custom_mode == PlaneMode.LOITER,
                )
            )
            continue
        airframe_omega = airframes[v.id].max_turn_rate(s.speed_m_s)
        omega = min(airframe_omega or math.inf, mission.limits.max_yaw_rate)
        radius = max(HOLD_MIN_RADIUS_M, HOLD_TURN_RADII * s.speed_m_s / omega)
        base = max(mission.target[2] if stacked else highest, floor_z_m)
        z = base + spacing * stack_level(v.id, heights)
        requests[v.id] = holding.HoldRequest(
            np.array(s.pos_m), s.yaw_rad, z, radius, motion(s, airframes[v.id], mission)
        )
    zones = zones_from_mission(mission)
    home_from_stack = stacked and mission.at_end == "rtl"  # ``returning``: one level each
    spread = len(requests) > STACK_LEVELS_MAX and not home_from_stack
    circles = (
        _spread(requests, heights, states, mission, obstacles, keep_out, zones) if spread else None
    )
    if circles is None:  # not too many for a stack, or no grid clear of the obstacles
        circles = _holds(requests, states, mission, obstacles, keep_out, zones)
    for vid, hold in circles.items():
        if hold.clearance_m < keep_out:
            event("hold_not_clear", vid, clearance_m=round(hold.clearance_m, 1))
        out.extend(loiter_orders(vid, hold, orders, airframes[vid]))
    return HoldPlan(circles, out)


def loiter_orders(
    vid: int, hold: holding.Hold, orders: Orders, airframe: Airframe
) -> list[confirmation.Order]:
    """The orders that hand ``hold`` to the vehicle's autopilot: GUIDED's loiter round its
    centre (DO_REPOSITION with its radius), the mission's v_min, and in course guidance the
    guided altitude (it outlives the course)."""
    mission = orders.mission
    lat, lon, alt = enu_to_geodetic(hold.x_m, hold.y_m, hold.z_m, mission.origin)
    out = [
        confirmation.Order(
            vid,
            partial(commands.reposition, vid, lat, lon, alt, hold.radius_m),
            commands.MAV_CMD_DO_REPOSITION,
            "hold: guided loiter",
        )
    ]
    slowest = slowest_airspeed(mission, airframe)
    out.append(
        confirmation.Order(
            vid,
            partial(commands.change_speed, vid, slowest),
            commands.MAV_CMD_DO_CHANGE_SPEED,
            "hold: speed",
        )
    )
    if orders.guidance_mode == "course":
        out.append(
            confirmation.Order(
                vid,
                partial(commands.guided_change_altitude, vid, slew.sendable_altitude(alt), 0.0),
                commands.MAV_CMD_GUIDED_CHANGE_ALTITUDE,
                "hold: altitude",
            )
        )
    return out


def slowest_airspeed(mission: Mission, airframe: Airframe) -> float:
    """The airspeed a hold is flown at: the mission's v_min (within the airframe's limits)."""
    return slew.airspeed_command(mission.limits.v_min, None, None, airframe)


def hold_motion(state: VehicleState, airframe: Airframe, mission: Mission) -> vehicle_motion.Motion:
    """A holding vehicle's ``motion`` at the airspeed it is told to hold at
    (``slowest_airspeed``) or faster.  At the speed it reports, a vehicle in a launch's
    holds heard at 0 m/s (its takeoff just begun, on a lossy link) was told a heading with
    a lateral acceleration of 0, which the command refuses: the holds failed, were handed
    over, and the run never left ``starting`` (the line abreast of five at ×10, 300 ms +
    20 % loss: 1 of 7 runs)."""
    return motion(state, airframe, mission, slowest_airspeed(mission, airframe))


async def command_holds(
    fleet: Sender,
    circles: dict[int, holding.Hold],
    ids: list[int],
    motions: list[vehicle_motion.Motion],
    orders: Orders,
    keep: assurance.KeepOut,
    hold_s: float,
    event: Callable[..., None],
    escaping: dict[int, assurance.Escape],
    now_s: float,
) -> dict[int, assurance.Verdict]:
    """One tick of the holding phase flown by the service (``service.hold_flight``): each of
    ``ids`` (in priority order, the leader first; ``motions`` theirs, ``motion``) told the
    course onto and round its circle
    (``holding.loiter_course``) at its circle's height, every command assured first as in a
    run (``assurance.assure``; an escape is sent instead with an ``assurance_override``
    event, ``phase`` ``hold``).  Returns each one's verdict."""
    mission = orders.mission
    wanted = []
    for vid, m in zip(ids, motions, strict=True):
        c = circles[vid]
        course = holding.loiter_course(
            m.pos_m,
            c.x_m,
            c.y_m,
            holding.flown_radius_m(c.radius_m),
            m.speed_m_s,
            m.turn_rate_rad_s,
            m.heading_tau_s,
        )
        wanted.append(vehicle_motion.Command(course, c.z_m))
    verdicts = assurance.assure(motions, wanted, hold_s, keep, [escaping.get(i) for i in ids])
    for vid, m, v in zip(ids, motions, verdicts, strict=True):
        remember(escaping, vid, v, now_s)
        if v.replaced:
            override_event(event, vid, v, ids, phase="hold")
        cmd = slew.SlewCommand(
            v.command.course_rad, m.speed_m_s * m.turn_rate_rad_s, v.command.z_m, 0.0
        )
        point = _course_point(cmd, v, m, orders, np.array(along(m, v.command)))
        lat, lon, alt = enu_to_geodetic(*point, mission.origin)
        await _send_course(fleet, vid, cmd, v, m, orders, (lat, lon, alt))
    return dict(zip(ids, verdicts, strict=True))

"""What the GUIDED slew commands carry so that ArduPlane flies the plan: the course with the
heading error its P-only controller needs to bank for the planned turn, the lateral
acceleration that lets it, and an altitude demand that TECS can follow.

Pure.  The ArduPlane behaviour relied on (ArduPlane 4.7, ``ModeGuided::update`` and
``GCS_MAVLINK_Plane::handle_command_int_guided_slew_commands``; measured on its SITL with the
plane.parm defaults, ``../shared/arduplane-traces``):

- ``MAV_CMD_GUIDED_CHANGE_HEADING``: commanded bank (centidegrees) = GUIDED_P × heading error
  (radians), clipped to ±min(atan(param3 / g), ROLL_LIMIT_DEG); the aircraft then turns at
  g·tan(bank)/airspeed.  A course that keeps moving (a turning plan) is followed behind by
  the error that gives the bank the turn needs: 0.87° of bank per degree of error with
  GUIDED_P 5000, so a 20° bank needs 23° of error.  Commanding the planned course plus that
  error (feed-forward) puts the aircraft on the planned course in a steady turn.
- ``MAV_CMD_GUIDED_CHANGE_ALTITUDE``: param3 > 0 is not a climb-rate cap (each update moves
  the demand from the *current* altitude by param3 × Δt, and TECS barely climbs: 3.6 m in
  60 s asked at 2 m/s); param3 = 0 is "as fast as possible" (TECS at up to TECS_CLMB_MAX,
  4.0 m/s over a 50 m step).  So the service sends param3 = 0 and shapes the demand itself
  (``tecs_altitude_demand``): TECS climbs at 1.75 / TECS_TIME_CONST × the height error, so
  the demand that makes it fly the planned vertical speed v_z is v_z × TECS_TIME_CONST / 1.75
  above the planned altitude, never further from the current altitude than TECS can climb
  (sink) in a few seconds.  z = 0 and z = −1 are DENIED (``is_equal`` with a float
  epsilon): never sent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gcs_ppf.guidance.airframe import G_M_S2, Airframe
from gcs_ppf.guidance.online import Guidance
from gcs_ppf.mavlink.ardupilot import (
    CLIMB_LAG_PER_TECS_TCONST,
    HEIGHT_GAIN_TIMES_TECS_TCONST,
    TURN_EFFICIENCY,
)

LATERAL_ACCEL_MARGIN = 1.5
"""param3 of the heading command allows this many times the planned turn's lateral
acceleration (the P-controller also banks to take out errors)."""


def needed_bank_rad(turn_rate_rad_s: float, speed_m_s: float) -> float:
    """The bank of a coordinated turn at ``turn_rate_rad_s`` and airspeed ``speed_m_s``,
    atan(v·ψ̇/g), signed as the turn."""
    return math.atan(speed_m_s * turn_rate_rad_s / (TURN_EFFICIENCY * G_M_S2))


def course_lead_rad(
    turn_rate_rad_s: float,
    speed_m_s: float,
    guided_p: float | None,
    roll_limit_deg: float | None = None,
) -> float:
    """The heading error GUIDED's P-controller needs to bank for the planned turn: needed
    bank in centidegrees / GUIDED_P, in the turn's direction (radians; 0 without GUIDED_P,
    the bank capped at ROLL_LIMIT_DEG)."""
    if guided_p is None or guided_p <= 0.0 or not math.isfinite(turn_rate_rad_s):
        return 0.0
    bank = needed_bank_rad(turn_rate_rad_s, speed_m_s)
    if roll_limit_deg is not None:
        cap = math.radians(roll_limit_deg)
        bank = max(-cap, min(cap, bank))
    return math.degrees(bank) * 100.0 / guided_p


def course_command_rad(
    planned_course_rad: float,
    turn_rate_rad_s: float,
    speed_m_s: float,
    guided_p: float | None,
    roll_limit_deg: float | None = None,
    current_course_rad: float | None = None,
) -> float:
    """The course to command (ICS yaw, rad, counter-clockwise: a positive turn rate turns
    left): the planned one led by ``course_lead_rad``, the lead cut (``opposing_lead_rad``)
    where it turns against the way from ``current_course_rad`` to the planned course."""
    lead = course_lead_rad(turn_rate_rad_s, speed_m_s, guided_p, roll_limit_deg)
    if current_course_rad is not None:
        correction = math.remainder(planned_course_rad - current_course_rad, math.tau)
        lead = opposing_lead_rad(lead, correction)
    return math.remainder(planned_course_rad + lead, math.tau)


def opposing_lead_rad(lead_rad: float, correction_rad: float) -> float:
    """The lead kept when the vehicle is ``correction_rad`` off the planned course (planned
    − current): whole when it turns the same way as the correction; against it, less by
    the correction's size, and nothing once the correction is as large.

    The lead is the bank for the turn the plan makes ``lead_s`` on, for a vehicle already
    on the planned course.  A plan re-made every tick from the vehicle's state turns onto
    its new course at once (assumption 2) and then, closing on a point ahead, turns back
    the way it came; the vehicle, not yet turned, was sent the turn back as well.  A wingman
    pursuing its slot ``v/ω`` ahead turns back at the rate ArduPlane's P-controller turns
    towards it (both ~3.3 s at 28 m/s with GUIDED_P 5000 and ω = 0.3 rad/s), so the two
    cancelled whatever the error: on real ArduPlane the wingmen of a formation takeoff of 5
    flew 7–8 m inside their slots for 30 s, planned 4.4° outwards, sent 1.0–1.4° inwards
    (a lead of 5.4° for the turn back).  Cut by the correction instead, the command stays
    on the correction's side until the vehicle has turned half-way, and in a steady turn
    (where the correction is the small lag the lead takes out) it barely changes."""
    if lead_rad * correction_rad >= 0.0:
        return lead_rad
    return math.copysign(max(abs(lead_rad) - abs(correction_rad), 0.0), lead_rad)


def lateral_accel_limit(
    turn_rate_rad_s: float,
    speed_m_s: float,
    plan_limit_m_s2: float,
    roll_limit_deg: float | None = None,
) -> float:
    """param3 of the heading command (m/s²): at least the plan's own limit
    (``plan_limit_m_s2``, v_max·ω_max), at least ``LATERAL_ACCEL_MARGIN`` × the planned
    turn's v·|ψ̇|, no more than ROLL_LIMIT_DEG allows anyway (ArduPlane clips there)."""
    turn_accel = speed_m_s * abs(turn_rate_rad_s) / TURN_EFFICIENCY  # g·tan(the turn's bank)
    accel = max(plan_limit_m_s2, LATERAL_ACCEL_MARGIN * turn_accel)
    if roll_limit_deg is not None:
        accel = min(accel, G_M_S2 * math.tan(math.radians(roll_limit_deg)))
    return max(accel, 0.05) if math.isfinite(accel) else 0.05


def altitude_demand(
    planned_z_m: float,
    current_z_m: float,
    horizon_s: float,
    climb_max_m_s: float,
    sink_max_m_s: float,
) -> float:
    """The altitude to send with param3 = 0: the planned one, but no further from the
    current altitude than TECS climbs (sinks) in ``horizon_s``."""
    top = current_z_m + climb_max_m_s * horizon_s
    bottom = current_z_m - sink_max_m_s * horizon_s
    return min(max(planned_z_m, bottom), top)


def tecs_altitude_demand(
    g: Guidance, i: int, current_z_m: float, tecs_time_constant_s: float, trim_m_s: float = 0.0
) -> float | None:
    """The altitude demand (ICS z) under which TECS flies vehicle ``i``'s planned vertical
    speed: its altitude now plus the vertical speed planned a climb lag on (the vertical
    speed follows TECS's demand CLIMB_LAG_PER_TECS_TCONST × TECS_TIME_CONST behind) over
    TECS's height gain (HEIGHT_GAIN_TIMES_TECS_TCONST / TECS_TIME_CONST per second: TECS
    climbs at that gain × the height error).  The plan starts where the vehicle is when the
    command acts (the service carries each state on to that moment).  None without the
    plan's climb profile.  ``trim_m_s`` is added to the planned vertical speed
    (``climb_trim``).

    The planned altitude a look-ahead (3 s) on asks for more: at the paper's scale
    (TECS_TIME_CONST 1 s, a height gain of 1.75 /s) a demand 3 s of climb ahead is 5× what
    TECS needs, every vehicle climbed at its pitch limit whatever the plan asked, and the
    wingmen flew 70–105 m above or below their slots in the leader's climbing frame.  At
    ArduPlane's (5 s: 0.35 /s, a 2 s lag) the two demands are nearly the same."""
    if g.climb_plan_m_s is None or g.speed_plan_t_s is None:
        return None
    lag_s = CLIMB_LAG_PER_TECS_TCONST * tecs_time_constant_s
    climb = float(np.interp(lag_s, g.speed_plan_t_s, g.climb_plan_m_s[:, i])) + trim_m_s
    return current_z_m + climb * tecs_time_constant_s / HEIGHT_GAIN_TIMES_TECS_TCONST


def planned_climb_m_s(g: Guidance, i: int, tecs_time_constant_s: float) -> float | None:
    """The vertical speed ``tecs_altitude_demand`` asks vehicle ``i`` for, without the trim."""
    if g.climb_plan_m_s is None or g.speed_plan_t_s is None:
        return None
    lag_s = CLIMB_LAG_PER_TECS_TCONST * tecs_time_constant_s
    return float(np.interp(lag_s, g.speed_plan_t_s, g.climb_plan_m_s[:, i]))


CLIMB_TRIM_RESPONSES = 2.0
"""The climb trim integrates over this many of TECS's vertical responses (its climb lag
plus the inverse of its height gain: 1 s at the paper's scale, 4.9 s at ArduPlane's)."""
CLIMB_TRIM_SHARE = 0.25
"""The climb trim is kept within this share of TECS_CLMB_MAX / TECS_SINK_MAX."""


@dataclass(frozen=True)
class ClimbTrim:
    """What one vehicle's vertical channel has learnt (``climb_trim``): the vertical speed
    added to the plan's so that the vehicle flies the plan's, and the one asked last."""

    trim_m_s: float = 0.0
    asked_m_s: float | None = None
    """The vertical speed the last command asked for (None: no TECS-led command)."""
    at_s: float | None = None
    """Mission time of that command."""


def climb_trim(
    trim: ClimbTrim, flown_m_s: float | None, now_s: float, airframe: Airframe
) -> ClimbTrim:
    """``trim`` after the vehicle flew ``flown_m_s`` where its last command asked
    ``trim.asked_m_s``: the shortfall integrated over ``CLIMB_TRIM_RESPONSES`` of TECS's
    responses, within ``CLIMB_TRIM_SHARE`` of its climb and sink limits.

    TECS climbs at its height gain × the height error, so a demand a few metres off the
    altitude the vehicle has when the command lands (telemetry a stream interval old, the
    link's delay) flies another vertical speed: at the paper's scale (1.75 /s) 8 m are
    14 m/s, and flown, the leader climbed at 33° where its plans asked 39°, which left the
    wingmen 40–70 m below their slots in the plan's climbing frame."""
    tecs, climb, sink = airframe.tecs_time_constant_s, airframe.climb_max_m_s, airframe.sink_max_m_s
    if (
        trim.asked_m_s is None
        or trim.at_s is None
        or flown_m_s is None
        or tecs is None
        or climb is None
        or sink is None
        or now_s <= trim.at_s
    ):
        return trim
    response_s = (CLIMB_LAG_PER_TECS_TCONST + 1.0 / HEIGHT_GAIN_TIMES_TECS_TCONST) * tecs
    gain = min((now_s - trim.at_s) / (CLIMB_TRIM_RESPONSES * response_s), 1.0)
    value = trim.trim_m_s + gain * (trim.asked_m_s - flown_m_s)
    value = min(max(value, -CLIMB_TRIM_SHARE * sink), CLIMB_TRIM_SHARE * climb)
    return ClimbTrim(value, trim.asked_m_s, trim.at_s)


REFUSED_ALTITUDES = (0.0, -1.0)
"""ArduPlane DENIES a CHANGE_ALTITUDE to these (``is_equal`` within a float epsilon)."""
_REFUSED_WINDOW_M = 0.01


def sendable_altitude(alt_m: float) -> float:
    """``alt_m`` moved 2 cm up if it is within 1 cm of a value ArduPlane refuses."""
    if any(abs(alt_m - r) < _REFUSED_WINDOW_M for r in REFUSED_ALTITUDES):
        return alt_m + 2.0 * _REFUSED_WINDOW_M
    return alt_m


@dataclass(frozen=True)
class SlewCommand:
    """One vehicle's course and altitude commands for one tick."""

    course_rad: float
    """ICS yaw to command (MAV_CMD_GUIDED_CHANGE_HEADING param2 after conversion)."""
    lateral_accel_m_s2: float
    """param3 of the heading command."""
    z_m: float
    """ICS altitude demand (MAV_CMD_GUIDED_CHANGE_ALTITUDE z after conversion)."""
    rate_m_s: float
    """param3 of the altitude command: 0 is "as fast as possible"."""
    climb_m_s: float | None = None
    """The vertical speed the altitude demand asks TECS for (``tecs_altitude_demand``),
    None when it is not led so."""


def slew_command(
    g: Guidance,
    i: int,
    airframe: Airframe,
    current_z_m: float,
    plan_accel_limit_m_s2: float,
    horizon_s: float,
    current_course_rad: float | None = None,
    climb_trim_m_s: float = 0.0,
    formation_turn_rad_s: float | None = None,
) -> SlewCommand:
    """Vehicle ``i`` of ``g``'s course (led for its P-controller when it reports GUIDED_P,
    the lead cut against the turn from ``current_course_rad``, ``opposing_lead_rad``; with
    ``formation_turn_rad_s``, led for that turn instead, uncut) and
    altitude: with TECS limits known, param3 = 0 and the demand shaped
    (``altitude_demand`` of ``tecs_altitude_demand`` when TECS_TIME_CONST is known and the
    plan's climb is finite, else of the planned altitude ``horizon_s`` ahead, as on the
    leader's final approach); without, the planned
    altitude at the planned vertical speed (how ArduPlane-like simulators without TECS
    were flown).  A vertical resolution is flown as fast as possible, unshaped (the guard
    asks only what the airframe climbs within its horizon)."""
    speed = float(g.speed_m_s[i])
    turn = float(g.turn_rate_rad_s[i])
    lead_turn, now = turn, current_course_rad
    if formation_turn_rad_s is not None:  # the formation's turn led, the wingman's own not
        lead_turn, now = formation_turn_rad_s, None
    course = course_command_rad(
        float(g.course_rad[i]), lead_turn, speed, airframe.guided_p, airframe.roll_limit_deg, now
    )
    accel = lateral_accel_limit(turn, speed, plan_accel_limit_m_s2, airframe.roll_limit_deg)
    planned_z = float(g.guided_point_m[i, 2])
    resolving = bool(g.resolving and g.resolving[i])
    climb, sink = airframe.climb_max_m_s, airframe.sink_max_m_s
    if resolving:
        return SlewCommand(course, accel, planned_z, 0.0)
    rate = float(g.climb_rate_m_s[i])
    if climb is not None and sink is not None:
        tecs = airframe.tecs_time_constant_s
        led = asked = None
        if tecs is not None and math.isfinite(rate):
            led = tecs_altitude_demand(g, i, current_z_m, tecs, climb_trim_m_s)
            asked = planned_climb_m_s(g, i, tecs)
        z = altitude_demand(planned_z if led is None else led, current_z_m, horizon_s, climb, sink)
        return SlewCommand(course, accel, z, 0.0, asked)
    return SlewCommand(course, accel, planned_z, rate if math.isfinite(rate) else 0.0)


def airspeed_command(
    planned_speed_m_s: float,
    airspeed_m_s: float | None,
    groundspeed_m_s: float | None,
    airframe: Airframe,
    speed_ratio: float | None = None,
) -> float:
    """The airspeed to command (DO_CHANGE_SPEED) for a planned speed over the ground.

    The plan lives in the ground frame (positions and speeds from GLOBAL_POSITION_INT), but
    ArduPlane holds an airspeed, and its airspeed (equivalent, EAS) is not its speed over
    the ground even without wind: the true airspeed is EAS × the density ratio, about 6–7 %
    more at 700 m AMSL (``../shared/arduplane-traces``: VFR_HUD groundspeed 6–7 % above
    airspeed).  Commanded as is, a plan that slows a vehicle down is never flown: the
    vehicle keeps flying faster than planned, and the next plan starts from that speed.  So
    the planned speed is scaled by the vehicle's own airspeed / groundspeed (VFR_HUD; 1 when
    unknown or implausible; ``speed_ratio``, the averaged ratio, when given) and kept within
    AIRSPEED_MIN..AIRSPEED_MAX (ArduPlane FAILS a speed outside them)."""
    ratio = 1.0
    if speed_ratio is not None and 0.5 <= speed_ratio <= 2.0:
        ratio = speed_ratio
    elif airspeed_m_s is not None and groundspeed_m_s is not None and groundspeed_m_s > 1.0:
        measured = airspeed_m_s / groundspeed_m_s
        if 0.5 <= measured <= 2.0:
            ratio = measured
    speed = planned_speed_m_s * ratio
    if airframe.airspeed_min_m_s is not None:
        speed = max(speed, airframe.airspeed_min_m_s)
    if airframe.airspeed_max_m_s is not None:
        speed = min(speed, airframe.airspeed_max_m_s)
    return speed

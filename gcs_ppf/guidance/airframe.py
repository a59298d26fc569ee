"""Each vehicle's flight envelope read from its ArduPlane parameters, and the online limits,
planning margin and separation-guard tuning derived from the envelopes of the fleet.

Pure.  Every figure comes from what ArduPlane itself does with the parameter:

- ``TECS_CLMB_MAX`` / ``TECS_SINK_MAX`` (m/s): TECS never demands a steeper climb or sink
  (``AP_TECS::_update_height_demand``), whatever the pitch limits allow; at airspeed v the
  flight path is therefore within asin(TECS_CLMB_MAX / v) up and asin(TECS_SINK_MAX / v) down.
- ``PTCH_LIM_MAX_DEG`` / ``PTCH_LIM_MIN_DEG``: the attitude limits (the flight path is kept
  within them too).
- ``AIRSPEED_MIN`` / ``AIRSPEED_MAX``: DO_CHANGE_SPEED outside them FAILS; the plan's speed
  range is kept inside.
- ``ROLL_LIMIT_DEG``: no bank beyond it, so a coordinated turn at airspeed v is at most
  ω_max(v) = g·tan(ROLL_LIMIT_DEG)/v.
- ``GUIDED_P``: GUIDED's heading controller (``ModeGuided::update``, ``guidedHeading``, P only
  in the defaults) banks GUIDED_P centidegrees per radian of heading error, so the heading
  error decays with the time constant v/(K·g), K = GUIDED_P·π/18000 (rad of bank per rad of
  error); with the service's feed-forward (``gcs_ppf.guidance.slew``) only what the roll-in leaves
  does (``response_lag_s``, from which the closed-loop margins are sized).
- ``TKOFF_ALT``: TAKEOFF mode climbs to it above home, then loiters.
- ``RLL2SRV_TCONST``: the roll loop's time constant (how long a commanded bank takes).

A parameter a vehicle did not answer is None here, and whatever depends on it keeps the
mission's limits or the service's fixed settings for that vehicle (the paper's scenes on a
simulator that does not have ArduPlane's parameters fly as before).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass

import numpy as np

from gcs_ppf.mavlink.ardupilot import TURN_EFFICIENCY
from gcs_ppf.mavlink.telemetry import VehicleTelemetry
from gcs_ppf.planning.scene import FloatArray

G_M_S2 = 9.80665
"""Standard gravity (ArduPilot's ``GRAVITY_MSS``)."""

DEFAULT_PLANNING_MARGIN_M = 100.0
"""Closed-loop planning margin tuned and measured at the paper's 100–300 m/s: a vehicle
without ``GUIDED_P`` gets it, and a derived margin never exceeds it.  Derived for the
built-in SITL's paper airframe (GUIDED_P for a 0.4 s heading loop at 100 m/s), v_max × lag
is 289 m: the keep-outs of Table 3's obstacles then overlap into one wall, and flown
closed loop the leader went 188 m into an obstacle (PPF's repulsions add between
overlapping spheres).  At ArduPlane's speeds the derivation gives less: 31 m at 28 m/s
with the roll-in lag, 94 m with the heading time constant (without RLL2SRV_TCONST)."""
DEFAULT_GUARD_HORIZON_S = 4.0
"""Separation-guard look-ahead tuned at 100–300 m/s: the shortest; an airframe that needs
longer to climb or sink the safe distance gets that time."""
DEFAULT_GUARD_MARGIN_M = 50.0
"""Separation-guard margin tuned at 100–300 m/s: the largest (see
``DEFAULT_PLANNING_MARGIN_M``), and that of a vehicle without ``GUIDED_P``."""
DEFAULT_GUARD_RESOLUTION_M = 150.0
"""Vertical resolution tuned at 100–300 m/s: the largest, and that of a vehicle without TECS
limits; one that climbs (sinks) less within the horizon is asked for less."""


@dataclass(frozen=True)
class Airframe:
    """One vehicle's envelope as its parameters give it (SI units; None: not answered)."""

    climb_max_m_s: float | None = None
    """``TECS_CLMB_MAX``."""
    sink_max_m_s: float | None = None
    """``TECS_SINK_MAX``."""
    airspeed_min_m_s: float | None = None
    """``AIRSPEED_MIN`` (``ARSPD_FBW_MIN`` before ArduPlane 4.5)."""
    airspeed_cruise_m_s: float | None = None
    """``AIRSPEED_CRUISE`` (``TRIM_ARSPD_CM`` / 100 before 4.5)."""
    airspeed_max_m_s: float | None = None
    """``AIRSPEED_MAX`` (``ARSPD_FBW_MAX`` before 4.5)."""
    roll_limit_deg: float | None = None
    """``ROLL_LIMIT_DEG`` (``LIM_ROLL_CD`` / 100 before 4.5)."""
    guided_p: float | None = None
    """``GUIDED_P``: centidegrees of bank per radian of heading error in GUIDED."""
    pitch_max_deg: float | None = None
    """``PTCH_LIM_MAX_DEG`` (``LIM_PITCH_MAX`` / 100 before 4.5)."""
    pitch_min_deg: float | None = None
    """``PTCH_LIM_MIN_DEG`` (``LIM_PITCH_MIN`` / 100 before 4.5); negative."""
    takeoff_alt_m: float | None = None
    """``TKOFF_ALT``."""
    roll_time_constant_s: float | None = None
    """``RLL2SRV_TCONST``: how fast the roll loop reaches a demanded bank."""
    tecs_time_constant_s: float | None = None
    """``TECS_TIME_CONST``: how fast TECS answers a height error."""

    @staticmethod
    def from_params(value: Callable[[str], float | None]) -> Airframe:
        """The envelope from ``value(name)`` (a parameter's value, None if not answered),
        preferring the names of ArduPlane 4.5 on; values that cannot be a limit (a zero or
        negative rate, speed or gain) count as not answered."""

        def first(*names_scales: tuple[str, float]) -> float | None:
            for name, scale in names_scales:
                v = value(name)
                if v is not None and math.isfinite(v):
                    return v * scale
            return None

        def positive(v: float | None) -> float | None:
            return v if v is not None and v > 0.0 else None

        roll = positive(first(("ROLL_LIMIT_DEG", 1.0), ("LIM_ROLL_CD", 0.01)))
        return Airframe(
            climb_max_m_s=positive(first(("TECS_CLMB_MAX", 1.0))),
            sink_max_m_s=positive(first(("TECS_SINK_MAX", 1.0))),
            airspeed_min_m_s=positive(first(("AIRSPEED_MIN", 1.0), ("ARSPD_FBW_MIN", 1.0))),
            airspeed_cruise_m_s=positive(first(("AIRSPEED_CRUISE", 1.0), ("TRIM_ARSPD_CM", 0.01))),
            airspeed_max_m_s=positive(first(("AIRSPEED_MAX", 1.0), ("ARSPD_FBW_MAX", 1.0))),
            roll_limit_deg=roll if roll is not None and roll < 90.0 else None,
            guided_p=positive(first(("GUIDED_P", 1.0))),
            pitch_max_deg=positive(first(("PTCH_LIM_MAX_DEG", 1.0), ("LIM_PITCH_MAX", 0.01))),
            pitch_min_deg=first(("PTCH_LIM_MIN_DEG", 1.0), ("LIM_PITCH_MIN", 0.01)),
            takeoff_alt_m=positive(first(("TKOFF_ALT", 1.0))),
            roll_time_constant_s=positive(first(("RLL2SRV_TCONST", 1.0))),
            tecs_time_constant_s=positive(first(("TECS_TIME_CONST", 1.0))),
        )

    @staticmethod
    def from_telemetry(t: VehicleTelemetry) -> Airframe:
        """The envelope from the PARAM_VALUEs a vehicle has answered."""

        def value(name: str) -> float | None:
            p = t.param(name)
            return None if p is None else p.value

        return Airframe.from_params(value)

    def as_dict(self) -> dict[str, float | None]:
        """For ``GET /vehicles``."""
        return asdict(self)

    @property
    def heading_gain(self) -> float | None:
        """K: radians of bank per radian of heading error (GUIDED_P·π/18000)."""
        return None if self.guided_p is None else self.guided_p * math.pi / 18000.0

    def heading_time_constant_s(self, speed_m_s: float) -> float | None:
        """How long GUIDED takes to take 63 % off a small heading error at ``speed_m_s``:
        turn rate g·tan(K·e)/v ≈ (K·g/v)·e, so e decays with v/(K·g)."""
        k = self.heading_gain
        return None if k is None else speed_m_s / (k * TURN_EFFICIENCY * G_M_S2)

    def max_turn_rate(self, speed_m_s: float) -> float | None:
        """ω_max(v) = g·tan(ROLL_LIMIT_DEG)/v, rad/s."""
        if self.roll_limit_deg is None:
            return None
        tan_bank = math.tan(math.radians(self.roll_limit_deg))
        return TURN_EFFICIENCY * G_M_S2 * tan_bank / max(speed_m_s, 1e-6)

    def max_climb_angle(self, speed_m_s: float) -> float | None:
        """Steepest flight-path climb (rad) at ``speed_m_s``: the pitch limit, and what
        TECS_CLMB_MAX gives at that speed."""
        return _tightest(
            None if self.pitch_max_deg is None else math.radians(self.pitch_max_deg),
            _path_angle(self.climb_max_m_s, speed_m_s),
        )

    def max_dive_angle(self, speed_m_s: float) -> float | None:
        """Steepest flight-path dive (rad, positive) at ``speed_m_s``: the pitch limit, and
        what TECS_SINK_MAX gives at that speed."""
        pitch_min = self.pitch_min_deg
        return _tightest(
            None if pitch_min is None or pitch_min >= 0.0 else math.radians(-pitch_min),
            _path_angle(self.sink_max_m_s, speed_m_s),
        )


def _path_angle(rate_m_s: float | None, speed_m_s: float) -> float | None:
    if rate_m_s is None:
        return None
    return math.asin(min(1.0, rate_m_s / max(speed_m_s, 1e-6)))


def _tightest(*values: float | None) -> float | None:
    known = [v for v in values if v is not None]
    return min(known) if known else None


@dataclass(frozen=True)
class OnlineLimits:
    """What the fleet's envelopes change in the planner's limits (None: the mission's)."""

    v_min: float | None = None
    v_max: float | None = None
    max_yaw_rate: float | None = None
    max_climb_angle: float | None = None
    max_dive_angle: float | None = None


def fleet_speed_range(airframes: Sequence[Airframe]) -> tuple[float | None, float | None]:
    """The speed range every vehicle can be commanded: the highest AIRSPEED_MIN and the
    lowest AIRSPEED_MAX of those that answered."""
    lows = [a.airspeed_min_m_s for a in airframes if a.airspeed_min_m_s is not None]
    highs = [a.airspeed_max_m_s for a in airframes if a.airspeed_max_m_s is not None]
    return (max(lows) if lows else None, min(highs) if highs else None)


def online_limits(airframes: Sequence[Airframe], speed_m_s: float) -> OnlineLimits:
    """The tightest of the fleet's envelopes, with the turn rate and the flight-path angles
    taken at ``speed_m_s`` (the fastest any vehicle may fly within the plan's look-ahead:
    both only get tighter with speed)."""
    v_min, v_max = fleet_speed_range(airframes)
    return OnlineLimits(
        v_min=v_min,
        v_max=v_max,
        max_yaw_rate=_tightest(*(a.max_turn_rate(speed_m_s) for a in airframes)),
        max_climb_angle=_tightest(*(a.max_climb_angle(speed_m_s) for a in airframes)),
        max_dive_angle=_tightest(*(a.max_dive_angle(speed_m_s) for a in airframes)),
    )


ROLL_IN_TIME_CONSTANTS = 4.0
"""A bank is reached within this many roll time constants (98 % of a first-order step).
Real ArduPlane (RLL2SRV_TCONST 0.25 s) peaked at 50° of bank 1.0 s after a course step."""


def response_lag_s(airframe: Airframe, speed_m_s: float, telemetry_interval_s: float) -> float:
    """How far behind its plan a vehicle flies, in seconds, plus one telemetry interval (the
    plan starts from a position that old); NaN without GUIDED_P.

    The service leads GUIDED's P-only heading controller by the error a planned turn needs
    (``gcs_ppf.guidance.slew``), so a vehicle does not follow a turning plan behind by the heading
    time constant v/(K·g) any more (2.6 s at 22 m/s: the 7–8° the issue measured); what is
    left is the roll-in, ``ROLL_IN_TIME_CONSTANTS`` × RLL2SRV_TCONST (1.0 s by default), the
    heading error it leaves then decaying with v/(K·g).  Without RLL2SRV_TCONST the heading
    time constant itself is taken.  Measured on real ArduPlane 4.7 SITL (3 vehicles, ground
    start, ``tests/integration/test_arduplane.py``): with the heading time constant (94 m
    of margin at 28 m/s) the wingmen could not come nearer than 93–133 m to slots 141 m
    from the leader (closer than the safe distance plus that margin); with 30 m they came
    to 13.5 and 26.7 m, separation ≥ 103.8 m, clearance ≥ 157 m."""
    tau = airframe.heading_time_constant_s(speed_m_s)
    if tau is None:
        return math.nan
    if airframe.roll_time_constant_s is not None:
        return ROLL_IN_TIME_CONSTANTS * airframe.roll_time_constant_s + telemetry_interval_s
    return tau + telemetry_interval_s


def planning_margin_m(
    airframes: Sequence[Airframe], v_max_m_s: float, telemetry_interval_s: float
) -> float:
    """The closed-loop margin added to both safe distances: v_max × the response lag at
    v_max for the slowest-responding vehicle, at most ``DEFAULT_PLANNING_MARGIN_M`` (which a
    vehicle without GUIDED_P, or an empty fleet, gets)."""
    margins = []
    for a in airframes:
        lag = response_lag_s(a, v_max_m_s, telemetry_interval_s)
        margins.append(DEFAULT_PLANNING_MARGIN_M if math.isnan(lag) else v_max_m_s * lag)
    return min(max(margins, default=DEFAULT_PLANNING_MARGIN_M), DEFAULT_PLANNING_MARGIN_M)


@dataclass(frozen=True)
class GuardTuning:
    """The separation guard's parameters for one tick, per vehicle in scene order."""

    horizon_s: float
    margin_m: FloatArray
    """Added to the safe distance: a pair closer than that within the horizon conflicts
    (and a resolution in force holds until the miss clears it by as much again)."""
    resolution_up_m: FloatArray
    resolution_down_m: FloatArray


def guard_tuning(
    airframes: Sequence[Airframe],
    speeds_m_s: Sequence[float],
    safe_distance_m: float,
    telemetry_interval_s: float,
    *,
    horizon_s: float | None = None,
    margin_m: float | None = None,
    resolution_m: float | None = None,
) -> GuardTuning:
    """The guard's horizon, margins and resolutions from the airframes (the keyword
    arguments, when given, override what is derived).

    A vertical resolution at TECS's climb (sink) rate needs safe_distance / rate seconds,
    after the vehicle's response lag, to open the safe distance vertically: that is the
    horizon (the longest of the fleet, no shorter than ``DEFAULT_GUARD_HORIZON_S``), and a
    vehicle is asked to climb (sink) only what it can within it: rate × horizon, no more
    than ``DEFAULT_GUARD_RESOLUTION_M`` (which one without TECS limits gets).  The margin
    is what the vehicle flies during its response lag, speed × lag, no more than
    ``DEFAULT_GUARD_MARGIN_M`` (which one without GUIDED_P gets).  The bounds keep the
    paper's fast airframes as the guard was tuned for them (150 m, 4 s, 50 m).
    """
    n = len(airframes)
    lags = [
        response_lag_s(a, v, telemetry_interval_s)
        for a, v in zip(airframes, speeds_m_s, strict=True)
    ]
    if horizon_s is None:
        horizons = []
        for a, lag in zip(airframes, lags, strict=True):
            rate = _tightest(a.climb_max_m_s, a.sink_max_m_s)
            if rate is None:
                horizons.append(DEFAULT_GUARD_HORIZON_S)
            else:
                horizons.append(safe_distance_m / rate + (0.0 if math.isnan(lag) else lag))
        horizon_s = max([DEFAULT_GUARD_HORIZON_S, *horizons])
    margins = np.array(
        [
            margin_m
            if margin_m is not None
            else (
                DEFAULT_GUARD_MARGIN_M if math.isnan(lag) else min(v * lag, DEFAULT_GUARD_MARGIN_M)
            )
            for v, lag in zip(speeds_m_s, lags, strict=True)
        ],
        dtype=float,
    ).reshape(n)

    def resolution(rate: float | None) -> float:
        if resolution_m is not None:
            return resolution_m
        if rate is None:
            return DEFAULT_GUARD_RESOLUTION_M
        return min(rate * horizon_s, DEFAULT_GUARD_RESOLUTION_M)

    up = np.array([resolution(a.climb_max_m_s) for a in airframes], dtype=float).reshape(n)
    down = np.array([resolution(a.sink_max_m_s) for a in airframes], dtype=float).reshape(n)
    return GuardTuning(horizon_s, margins, up, down)


def fastest_speed(
    speeds_m_s: Sequence[float], v_min: float, v_max: float, accel: float, lookahead_s: float
) -> float:
    """The fastest any vehicle may fly within the plan's look-ahead: the fastest now plus
    what it can gain, within [v_min, v_max]."""
    now = max(speeds_m_s, default=v_min)
    return min(v_max, max(v_min, now + accel * lookahead_s))


@dataclass(frozen=True)
class TickEnvelope:
    """What the fleet's envelopes give one planning tick."""

    limits: OnlineLimits
    planning_margin_m: float
    speed_m_s: float
    """The speed the turn rate and flight-path angles were taken at."""


def tick_envelope(
    airframes: Sequence[Airframe],
    speeds_m_s: Sequence[float],
    mission_v_min: float,
    mission_v_max: float,
    accel: float,
    lookahead_s: float,
    telemetry_interval_s: float,
    margin_override_m: float | None = None,
) -> TickEnvelope:
    """The online limits (``online_limits``) at the fastest speed of the look-ahead and the
    planning margin (``planning_margin_m`` at the plan's top speed, or the override)."""
    _, airspeed_max = fleet_speed_range(airframes)
    v_max = mission_v_max if airspeed_max is None else min(mission_v_max, airspeed_max)
    v_min = min(mission_v_min, v_max)
    speed = fastest_speed(speeds_m_s, v_min, v_max, accel, lookahead_s)
    margin = margin_override_m
    if margin is None:
        margin = planning_margin_m(airframes, v_max, telemetry_interval_s)
    return TickEnvelope(online_limits(airframes, speed), margin, speed)

"""Fleet flight model: how an ArduPlane flies the demands of its own autopilot — bank-to-turn
with a roll lag, GUIDED's P-only heading controller, L1 navigation, a TECS-like height and
speed loop with climb and sink limits, and the takeoff roll — calibrated against real
ArduPlane SITL (``tests/sitl/test_arduplane_calibration.py``, ``../shared/arduplane-traces``).

Everything is a structure of arrays over the fleet (N vehicles) and every function is pure:
``step`` takes the state, the envelope and the guidance commands and returns a new state.
Frames and units follow CONVENTIONS §1: ICS = local ENU metres, pitch θ positive nose up,
yaw ψ from +x (east) counter-clockwise, speeds m/s, rates rad/s; roll is reported with
MAVLink's sign (right wing down positive, a clockwise turn).

Kinematics are the paper's Eq. 5 with the flight-path angle as pitch (no wind, so airspeed
= speed along the path and course = yaw)::

    ẋ = v cos θ cos ψ     ẏ = v cos θ sin ψ     ż = v sin θ = climb rate

The turn is what the bank gives, ψ̇ = −η g tan φ / v (η = ``TURN_EFFICIENCY``), within the
airframe's SIM_YAW_RATE; the bank follows the autopilot's demand within a roll-rate limit,
second-order and overshooting as ArduPlane's does (SIM_ROLL_ZETA), or with a first-order
lag (``roll_lag_s``).  The demand is ArduPlane's:

* GUIDED heading (MAV_CMD_GUIDED_CHANGE_HEADING, ArduPlane ``mode_guided.cpp``): a P-only
  controller, bank = GUIDED_P (centidegrees per radian) × course error, clipped to
  ±min(atan(param3 / g), ROLL_LIMIT_DEG) — the aircraft lags a turning course command;
* waypoints: L1 navigation, lateral acceleration 4πζ v sin η / NAVL1_PERIOD towards the
  desired course; loiters as ArduPlane's L1 loiter, straight for the centre until the
  circle's own demand (radial PD + v²/r) takes over (``loiter_accel_left``);
* CIRCLE: the bank of a circle of WP_LOITER_RAD.

Height is a TECS-like loop: the height demand moves towards the target at no more than
TECS_CLMB_MAX / TECS_SINK_MAX, the climb-rate demand is ``height_gain_1_s`` × the height error
(within those limits and the pitch limits; no feed-forward of the demand's rate, which is
why a slewed GUIDED altitude barely climbs), and the climb rate follows it with a lag
(``climb_lag_s``).  Speeding up costs height and slowing down gains it (TECS trades energy:
the envelope's ``speed_height_coupling``).  Speed follows its demand within SIM_ACCEL_MAX /
SIM_DECEL_MAX, second-order as ArduPlane's TECS (SIM_SPD_OMEGA, SIM_SPD_ZETA) or with a
first-order lag.  A vehicle on the ground stays there unless it is taking off (ArduPlane's
TAKEOFF mode): it rolls along its heading at ``GROUND_ACCEL_M_S2`` and lifts off at its
rotation speed, then climbs at the takeoff climb rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from enum import IntEnum

import numpy as np
from numpy.typing import NDArray

from gcs_ppf.mavlink.ardupilot import (
    CLIMB_LAG_PER_TECS_TCONST,
    HEIGHT_GAIN_TIMES_TECS_TCONST,
    ROLL_LAG_PER_TCONST,
    ROLL_RATE_MAX_RAD_S,
    TURN_EFFICIENCY,
)

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

GRAVITY_M_S2 = 9.80665
#: Physics step of the SITL (50 Hz), seconds.
DT_S = 0.02

# Fitted to real ArduPlane 4.7 SITL (plane.parm), see tests/sitl/test_arduplane_calibration.py
# (the roll loop's lag and rate, the turn efficiency and TECS's climb lag and height gain
# are gcs_ppf.mavlink.ardupilot's).
#: The vertical speed's lag in the takeoff climb, s (trace 01 climbed at 10 m/s 0.5 s
#: after lift-off).
TAU_TAKEOFF_CLIMB_S = 0.4
#: The natural frequency of the bank's second-order response (``Envelope.roll_damping`` >
#: 0), × the roll lag: fitted with ArduPlane's damping of 0.45 to the peak bank of its
#: course steps (50° at a 45° limit, 20° on a demand of 17.5°).
ROLL_OMEGA_TIMES_LAG = 1.2
#: Lag of the airspeed behind its demand where it is first-order (``Envelope.speed_damping``
#: 0), s (within SIM_ACCEL_MAX / SIM_DECEL_MAX).
TAU_SPEED_S = 1.0
#: How often ArduPlane moves GUIDED's slewed altitude demand (``update_target_altitude``
#: clamps it to the current altitude ± param3 × this), s.
GUIDED_ALT_UPDATE_S = 0.1
#: Airspeed of the full-throttle takeoff climb, × the rotation speed (trace 01: 27 m/s).
TAKEOFF_SPEED_FACTOR = 1.4
#: Takeoff roll acceleration at full throttle, m/s² (lift-off at 19 m/s after 3.8 s).
GROUND_ACCEL_M_S2 = 6.0
#: A loiter circle is at least this factor times the tightest turn radius.
ORBIT_MARGIN = 1.15
#: Flight-path angle held by a vehicle without thrust (disarmed or dead): a glide, radians.
GLIDE_PITCH_RAD = -0.1
#: Below this speed the turn formula uses it instead (no division by zero on the ground).
MIN_TURN_SPEED_M_S = 1.0


class GuidanceKind(IntEnum):
    """What the guidance of one vehicle does during a step."""

    HOLD = 0
    """Neutral controls: wings level, pitch held (MANUAL with centred sticks)."""
    GOTO = 1
    """L1 navigation to ``target_enu_m`` (horizontal), TECS to its altitude."""
    ORBIT = 2
    """Loiter on a circle of ``radius_m`` around ``target_enu_m`` (L1 onto the circle), TECS
    to the target's altitude."""
    TURN = 3
    """Constant-bank circle (ArduPlane CIRCLE mode), TECS to the target's altitude."""
    COURSE = 4
    """Hold the course ``course_rad`` with GUIDED's P-only heading controller, banking no
    more than ``lateral_accel_m_s2`` allows (MAV_CMD_GUIDED_CHANGE_HEADING)."""


@dataclass(frozen=True, slots=True)
class FleetState:
    """State of N vehicles. Arrays have shape (N, 3) for positions, (N,) otherwise.

    ``pitch_rad`` is the flight-path angle, ``roll_rad`` the bank (MAVLink sign),
    ``climb_m_s`` the vertical speed, ``height_demand_m`` TECS's rate-limited height demand
    (ICS z), ``landed`` true while on the ground.
    """

    pos_enu_m: FloatArray
    pitch_rad: FloatArray
    yaw_rad: FloatArray
    speed_m_s: FloatArray
    roll_rad: FloatArray
    climb_m_s: FloatArray
    height_demand_m: FloatArray
    pitch_rate_rad_s: FloatArray
    yaw_rate_rad_s: FloatArray
    accel_m_s2: FloatArray
    landed: BoolArray
    roll_rate_rad_s: FloatArray

    @property
    def n(self) -> int:
        return int(self.speed_m_s.shape[0])

    def velocity_enu_m_s(self) -> FloatArray:
        """ICS velocity, shape (N, 3)."""
        cp = np.cos(self.pitch_rad)
        v = self.speed_m_s
        out: FloatArray = np.stack(
            (
                v * cp * np.cos(self.yaw_rad),
                v * cp * np.sin(self.yaw_rad),
                v * np.sin(self.pitch_rad),
            ),
            axis=1,
        )
        return out


@dataclass(slots=True)
class Envelope:
    """Performance limits and autopilot gains of each vehicle, shape (N,); mutable:
    parameters change them (``Autopilot.write_envelope``)."""

    v_min_m_s: FloatArray
    v_max_m_s: FloatArray
    accel_m_s2: FloatArray
    decel_m_s2: FloatArray
    max_pitch_rate_rad_s: FloatArray
    max_yaw_rate_rad_s: FloatArray
    pitch_min_rad: FloatArray
    pitch_max_rad: FloatArray
    ground_z_m: FloatArray
    roll_limit_rad: FloatArray
    heading_gain: FloatArray
    """GUIDED_P as radians of bank per radian of course error."""
    climb_max_m_s: FloatArray
    sink_max_m_s: FloatArray
    l1_period_s: FloatArray
    l1_damping: FloatArray
    takeoff_climb_m_s: FloatArray
    rotate_speed_m_s: FloatArray
    speed_height_coupling: FloatArray
    """Fraction of the kinetic energy of a speed change that TECS pays in height."""
    roll_lag_s: FloatArray
    roll_damping: FloatArray
    """Damping of the bank's second-order response to its demand (ArduPlane's overshoots);
    0: a first-order lag of ``roll_lag_s``."""
    speed_omega_rad_s: FloatArray
    speed_damping: FloatArray
    """The airspeed's second-order response to its demand (TECS's, which lags a ramp and
    overshoots after it): natural frequency and damping; damping 0: a first-order lag of
    ``TAU_SPEED_S``."""
    climb_lag_s: FloatArray
    height_gain_1_s: FloatArray


def default_envelope(
    n: int,
    *,
    v_min: float,
    v_max: float,
    accel: float,
    decel: float,
    max_pitch_rate: float,
    max_yaw_rate: float,
    ground_z_m: FloatArray,
) -> Envelope:
    """An envelope for N vehicles with ArduPlane's default gains (plane.parm); the autopilots
    overwrite it from their parameters."""
    return Envelope(
        v_min_m_s=np.full(n, v_min),
        v_max_m_s=np.full(n, v_max),
        accel_m_s2=np.full(n, accel),
        decel_m_s2=np.full(n, decel),
        max_pitch_rate_rad_s=np.full(n, max_pitch_rate),
        max_yaw_rate_rad_s=np.full(n, max_yaw_rate),
        pitch_min_rad=np.full(n, math.radians(-20.0)),
        pitch_max_rad=np.full(n, math.radians(25.0)),
        ground_z_m=np.array(ground_z_m, dtype=np.float64),
        roll_limit_rad=np.full(n, math.radians(65.0)),
        heading_gain=np.full(n, heading_gain(5000.0)),
        climb_max_m_s=np.full(n, 5.0),
        sink_max_m_s=np.full(n, 5.0),
        l1_period_s=np.full(n, 15.0),
        l1_damping=np.full(n, 0.75),
        takeoff_climb_m_s=np.full(n, 10.0),
        rotate_speed_m_s=np.full(n, 19.0),
        speed_height_coupling=np.zeros(n),
        roll_lag_s=np.full(n, ROLL_LAG_PER_TCONST * 0.25),
        roll_damping=np.zeros(n),
        speed_omega_rad_s=np.ones(n),
        speed_damping=np.zeros(n),
        climb_lag_s=np.full(n, CLIMB_LAG_PER_TECS_TCONST * 5.0),
        height_gain_1_s=np.full(n, HEIGHT_GAIN_TIMES_TECS_TCONST / 5.0),
    )


def heading_gain(guided_p: float) -> float:
    """GUIDED_P (centidegrees of bank per radian of error) as radians per radian."""
    return guided_p * math.pi / 18000.0


@dataclass(slots=True)
class Guidance:
    """Commands of each vehicle's autopilot for the next steps, shape (N,) or (N, 3).

    ``direction`` is +1 for clockwise loiters (ArduPlane's positive radius), −1 for
    counter-clockwise. ``thrust`` is False for a disarmed or dead vehicle: it glides at v_min.
    ``course_rad`` and ``lateral_accel_m_s2`` are read in COURSE only.  ``alt_slew_m_s`` is
    GUIDED_CHANGE_ALTITUDE's param3: the altitude demand is kept within ± param3 ×
    ``GUIDED_ALT_UPDATE_S`` of the current altitude (∞: the target itself).  ``takeoff``
    is ArduPlane's takeoff stage: roll on the ground, lift off, climb at the takeoff rate.
    """

    kind: IntArray
    target_enu_m: FloatArray
    radius_m: FloatArray
    direction: FloatArray
    speed_cmd_m_s: FloatArray
    thrust: BoolArray
    course_rad: FloatArray
    lateral_accel_m_s2: FloatArray
    alt_slew_m_s: FloatArray
    takeoff: BoolArray


def initial_state(
    pos_enu_m: FloatArray,
    pitch_rad: FloatArray,
    yaw_rad: FloatArray,
    speed_m_s: FloatArray,
    landed: BoolArray | None = None,
) -> FleetState:
    """A fleet at the given state, wings level, holding its flight path (or on the ground,
    at rest, where ``landed``)."""
    n = int(np.asarray(speed_m_s).shape[0])
    on_ground = np.zeros(n, dtype=np.bool_) if landed is None else np.array(landed, dtype=bool)
    pos = np.array(pos_enu_m, dtype=np.float64).reshape(n, 3)
    speed = np.where(on_ground, 0.0, np.array(speed_m_s, dtype=np.float64))
    pitch = np.where(on_ground, 0.0, np.array(pitch_rad, dtype=np.float64))
    zeros = np.zeros(n)
    return FleetState(
        pos_enu_m=pos,
        pitch_rad=pitch,
        yaw_rad=np.array(yaw_rad, dtype=np.float64),
        speed_m_s=speed,
        roll_rad=zeros.copy(),
        climb_m_s=speed * np.sin(pitch),
        height_demand_m=pos[:, 2].copy(),
        pitch_rate_rad_s=zeros.copy(),
        yaw_rate_rad_s=zeros.copy(),
        accel_m_s2=zeros.copy(),
        landed=on_ground,
        roll_rate_rad_s=zeros.copy(),
    )


def hold_guidance(state: FleetState) -> Guidance:
    """Guidance that keeps every vehicle flying as it is (HOLD at its current speed)."""
    n = state.n
    return Guidance(
        kind=np.full(n, GuidanceKind.HOLD, dtype=np.int64),
        target_enu_m=state.pos_enu_m.copy(),
        radius_m=np.full(n, 60.0),
        direction=np.ones(n),
        speed_cmd_m_s=state.speed_m_s.copy(),
        thrust=np.ones(n, dtype=np.bool_),
        course_rad=state.yaw_rad.copy(),
        lateral_accel_m_s2=np.full(n, np.inf),
        alt_slew_m_s=np.full(n, np.inf),
        takeoff=np.zeros(n, dtype=np.bool_),
    )


def wrap_pi(angle: FloatArray) -> FloatArray:
    """Wrap angles to [−π, π)."""
    out: FloatArray = (angle + math.pi) % math.tau - math.pi
    return out


def min_turn_radius_m(speed_m_s: FloatArray, env: Envelope) -> FloatArray:
    """The tightest circle at this speed: the roll limit's v² / (g tan φ_max), or the
    airframe's turn rate limit v / ω_max, whichever is wider."""
    v = np.maximum(speed_m_s, MIN_TURN_SPEED_M_S)
    by_bank = v * v / (TURN_EFFICIENCY * GRAVITY_M_S2 * np.tan(np.minimum(env.roll_limit_rad, 1.5)))
    out: FloatArray = np.maximum(by_bank, v / env.max_yaw_rate_rad_s)
    return out


def effective_radius_m(radius_m: FloatArray, speed_m_s: FloatArray, env: Envelope) -> FloatArray:
    """Loiter radius actually flown: at least ORBIT_MARGIN × the tightest turn radius."""
    out: FloatArray = np.maximum(np.abs(radius_m), ORBIT_MARGIN * min_turn_radius_m(speed_m_s, env))
    return out


def commanded_course_rad(state: FleetState, env: Envelope, guid: Guidance) -> FloatArray:
    """Course (ENU yaw) each vehicle steers for in GOTO, ORBIT and COURSE, shape (N,)."""
    rel = guid.target_enu_m[:, :2] - state.pos_enu_m[:, :2]
    dist = np.hypot(rel[:, 0], rel[:, 1])
    goto = np.arctan2(rel[:, 1], rel[:, 0])
    r_eff = effective_radius_m(guid.radius_m, state.speed_m_s, env)
    gamma = np.arctan2(-rel[:, 1], -rel[:, 0])  # bearing centre → vehicle
    lam = -np.sign(guid.direction)  # ENU counter-clockwise is +1; ArduPlane +1 is clockwise
    lam = np.where(lam == 0.0, -1.0, lam)
    orbit = gamma + lam * (math.pi / 2 + np.arctan(2.0 * (dist - r_eff) / r_eff))
    course: FloatArray = np.where(
        guid.kind == GuidanceKind.ORBIT,
        orbit,
        np.where(guid.kind == GuidanceKind.COURSE, guid.course_rad, goto),
    )
    return course


def loiter_accel_left(
    state: FleetState, env: Envelope, guid: Guidance, v: FloatArray
) -> FloatArray:
    """Lateral acceleration (to the left) of a loiter, as ArduPlane's L1 loiter flies one:
    outside the circle it first heads for the centre (the L1 law on the angle between the
    velocity and the line to the centre), and once the circle's own demand — a PD on the
    radial error plus the centripetal v²/r — asks for the turn in the loiter's direction
    at least as hard, it flies the circle. (Adding the centripetal term from the start, as
    this model first did, flew a steady 11–25° off the bearing to a guided point.)"""
    omega = 2.0 * math.pi / env.l1_period_s
    away = state.pos_enu_m[:, :2] - guid.target_enu_m[:, :2]  # centre → vehicle
    dist = np.maximum(np.hypot(away[:, 0], away[:, 1]), 0.1)
    ux, uy = away[:, 0] / dist, away[:, 1] / dist
    vx, vy = v * np.cos(state.yaw_rad), v * np.sin(state.yaw_rad)
    inward = -(vx * ux + vy * uy)  # speed towards the centre
    sideways = -(ux * vy - uy * vx)  # speed across the line to the centre (clockwise +)
    to_centre = np.clip(np.arctan2(sideways, inward), -math.pi / 2, math.pi / 2)
    capture = 4.0 * math.pi * env.l1_damping * v * np.sin(to_centre) / env.l1_period_s
    r = effective_radius_m(guid.radius_m, state.speed_m_s, env)
    error = dist - r
    turn = np.where(guid.direction >= 0, 1.0, -1.0)  # +1 clockwise
    along = sideways * turn  # speed along the loiter's direction
    pd = error * omega**2 - inward * 2.0 * env.l1_damping * omega  # radial error and its rate
    pd = np.where((inward < 0) & (along < 0), np.maximum(pd, 0.0), pd)
    circle = turn * (pd + along * along / np.maximum(0.5 * r, r + error))
    capturing = (error > 0) & (turn * capture < turn * circle)
    out: FloatArray = -np.where(capturing, capture, circle)  # clockwise + → left −
    return out


def bank_demand_rad(state: FleetState, env: Envelope, guid: Guidance) -> FloatArray:
    """The bank each autopilot asks for (MAVLink sign: positive turns clockwise)."""
    kind = guid.kind
    v = np.maximum(state.speed_m_s, MIN_TURN_SPEED_M_S)
    error = wrap_pi(commanded_course_rad(state, env, guid) - state.yaw_rad)  # + = turn left
    # GUIDED heading: P-only, bank limited by the command's lateral acceleration.
    course_limit = np.minimum(np.arctan(guid.lateral_accel_m_s2 / GRAVITY_M_S2), env.roll_limit_rad)
    bank_course = np.clip(-env.heading_gain * error, -course_limit, course_limit)
    # L1 towards the desired course (sin η saturates beyond ±90°), plus a loiter's v²/r.
    eta = np.clip(error, -math.pi / 2, math.pi / 2)
    accel_left = 4.0 * math.pi * env.l1_damping * v * np.sin(eta) / env.l1_period_s
    orbit = loiter_accel_left(state, env, guid, v)
    accel_left = np.where(kind == GuidanceKind.ORBIT, orbit, accel_left)
    bank_nav = -np.arctan(accel_left / GRAVITY_M_S2)
    circle = np.sign(guid.direction) * np.arctan(
        v * v / (GRAVITY_M_S2 * np.maximum(np.abs(guid.radius_m), 1.0))
    )
    bank = np.where(
        kind == GuidanceKind.COURSE,
        bank_course,
        np.where(
            kind == GuidanceKind.TURN, circle, np.where(kind == GuidanceKind.HOLD, 0.0, bank_nav)
        ),
    )
    bank = np.where(guid.takeoff & state.landed, 0.0, bank)
    out: FloatArray = np.clip(bank, -env.roll_limit_rad, env.roll_limit_rad)
    return out


def climb_demand_m_s(
    state: FleetState, env: Envelope, guid: Guidance, dt: float
) -> tuple[FloatArray, FloatArray]:
    """TECS: the new height demand and the climb-rate demand, shape (N,) each."""
    z = state.pos_enu_m[:, 2]
    slew = guid.alt_slew_m_s * GUIDED_ALT_UPDATE_S
    demand = np.clip(guid.target_enu_m[:, 2], z - slew, z + slew)
    step_up, step_down = env.climb_max_m_s * dt, env.sink_max_m_s * dt
    height_demand = state.height_demand_m + np.clip(
        demand - state.height_demand_m, -step_down, step_up
    )
    climb = env.height_gain_1_s * (height_demand - z)
    climb = np.clip(climb, -env.sink_max_m_s, env.climb_max_m_s)
    climb = np.where(guid.takeoff, env.takeoff_climb_m_s, climb)
    held = (guid.kind == GuidanceKind.HOLD) & ~guid.takeoff
    climb = np.where(held, state.climb_m_s, climb)  # MANUAL, centred stick: pitch held
    return np.where(held | guid.takeoff, z, height_demand), climb


def step(state: FleetState, env: Envelope, guid: Guidance, dt: float) -> FleetState:
    """Advance the fleet by ``dt`` seconds (pure; returns a new state)."""
    v = state.speed_m_s
    airborne = ~state.landed

    # Lateral: bank follows the demand, the turn is what the bank gives.
    demand = bank_demand_rad(state, env, guid)
    omega = ROLL_OMEGA_TIMES_LAG / env.roll_lag_s
    zeta = env.roll_damping
    second_order = state.roll_rate_rad_s + dt * (
        omega * omega * (demand - state.roll_rad) - 2.0 * zeta * omega * state.roll_rate_rad_s
    )
    first_order = (demand - state.roll_rad) / env.roll_lag_s
    bank_rate = np.clip(
        np.where(zeta > 0.0, second_order, first_order), -ROLL_RATE_MAX_RAD_S, ROLL_RATE_MAX_RAD_S
    )
    bank_rate = np.where(airborne, bank_rate, 0.0)
    roll = np.where(airborne, state.roll_rad + bank_rate * dt, 0.0)
    yaw_rate = -TURN_EFFICIENCY * GRAVITY_M_S2 * np.tan(roll) / np.maximum(v, MIN_TURN_SPEED_M_S)
    yaw_rate = np.where(
        airborne, np.clip(yaw_rate, -env.max_yaw_rate_rad_s, env.max_yaw_rate_rad_s), 0.0
    )

    # Speed: its demand within the airframe's limits; the takeoff roll at full throttle.
    v_cmd = np.where(guid.thrust, guid.speed_cmd_m_s, env.v_min_m_s)
    v_cmd = np.where(guid.takeoff, TAKEOFF_SPEED_FACTOR * env.rotate_speed_m_s, v_cmd)
    v_cmd = np.clip(v_cmd, env.v_min_m_s, env.v_max_m_s)
    omega_v, zeta_v = env.speed_omega_rad_s, env.speed_damping
    second = state.accel_m_s2 + dt * (
        omega_v * omega_v * (v_cmd - v) - 2.0 * zeta_v * omega_v * state.accel_m_s2
    )
    first = (v_cmd - v) / TAU_SPEED_S
    accel = np.clip(np.where(zeta_v > 0.0, second, first), -env.decel_m_s2, env.accel_m_s2)
    rolling = state.landed & guid.takeoff & guid.thrust
    accel = np.where(rolling, GROUND_ACCEL_M_S2, np.where(airborne, accel, 0.0))
    speed = v + accel * dt
    speed = np.where(airborne, np.clip(speed, env.v_min_m_s, env.v_max_m_s), speed)
    lift_off = rolling & (speed >= env.rotate_speed_m_s)
    flying = airborne | lift_off

    # Vertical: TECS's climb demand (energy traded with speed), lagged, within pitch limits.
    height_demand, climb_cmd = climb_demand_m_s(state, env, guid, dt)
    climb_cmd = climb_cmd - env.speed_height_coupling * v * accel / GRAVITY_M_S2
    climb_max = np.where(guid.takeoff, env.takeoff_climb_m_s, env.climb_max_m_s)
    climb_cmd = np.clip(climb_cmd, -env.sink_max_m_s, climb_max)
    vs = np.maximum(speed, MIN_TURN_SPEED_M_S)
    climb_cmd = np.where(guid.thrust, climb_cmd, vs * math.sin(GLIDE_PITCH_RAD))
    climb_cmd = np.clip(climb_cmd, vs * np.sin(env.pitch_min_rad), vs * np.sin(env.pitch_max_rad))
    climb_rate_limit = vs * env.max_pitch_rate_rad_s  # the flight path turns no faster
    tau = np.where(guid.takeoff, TAU_TAKEOFF_CLIMB_S, env.climb_lag_s)
    climb_accel = np.clip((climb_cmd - state.climb_m_s) / tau, -climb_rate_limit, climb_rate_limit)
    climb = np.where(flying, state.climb_m_s + climb_accel * dt, 0.0)
    climb = np.clip(climb, -0.99 * vs, 0.99 * vs)
    pitch = np.where(flying, np.arcsin(climb / vs), 0.0)

    yaw = wrap_pi(state.yaw_rad + yaw_rate * dt)
    cp = np.cos(pitch)
    vel = np.stack((speed * cp * np.cos(yaw), speed * cp * np.sin(yaw), climb), axis=1)
    moving = flying | rolling
    pos = state.pos_enu_m + np.where(moving[:, None], vel, 0.0) * dt

    # Ground contact: a flying vehicle below its ground level stops there, landed.
    hit = flying & (pos[:, 2] < env.ground_z_m)
    landed = (state.landed & ~lift_off) | hit
    if hit.any():
        pos[:, 2] = np.where(hit, env.ground_z_m, pos[:, 2])
        speed = np.where(hit, 0.0, speed)
        climb = np.where(hit, 0.0, climb)
        pitch = np.where(hit, 0.0, pitch)
        roll = np.where(hit, 0.0, roll)
        yaw_rate = np.where(hit, 0.0, yaw_rate)
        accel = np.where(hit, 0.0, accel)
    return FleetState(
        pos_enu_m=pos,
        pitch_rad=pitch,
        yaw_rad=yaw,
        speed_m_s=speed,
        roll_rad=roll,
        climb_m_s=climb,
        height_demand_m=np.where(landed, pos[:, 2], height_demand),
        pitch_rate_rad_s=(pitch - state.pitch_rad) / dt,
        yaw_rate_rad_s=yaw_rate,
        accel_m_s2=accel,
        landed=landed,
        roll_rate_rad_s=np.where(hit, 0.0, bank_rate),
    )


def with_vehicle(state: FleetState, i: int, **changes: float) -> FleetState:
    """A copy of ``state`` with scalar fields of vehicle ``i`` changed (for resets and tests)."""
    fields = {}
    for name, value in changes.items():
        arr = np.array(getattr(state, name), copy=True)
        arr[i] = value
        fields[name] = arr
    return replace(state, **fields)

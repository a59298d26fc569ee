"""Fleet kinematics: the paper's Eq. 5 with turn-rate, pitch-rate, speed and acceleration
limits, and the guidance that a fixed-wing autopilot closes around it.

Everything is a structure of arrays over the fleet (N vehicles) and every function is pure:
``step`` takes the state, the envelope and the guidance commands and returns a new state.
Frames and units follow CONVENTIONS §1: ICS = local ENU metres, pitch θ positive nose up,
yaw ψ from +x (east) counter-clockwise, speeds m/s, rates rad/s.

Eq. 5::

    ẋ = v cos θ cos ψ     ẏ = v cos θ sin ψ     ż = v sin θ
    θ̇ ∈ [−ω_θ, ω_θ]       ψ̇ ∈ [−ω_ψ, ω_ψ]       v̇ ∈ [−decel, accel],  v ∈ [v_min, v_max]

Turning starts and stops instantly (assumption (2) of the paper, CONVENTIONS §2 erratum 5):
the commanded rate is clipped to ω_max and applied for the whole step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from enum import IntEnum

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

GRAVITY_M_S2 = 9.80665
#: Physics step of the SITL (50 Hz), seconds.
DT_S = 0.02

#: Heading-error gain of the course controller, 1/s (rate = gain × error, then clipped).
K_COURSE = 2.5
#: Flight-path gain: commanded climb angle is atan(K_ALT × altitude error / v), 1/s.
K_ALT = 0.5
#: Pitch-error gain, 1/s.
K_PITCH = 2.0
#: Speed-error gain, 1/s (then clipped to the acceleration limits).
K_SPEED = 1.0
#: Convergence gain of the loiter vector field (dimensionless, per loiter radius).
K_ORBIT = 2.0
#: A loiter circle is at least this factor times the tightest turn radius v / ω_max.
ORBIT_MARGIN = 1.15
#: Pitch held by a vehicle without thrust (disarmed or dead): a glide, radians.
GLIDE_PITCH_RAD = -0.1


class GuidanceKind(IntEnum):
    """What the guidance of one vehicle does during a step."""

    HOLD = 0
    """Neutral controls: pitch and yaw rates zero (MANUAL with centred sticks)."""
    GOTO = 1
    """Turn-rate-limited pursuit of ``target_enu_m`` (horizontal course), holding its altitude."""
    ORBIT = 2
    """Loiter on a circle of ``radius_m`` around ``target_enu_m`` (a vector field that first
    flies to the circle), holding the target's altitude."""
    TURN = 3
    """Constant-rate turn (ArduPlane CIRCLE mode), holding the target's altitude."""
    COURSE = 4
    """Hold the course ``course_rad`` (ArduPlane GUIDED after MAV_CMD_GUIDED_CHANGE_HEADING),
    turning no harder than ``lateral_accel_m_s2`` allows, holding the target's altitude."""


@dataclass(frozen=True, slots=True)
class FleetState:
    """Kinematic state of N vehicles. Arrays have shape (N, 3) for positions, (N,) otherwise."""

    pos_enu_m: FloatArray
    pitch_rad: FloatArray
    yaw_rad: FloatArray
    speed_m_s: FloatArray
    pitch_rate_rad_s: FloatArray
    yaw_rate_rad_s: FloatArray
    accel_m_s2: FloatArray
    landed: BoolArray

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

    def roll_rad(self) -> FloatArray:
        """Bank angle of a coordinated turn at the current yaw rate, NED sign (right wing down
        positive, i.e. a clockwise turn, ψ̇ < 0, banks right)."""
        roll: FloatArray = np.arctan(-self.speed_m_s * self.yaw_rate_rad_s / GRAVITY_M_S2)
        return np.clip(roll, -1.4, 1.4)


@dataclass(slots=True)
class Envelope:
    """Performance limits of each vehicle, shape (N,); mutable: parameters change them."""

    v_min_m_s: FloatArray
    v_max_m_s: FloatArray
    accel_m_s2: FloatArray
    decel_m_s2: FloatArray
    max_pitch_rate_rad_s: FloatArray
    max_yaw_rate_rad_s: FloatArray
    pitch_min_rad: FloatArray
    pitch_max_rad: FloatArray
    ground_z_m: FloatArray


@dataclass(slots=True)
class Guidance:
    """Commands of each vehicle's autopilot for the next steps, shape (N,) or (N, 3).

    ``direction`` is +1 for clockwise loiters (ArduPlane's positive radius), −1 for
    counter-clockwise. ``thrust`` is False for a disarmed or dead vehicle: it glides at v_min.
    ``course_rad`` and ``lateral_accel_m_s2`` are read in COURSE only; ``climb_rate_m_s``
    caps the vertical speed at which the altitude of ``target_enu_m`` is approached (∞: as
    fast as the flight-path gain and the pitch limits allow).
    """

    kind: IntArray
    target_enu_m: FloatArray
    radius_m: FloatArray
    direction: FloatArray
    speed_cmd_m_s: FloatArray
    thrust: BoolArray
    course_rad: FloatArray
    lateral_accel_m_s2: FloatArray
    climb_rate_m_s: FloatArray


def initial_state(
    pos_enu_m: FloatArray, pitch_rad: FloatArray, yaw_rad: FloatArray, speed_m_s: FloatArray
) -> FleetState:
    """A fleet in flight at the given state, all rates zero."""
    n = int(speed_m_s.shape[0])
    zeros = np.zeros(n)
    return FleetState(
        pos_enu_m=np.array(pos_enu_m, dtype=np.float64).reshape(n, 3),
        pitch_rad=np.array(pitch_rad, dtype=np.float64),
        yaw_rad=np.array(yaw_rad, dtype=np.float64),
        speed_m_s=np.array(speed_m_s, dtype=np.float64),
        pitch_rate_rad_s=zeros.copy(),
        yaw_rate_rad_s=zeros.copy(),
        accel_m_s2=zeros.copy(),
        landed=np.zeros(n, dtype=np.bool_),
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
        climb_rate_m_s=np.full(n, np.inf),
    )


def wrap_pi(angle: FloatArray) -> FloatArray:
    """Wrap angles to [−π, π)."""
    out: FloatArray = (angle + math.pi) % math.tau - math.pi
    return out


def effective_radius_m(
    radius_m: FloatArray, speed_m_s: FloatArray, max_yaw_rate: FloatArray
) -> FloatArray:
    """Loiter radius actually flown: at least ORBIT_MARGIN × v / ω_max (the tightest circle
    the vehicle can hold at its speed)."""
    out: FloatArray = np.maximum(np.abs(radius_m), ORBIT_MARGIN * speed_m_s / max_yaw_rate)
    return out


def commanded_course_rad(state: FleetState, env: Envelope, guid: Guidance) -> FloatArray:
    """Course (ENU yaw) each vehicle steers for in GOTO and ORBIT, shape (N,)."""
    rel = guid.target_enu_m[:, :2] - state.pos_enu_m[:, :2]
    dist = np.hypot(rel[:, 0], rel[:, 1])
    goto = np.arctan2(rel[:, 1], rel[:, 0])
    r_eff = effective_radius_m(guid.radius_m, state.speed_m_s, env.max_yaw_rate_rad_s)
    gamma = np.arctan2(-rel[:, 1], -rel[:, 0])  # bearing centre → vehicle
    lam = -np.sign(guid.direction)  # ENU counter-clockwise is +1; ArduPlane +1 is clockwise
    lam = np.where(lam == 0.0, -1.0, lam)
    orbit = gamma + lam * (math.pi / 2 + np.arctan(K_ORBIT * (dist - r_eff) / r_eff))
    course: FloatArray = np.where(
        guid.kind == GuidanceKind.ORBIT,
        orbit,
        np.where(guid.kind == GuidanceKind.COURSE, guid.course_rad, goto),
    )
    return course


def step(state: FleetState, env: Envelope, guid: Guidance, dt: float) -> FleetState:
    """Advance the fleet by ``dt`` seconds (pure; returns a new state)."""
    kind = guid.kind
    v = state.speed_m_s
    w_yaw = env.max_yaw_rate_rad_s
    w_pitch = env.max_pitch_rate_rad_s

    # Lateral: yaw rate.
    course = commanded_course_rad(state, env, guid)
    pursuit_rate = K_COURSE * wrap_pi(course - state.yaw_rad)
    turn_rate = -np.sign(guid.direction) * v / np.maximum(np.abs(guid.radius_m), 1.0)
    yaw_rate_cmd = np.where(
        kind == GuidanceKind.HOLD,
        0.0,
        np.where(kind == GuidanceKind.TURN, turn_rate, pursuit_rate),
    )
    # A course command turns no harder than its lateral acceleration (bank) limit allows.
    w_turn = np.where(
        kind == GuidanceKind.COURSE,
        np.minimum(w_yaw, guid.lateral_accel_m_s2 / np.maximum(v, 1.0)),
        w_yaw,
    )
    yaw_rate = np.clip(yaw_rate_cmd, -w_turn, w_turn)

    # Longitudinal: pitch rate from the altitude error (not in HOLD), glide without thrust.
    # A climb-rate limit caps the error the gain sees, so the vertical speed K_ALT × error
    # never exceeds it (ArduPlane's altitude slew: TECS demands at most that height rate).
    reach = guid.climb_rate_m_s / K_ALT
    dz = np.clip(guid.target_enu_m[:, 2] - state.pos_enu_m[:, 2], -reach, reach)
    gamma_cmd = np.arctan2(K_ALT * dz, np.maximum(v, 1.0))
    gamma_cmd = np.where(guid.thrust, gamma_cmd, np.minimum(gamma_cmd, GLIDE_PITCH_RAD))
    gamma_cmd = np.clip(gamma_cmd, env.pitch_min_rad, env.pitch_max_rad)
    pitch_rate_cmd = K_PITCH * (gamma_cmd - state.pitch_rad)
    hold_pitch = (kind == GuidanceKind.HOLD) & guid.thrust
    pitch_rate = np.clip(np.where(hold_pitch, 0.0, pitch_rate_cmd), -w_pitch, w_pitch)

    # Speed.
    v_cmd = np.where(guid.thrust, guid.speed_cmd_m_s, env.v_min_m_s)
    v_cmd = np.clip(v_cmd, env.v_min_m_s, env.v_max_m_s)
    accel = np.clip(K_SPEED * (v_cmd - v), -env.decel_m_s2, env.accel_m_s2)

    pitch = np.clip(state.pitch_rad + pitch_rate * dt, -math.pi / 2, math.pi / 2)
    yaw = wrap_pi(state.yaw_rad + yaw_rate * dt)
    speed = np.clip(v + accel * dt, env.v_min_m_s, env.v_max_m_s)
    cp = np.cos(pitch)
    vel = np.stack(
        (speed * cp * np.cos(yaw), speed * cp * np.sin(yaw), speed * np.sin(pitch)), axis=1
    )
    pos = state.pos_enu_m + vel * dt

    # Ground contact: a vehicle below its ground level stops there, landed.
    landed = state.landed | (pos[:, 2] < env.ground_z_m)
    if landed.any():
        keep = landed[:, None]
        pos = np.where(
            keep, np.stack((pos[:, 0], pos[:, 1], np.maximum(pos[:, 2], env.ground_z_m)), 1), pos
        )
        pos = np.where(state.landed[:, None], state.pos_enu_m, pos)
        pitch = np.where(landed, 0.0, pitch)
        yaw = np.where(state.landed, state.yaw_rad, yaw)
        speed = np.where(landed, 0.0, speed)
        pitch_rate = np.where(landed, 0.0, pitch_rate)
        yaw_rate = np.where(landed, 0.0, yaw_rate)
        accel = np.where(landed, 0.0, accel)
    return FleetState(
        pos_enu_m=pos,
        pitch_rad=pitch,
        yaw_rad=yaw,
        speed_m_s=speed,
        pitch_rate_rad_s=pitch_rate,
        yaw_rate_rad_s=yaw_rate,
        accel_m_s2=accel,
        landed=landed,
    )


def with_vehicle(state: FleetState, i: int, **changes: float) -> FleetState:
    """A copy of ``state`` with scalar fields of vehicle ``i`` changed (for resets and tests)."""
    fields = {}
    for name, value in changes.items():
        arr = np.array(getattr(state, name), copy=True)
        arr[i] = value
        fields[name] = arr
    return replace(state, **fields)

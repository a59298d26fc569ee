"""The fleet's physics step compiled (numba): ``sitl.physics.step_reference`` vehicle by vehicle.

``step_reference`` says what the model is, in numpy over the fleet; on five vehicles its
~200 numpy calls a step on 5-element arrays cost ~0.5 ms, a third of the SITL's CPU at ×10
(py-spy).  This kernel does the same arithmetic in the same order on scalars, one vehicle
at a time, in a few microseconds: every expression below is the numpy one it stands for
(``np.clip`` is ``min(max(x, lo), hi)``, ``np.where`` an ``if``), so the two agree to the
last bit wherever numpy's transcendental functions are the C library's (x86-64 without
AVX-512) and within an ulp elsewhere (``tests/sitl/test_sitl_physics.py`` holds them
together).  No fast-math: the order of operations is kept.

``python -m sitl.compiled`` builds it into numba's cache (``make install``), so that no SITL
waits for the compiler at its first step.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from typing import Any, TypeVar, cast

import numpy as np
from numba import njit

from gcs_ppf.mavlink.ardupilot import ROLL_RATE_MAX_RAD_S, TURN_EFFICIENCY

# The constants of sitl.physics (imported there from here would be circular: physics
# imports this module; test_sitl_physics checks that they are the same).
GRAVITY_M_S2 = 9.80665
TAU_TAKEOFF_CLIMB_S = 0.4
TAU_SPEED_S = 1.0
GUIDED_ALT_UPDATE_S = 0.1
TAKEOFF_SPEED_FACTOR = 1.4
GROUND_ACCEL_M_S2 = 6.0
ORBIT_MARGIN = 1.15
GLIDE_PITCH_RAD = -0.1
MIN_TURN_SPEED_M_S = 1.0
# GuidanceKind
HOLD, GOTO, ORBIT, TURN, COURSE = 0, 1, 2, 3, 4

_HALF_PI = math.pi / 2
_FOUR_PI = 4.0 * math.pi
_TWO_PI = 2.0 * math.pi
_SIN_GLIDE = math.sin(GLIDE_PITCH_RAD)
_TURN_G = TURN_EFFICIENCY * GRAVITY_M_S2
_NEG_TURN_G = -TURN_EFFICIENCY * GRAVITY_M_S2

F = TypeVar("F", bound=Callable[..., Any])


def _jit(function: F) -> F:
    """``njit(cache=True)`` with IEEE division (a zero divisor gives inf or NaN, as numpy's
    arrays do, instead of raising)."""
    return cast(F, njit(cache=True, error_model="numpy")(function))


@_jit
def _max(a: float, b: float) -> float:
    """np.maximum: NaN if either is."""
    return a if (a >= b or a != a) else b


@_jit
def _min(a: float, b: float) -> float:
    """np.minimum: NaN if either is."""
    return a if (a <= b or a != a) else b


@_jit
def _clip(x: float, lo: float, hi: float) -> float:
    """np.clip: minimum(maximum(x, lo), hi)."""
    return _min(_max(x, lo), hi)


@_jit
def _sign(x: float) -> float:
    """np.sign."""
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    return x  # ±0 or NaN, as np.sign


@_jit
def _wrap_pi(angle: float) -> float:
    """physics.wrap_pi (Python's and numpy's floor modulo agree)."""
    return (angle + math.pi) % math.tau - math.pi


@_jit
def _effective_radius(radius: float, speed: float, roll_limit: float, max_yaw_rate: float) -> float:
    """physics.effective_radius_m of one vehicle."""
    v = _max(speed, MIN_TURN_SPEED_M_S)
    by_bank = v * v / (_TURN_G * math.tan(_min(roll_limit, 1.5)))
    tightest = _max(by_bank, v / max_yaw_rate)
    return _max(abs(radius), ORBIT_MARGIN * tightest)


@_jit
def step_fleet(
    pos: np.ndarray,
    pitch: np.ndarray,
    yaw: np.ndarray,
    speed: np.ndarray,
    roll: np.ndarray,
    climb: np.ndarray,
    height_demand: np.ndarray,
    landed: np.ndarray,
    v_min: np.ndarray,
    v_max: np.ndarray,
    accel_max: np.ndarray,
    decel_max: np.ndarray,
    max_pitch_rate: np.ndarray,
    max_yaw_rate: np.ndarray,
    pitch_min: np.ndarray,
    pitch_max: np.ndarray,
    ground_z: np.ndarray,
    roll_limit: np.ndarray,
    heading_gain: np.ndarray,
    climb_max: np.ndarray,
    sink_max: np.ndarray,
    l1_period: np.ndarray,
    l1_damping: np.ndarray,
    takeoff_climb: np.ndarray,
    rotate_speed: np.ndarray,
    speed_height_coupling: np.ndarray,
    roll_lag: np.ndarray,
    climb_lag: np.ndarray,
    height_gain: np.ndarray,
    kind: np.ndarray,
    target: np.ndarray,
    radius: np.ndarray,
    direction: np.ndarray,
    speed_cmd: np.ndarray,
    thrust: np.ndarray,
    course_cmd: np.ndarray,
    lateral_accel: np.ndarray,
    alt_slew: np.ndarray,
    takeoff: np.ndarray,
    dt: float,
) -> tuple[np.ndarray, ...]:
    """``physics.step_reference`` on the fleet's arrays (state, envelope, guidance): the new
    (pos, pitch, yaw, speed, roll, climb, height_demand, pitch_rate, yaw_rate, accel,
    landed)."""
    n = speed.shape[0]
    o_pos = np.empty((n, 3))
    o_pitch = np.empty(n)
    o_yaw = np.empty(n)
    o_speed = np.empty(n)
    o_roll = np.empty(n)
    o_climb = np.empty(n)
    o_hd = np.empty(n)
    o_pitch_rate = np.empty(n)
    o_yaw_rate = np.empty(n)
    o_accel = np.empty(n)
    o_landed = np.empty(n, dtype=np.bool_)
    for i in range(n):
        v = speed[i]
        on_ground = landed[i]
        airborne = not on_ground
        k = kind[i]
        px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
        tx, ty, tz = target[i, 0], target[i, 1], target[i, 2]
        to = takeoff[i]
        th = thrust[i]

        # ---- bank_demand_rad (an ORBIT's commanded course is not used: its loiter is) --
        vv = _max(v, MIN_TURN_SPEED_M_S)
        if k == COURSE:
            error = _wrap_pi(course_cmd[i] - yaw[i])  # + = turn left
            course_limit = _min(math.atan(lateral_accel[i] / GRAVITY_M_S2), roll_limit[i])
            bank = _clip(-heading_gain[i] * error, -course_limit, course_limit)
        elif k == TURN:
            bank = _sign(direction[i]) * math.atan(
                vv * vv / (GRAVITY_M_S2 * _max(abs(radius[i]), 1.0))
            )
        elif k == HOLD:
            bank = 0.0
        elif k == ORBIT:  # loiter_accel_left
            r_eff = _effective_radius(radius[i], v, roll_limit[i], max_yaw_rate[i])
            period, damping = l1_period[i], l1_damping[i]
            omega = _TWO_PI / period
            awx, awy = px - tx, py - ty
            d = _max(math.hypot(awx, awy), 0.1)
            ux, uy = awx / d, awy / d
            vx, vy = vv * math.cos(yaw[i]), vv * math.sin(yaw[i])
            inward = -(vx * ux + vy * uy)
            sideways = -(ux * vy - uy * vx)
            to_centre = _clip(math.atan2(sideways, inward), -_HALF_PI, _HALF_PI)
            capture = _FOUR_PI * damping * vv * math.sin(to_centre) / period
            err = d - r_eff
            turn = 1.0 if direction[i] >= 0 else -1.0
            along = sideways * turn
            pd = err * (omega * omega) - inward * 2.0 * damping * omega
            if inward < 0 and along < 0:
                pd = _max(pd, 0.0)
            circle = turn * (pd + along * along / _max(0.5 * r_eff, r_eff + err))
            capturing = err > 0 and turn * capture < turn * circle
            bank = -math.atan(-(capture if capturing else circle) / GRAVITY_M_S2)
        else:  # GOTO: L1 towards the point (sin η saturates beyond ±90°)
            error = _wrap_pi(math.atan2(ty - py, tx - px) - yaw[i])
            eta = _clip(error, -_HALF_PI, _HALF_PI)
            accel_left = _FOUR_PI * l1_damping[i] * vv * math.sin(eta) / l1_period[i]
            bank = -math.atan(accel_left / GRAVITY_M_S2)
        if to and on_ground:
            bank = 0.0
        bank = _clip(bank, -roll_limit[i], roll_limit[i])

        # ---- lateral -----------------------------------------------------------------
        bank_rate = _clip((bank - roll[i]) / roll_lag[i], -ROLL_RATE_MAX_RAD_S, ROLL_RATE_MAX_RAD_S)
        new_roll = roll[i] + bank_rate * dt if airborne else 0.0
        yaw_rate = _NEG_TURN_G * math.tan(new_roll) / _max(v, MIN_TURN_SPEED_M_S)
        if airborne:
            yaw_rate = _clip(yaw_rate, -max_yaw_rate[i], max_yaw_rate[i])
        else:
            yaw_rate = 0.0

        # ---- speed -------------------------------------------------------------------
        v_cmd = speed_cmd[i] if th else v_min[i]
        if to:
            v_cmd = TAKEOFF_SPEED_FACTOR * rotate_speed[i]
        v_cmd = _clip(v_cmd, v_min[i], v_max[i])
        accel = _clip((v_cmd - v) / TAU_SPEED_S, -decel_max[i], accel_max[i])
        rolling = on_ground and to and th
        if rolling:
            accel = GROUND_ACCEL_M_S2
        elif not airborne:
            accel = 0.0
        new_speed = v + accel * dt
        if airborne:
            new_speed = _clip(new_speed, v_min[i], v_max[i])
        lift_off = rolling and new_speed >= rotate_speed[i]
        flying = airborne or lift_off

        # ---- climb_demand_m_s --------------------------------------------------------
        slew = alt_slew[i] * GUIDED_ALT_UPDATE_S
        demand = _clip(tz, pz - slew, pz + slew)
        step_up, step_down = climb_max[i] * dt, sink_max[i] * dt
        hd = height_demand[i] + _clip(demand - height_demand[i], -step_down, step_up)
        climb_cmd = height_gain[i] * (hd - pz)
        climb_cmd = _clip(climb_cmd, -sink_max[i], climb_max[i])
        if to:
            climb_cmd = takeoff_climb[i]
        held = k == HOLD and not to
        if held:
            climb_cmd = climb[i]
        if held or to:
            hd = pz

        # ---- vertical ----------------------------------------------------------------
        climb_cmd = climb_cmd - speed_height_coupling[i] * v * accel / GRAVITY_M_S2
        top = takeoff_climb[i] if to else climb_max[i]
        climb_cmd = _clip(climb_cmd, -sink_max[i], top)
        vs = _max(new_speed, MIN_TURN_SPEED_M_S)
        if not th:
            climb_cmd = vs * _SIN_GLIDE
        climb_cmd = _clip(climb_cmd, vs * math.sin(pitch_min[i]), vs * math.sin(pitch_max[i]))
        climb_rate_limit = vs * max_pitch_rate[i]
        tau = TAU_TAKEOFF_CLIMB_S if to else climb_lag[i]
        climb_accel = _clip((climb_cmd - climb[i]) / tau, -climb_rate_limit, climb_rate_limit)
        new_climb = climb[i] + climb_accel * dt if flying else 0.0
        new_climb = _clip(new_climb, -0.99 * vs, 0.99 * vs)
        new_pitch = math.asin(new_climb / vs) if flying else 0.0

        new_yaw = _wrap_pi(yaw[i] + yaw_rate * dt)
        cp = math.cos(new_pitch)
        if flying or rolling:
            ve = new_speed * cp * math.cos(new_yaw)
            vn = new_speed * cp * math.sin(new_yaw)
            vu = new_climb
        else:
            ve = vn = vu = 0.0
        qx, qy, qz = px + ve * dt, py + vn * dt, pz + vu * dt

        # ---- ground contact ----------------------------------------------------------
        hit = flying and qz < ground_z[i]
        now_landed = (on_ground and not lift_off) or hit
        if hit:
            qz = ground_z[i]
            new_speed = 0.0
            new_climb = 0.0
            new_pitch = 0.0
            new_roll = 0.0
            yaw_rate = 0.0
            accel = 0.0
        o_pos[i, 0], o_pos[i, 1], o_pos[i, 2] = qx, qy, qz
        o_pitch[i] = new_pitch
        o_yaw[i] = new_yaw
        o_speed[i] = new_speed
        o_roll[i] = new_roll
        o_climb[i] = new_climb
        o_hd[i] = qz if now_landed else hd
        o_pitch_rate[i] = (new_pitch - pitch[i]) / dt
        o_yaw_rate[i] = yaw_rate
        o_accel[i] = accel
        o_landed[i] = now_landed
    return (
        o_pos,
        o_pitch,
        o_yaw,
        o_speed,
        o_roll,
        o_climb,
        o_hd,
        o_pitch_rate,
        o_yaw_rate,
        o_accel,
        o_landed,
    )


def main() -> int:
    """Compile the step for the fleet arrays the SITL passes (numba's cache)."""
    from sitl.physics import default_envelope, hold_guidance, initial_state, step

    started = time.perf_counter()
    state = initial_state(np.zeros((1, 3)), np.zeros(1), np.zeros(1), np.ones(1))
    env = default_envelope(
        1, v_min=1.0, v_max=2.0, accel=1.0, decel=1.0, max_pitch_rate=1.0, max_yaw_rate=1.0,
        ground_z_m=np.zeros(1),
    )  # fmt: skip
    step(state, env, hold_guidance(state), 0.02)
    print(f"sitl: physics kernel ready in numba's cache ({time.perf_counter() - started:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

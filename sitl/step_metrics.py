"""Step-response metrics of a Response (rise times, overshoot, peak bank, settling, lag),
the same functions for a recording and for its replay on the built-in SITL."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from sitl.recordings import FloatArray, Response


def _first(t: FloatArray, mask: NDArray[np.bool_]) -> float:
    idx = np.flatnonzero(mask)
    return float(t[idx[0]]) if idx.size else math.nan


def _settled(t: FloatArray, ok: NDArray[np.bool_]) -> float:
    """The first time after which ``ok`` holds to the end."""
    bad = np.flatnonzero(~ok)
    if bad.size == 0:
        return float(t[0])
    return float(t[bad[-1] + 1]) if bad[-1] + 1 < t.size else math.nan


def heading_metrics(r: Response, delta_deg: float) -> dict[str, float]:
    """A course step of ``delta_deg`` (+ right, − left; ±180: either way, the way it turned),
    measured along the turn."""
    d = r.course_deg - r.course_deg[0]
    if abs(abs(delta_deg) - 180.0) < 1e-9:  # a reversal: the way it went
        delta_deg = math.copysign(180.0, d[-1])
    d = d * math.copysign(1.0, delta_deg)
    delta_deg = abs(delta_deg)
    turn = np.gradient(r.course_deg, r.t)
    return {
        "t_10pct_s": _first(r.t, d >= 0.1 * delta_deg),
        "t_90pct_s": _first(r.t, d >= 0.9 * delta_deg),
        "t_within_2deg_s": _settled(r.t, np.abs(d - delta_deg) < 2.0),
        "peak_roll_deg": float(np.max(np.abs(r.roll_deg))),
        "course_change_3s_deg": float(np.interp(3.0, r.t, d)),
        # Reported, not compared: at roll-in ArduPlane's course rate swings 30 → 8 → 20°/s
        # within a second (sideslip), which a model without yaw dynamics does not have.
        "max_turn_rate_dps": float(np.max(np.abs(turn))),
        "overshoot_deg": float(np.max(d) - delta_deg),
        "alt_excursion_m": float(np.max(np.abs(r.rel_alt_m - r.rel_alt_m[0]))),
    }


def altitude_metrics(r: Response, delta_m: float) -> dict[str, float]:
    d = r.rel_alt_m - r.rel_alt_m[0]
    t10, t90 = _first(r.t, d >= 0.1 * delta_m), _first(r.t, d >= 0.9 * delta_m)
    return {
        "t_10pct_s": t10,
        "t_90pct_s": t90,
        "mean_climb_10_90_m_s": 0.8 * delta_m / (t90 - t10) if t90 > t10 else math.nan,
        "peak_climb_m_s": float(np.max(r.climb_m_s)),
        "overshoot_m": float(np.max(d) - delta_m),
        "change_at_end_m": float(d[-1]),
    }


def airspeed_metrics(r: Response, target: float) -> dict[str, float]:
    v0 = r.airspeed_m_s[0]
    frac = (r.airspeed_m_s - v0) / (target - v0)
    d = r.rel_alt_m - r.rel_alt_m[0]
    return {
        "t_10pct_s": _first(r.t, frac >= 0.1),
        "t_90pct_s": _first(r.t, frac >= 0.9),
        "overshoot_m_s": float(np.max((r.airspeed_m_s - target) * np.sign(target - v0))),
        "alt_excursion_max_m": float(np.max(d)),
        "alt_excursion_min_m": float(np.min(d)),
    }


def reposition_metrics(r: Response, east: float, north: float) -> dict[str, float]:
    dist = np.hypot(r.east_m - east, r.north_m - north)
    bearing = math.degrees(math.atan2(east, north))
    change = (bearing - r.course_deg[0] + 180.0) % 360.0 - 180.0
    turned = (r.course_deg - r.course_deg[0]) / change
    tail = r.t >= r.t[-1] - 15.0
    return {
        "t_course_80pct_s": _first(r.t, turned >= 0.8),
        "peak_roll_deg": float(np.max(np.abs(r.roll_deg))),
        "t_within_100m_s": _first(r.t, dist <= 100.0),
        "loiter_radius_m": float(np.mean(dist[tail])),
        "loiter_roll_deg": float(np.mean(np.abs(r.roll_deg[tail]))),
    }


def ramp_metrics(r: Response) -> dict[str, float]:
    """How far the course lags a command that keeps turning (steady state: the last half of
    the ramp), the bank that turn takes, and the settling after the last command. The lag
    is against the courses as they were commanded (``r.commanded_course_deg``)."""
    if r.commanded_course_deg is None:
        raise ValueError("a ramp's response needs the courses commanded")
    moving = np.flatnonzero(np.diff(r.commanded_course_deg) != 0.0)
    ramp_s = float(r.t[moving[-1] + 1])
    lag = r.commanded_course_deg - r.course_deg
    steady = (r.t >= ramp_s / 2) & (r.t <= ramp_s)
    after = r.t >= ramp_s
    return {
        "steady_lag_deg": float(np.mean(lag[steady])),
        "steady_roll_deg": float(np.mean(np.abs(r.roll_deg[steady]))),
        "t_lag_within_2deg_after_s": _settled(r.t[after], np.abs(lag[after]) < 2.0) - ramp_s,
        "alt_excursion_m": float(np.max(np.abs(r.rel_alt_m - r.rel_alt_m[0]))),
    }


def speed_ramp_metrics(r: Response) -> dict[str, float]:
    """How far the airspeed lags a commanded slowing and speeding up (the mean over each
    ramp's second half, m/s, positive: behind), how long after the slowing it comes within
    0.5 m/s of the command, and how far and when it overshoots after speeding up (ArduPlane
    overshoots by more than 0.5 m/s, so a settling time in that band would only say
    whether the overshoot crosses it)."""
    cmd = r.commanded_airspeed_m_s
    if cmd is None:
        raise ValueError("a speed ramp's response needs the airspeeds commanded")
    changing = np.flatnonzero(np.diff(cmd) != 0.0) + 1
    low = cmd.min()
    down_end = float(r.t[np.flatnonzero(cmd <= low)[0]])
    up_start = float(r.t[np.flatnonzero((r.t > down_end) & (cmd > low))[0]])
    up_end = float(r.t[changing[-1]])
    behind = (r.airspeed_m_s - cmd) * np.where(r.t < up_start, 1.0, -1.0)
    down = (r.t >= down_end / 2) & (r.t <= down_end)
    up = (r.t >= (up_start + up_end) / 2) & (r.t <= up_end)
    close = np.abs(r.airspeed_m_s - cmd) <= 0.5
    held, after = (r.t >= down_end) & (r.t < up_start), r.t >= up_end
    return {
        "lag_slowing_m_s": float(np.mean(behind[down])),
        "lag_speeding_m_s": float(np.mean(behind[up])),
        "t_within_0_5_after_slowing_s": _settled(r.t[held], close[held]) - down_end,
        "overshoot_m_s": float(np.max(r.airspeed_m_s[after] - cmd[after])),
        "t_overshoot_s": float(r.t[after][np.argmax(r.airspeed_m_s[after])]) - up_end,
        "alt_excursion_m": float(np.max(np.abs(r.rel_alt_m - r.rel_alt_m[0]))),
    }


def takeoff_metrics(r: Response) -> dict[str, float]:
    return {
        "t_liftoff_s": _first(r.t, r.rel_alt_m > 1.0),
        "t_95m_s": _first(r.t, r.rel_alt_m >= 95.0),
        "max_climb_m_s": float(np.max(r.climb_m_s)),
        "max_alt_m": float(np.max(r.rel_alt_m)),
        "final_alt_m": float(r.rel_alt_m[-1]),
    }

"""How a vehicle answers a command, predicted: its state and limits (``Motion``), what it is
told (``Command``), and where that takes it (``hold_path``, ``advance``, ``track``) — the
typed front of the compiled ``prediction``, for the run-time assurance
(``gcs_ppf.guidance.assurance``) and the holds (``gcs_ppf.guidance.holding``).

Pure.  The prediction is ArduPlane's response as the built-in SITL is calibrated to it
(``sitl/calibration.py``, ``gcs_ppf.mavlink.ardupilot``): the turn is what the bank gives,
the bank follows GUIDED's P-only demand (the course error over the heading time constant,
at most the airframe's turn rate) with the roll loop's lag and rate limit, from the bank the
vehicle flies now (a vehicle turning hard one way first rolls out: at 100 m/s, 1.5 s and
150 m the other way, measured on a lossy link under load); the vertical speed follows
TECS's demand (the height error × its gain, within the climb and sink limits) with its
lag, from the vertical speed the vehicle flies now (a vehicle diving at 125 m/s does not
level off at once); the speed held.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from gcs_ppf.guidance import prediction
from gcs_ppf.guidance.airframe import G_M_S2
from gcs_ppf.mavlink.ardupilot import TURN_EFFICIENCY
from gcs_ppf.planning.scene import FloatArray

SIDE_DEADBAND_RAD = math.radians(10.0)
"""A course this close to the vehicle's yaw turns neither way (no reversal to reach it)."""


@dataclass(frozen=True, slots=True)
class Command:
    """What a vehicle is told: a course (ICS yaw, rad) and an altitude (ICS z, m)."""

    course_rad: float
    z_m: float


@dataclass(frozen=True, slots=True)
class Motion:
    """How a vehicle answers a command: its state now and its airframe's limits."""

    pos_m: tuple[float, float, float]
    yaw_rad: float
    speed_m_s: float
    turn_rate_rad_s: float
    """Steepest turn (rad/s) at its speed: the bank limit, and the mission's yaw rate."""
    climb_m_s: float
    sink_m_s: float
    heading_tau_s: float = 1.0
    """First-order time constant of the course (ArduPlane's GUIDED P-controller)."""
    yaw_rate_rad_s: float = 0.0
    """How fast it turns now (+: left), i.e. the bank it flies: a turn the other way first
    rolls out of it."""
    roll_lag_s: float = 0.0
    """The bank's first-order lag behind its demand (ArduPlane: ``ROLL_LAG_PER_TCONST`` ×
    RLL2SRV_TCONST); 0: the bank is where it is asked at once."""
    roll_rate_rad_s: float = math.inf
    """The fastest roll (rad/s)."""
    climb_rate_m_s: float = 0.0
    """Its vertical speed now (m/s, + up)."""
    climb_lag_s: float = 0.0
    """The vertical speed's first-order lag behind TECS's demand (ArduPlane:
    ``CLIMB_LAG_PER_TECS_TCONST`` × TECS_TIME_CONST); 0: at once."""
    height_gain_1_s: float = math.inf
    """TECS's climb-rate demand per metre of height error (1/s); inf: the limits at once."""

    def bank_for(self, yaw_rate_rad_s: float) -> float:
        """The bank (rad, + left) that turns at ``yaw_rate_rad_s``."""
        v = max(self.speed_m_s, 1e-6)
        return math.atan(yaw_rate_rad_s * v / (TURN_EFFICIENCY * G_M_S2))

    def velocity(self, yaw_rad: float | None = None) -> FloatArray:
        """Its level velocity (m/s, ICS) along ``yaw_rad`` (default: its yaw now)."""
        yaw = self.yaw_rad if yaw_rad is None else yaw_rad
        return self.speed_m_s * np.array([math.cos(yaw), math.sin(yaw), 0.0])

    def yaw_rate_for(self, bank_rad: float) -> float:
        """The turn (rad/s, + left) that ``bank_rad`` gives."""
        return TURN_EFFICIENCY * G_M_S2 * math.tan(bank_rad) / max(self.speed_m_s, 1e-6)


def wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def turn_side(m: Motion, course_rad: float) -> int:
    """The way a course turns the vehicle (ArduPlane turns the shorter way): +1 left, −1
    right, 0 for a course within ``SIDE_DEADBAND_RAD`` of its yaw."""
    error = wrap(course_rad - m.yaw_rad)
    return 0 if abs(error) < SIDE_DEADBAND_RAD else (1 if error > 0.0 else -1)


def motion_vector(m: Motion) -> FloatArray:
    """``m`` as ``prediction``'s vector."""
    return np.array(
        [
            *m.pos_m,
            m.yaw_rad,
            m.speed_m_s,
            m.turn_rate_rad_s,
            m.climb_m_s,
            m.sink_m_s,
            m.heading_tau_s,
            m.yaw_rate_rad_s,
            m.roll_lag_s,
            m.roll_rate_rad_s,
            m.climb_rate_m_s,
            m.climb_lag_s,
            m.height_gain_1_s,
        ],
        dtype=np.float64,
    )


def hold_path(m: Motion, c: Command, hold_s: float) -> tuple[FloatArray, float]:
    """Positions [k,3] (from now, every ``STEP_S`` or less) while the vehicle flies ``c``
    for ``hold_s``, and its yaw at the end."""
    path, end = prediction.fly_hold(
        motion_vector(m), float(c.course_rad), float(c.z_m), float(hold_s)
    )
    return path, float(end[prediction.YAW])


def advance(m: Motion, c: Command, dt_s: float) -> Motion:
    """The vehicle ``dt_s`` later, flying ``c`` as predicted (its position, yaw and turn)."""
    vector = motion_vector(m)
    path, end = prediction.fly_hold(vector, float(c.course_rad), float(c.z_m), float(dt_s))
    x, y, z = (float(v) for v in path[-1])
    turning = prediction.yaw_rate_for(vector, end[prediction.BANK])
    return replace(
        m,
        pos_m=(x, y, z),
        yaw_rad=wrap(float(end[prediction.YAW])),
        yaw_rate_rad_s=float(turning),
        climb_rate_m_s=float(end[prediction.FLIGHT_VZ]),
    )


def escape_s(m: Motion) -> float:
    """The longest an escape takes: a half turn at the full rate, after rolling from full
    bank one way to full bank the other."""
    return float(prediction.escape_s(motion_vector(m)))


@dataclass(frozen=True, slots=True)
class Track:
    """A teammate's predicted flight: its hold path (the same instants as every other's),
    then on through an escape's time (``STEP_S`` apart from the hold's end), [k+1+j,3]."""

    path: FloatArray


def track(vector: FloatArray, c: Command, hold_s: float, after_steps: int) -> Track:
    """A vehicle's predicted flight on ``c``: its hold, then ``after_steps`` more."""
    course, z = float(c.course_rad), float(c.z_m)
    return Track(prediction.track_path(vector, course, z, float(hold_s), int(after_steps)))


def straight_track(m: Motion, hold_s: float, after_steps: int) -> Track:
    """A teammate not yet assured this tick, holding its course and height (``track``)."""
    return track(motion_vector(m), Command(m.yaw_rad, m.pos_m[2]), hold_s, after_steps)

"""ArduPlane facts a ground station relies on: flight-mode numbers, the armed flag, component
ids, and how its roll loop and turns answer (measured on real ArduPlane SITL).

The mode numbers are ArduPlane's ``Mode::Number`` (``ArduPlane/mode.h``), which is also the
``PLANE_MODE`` enum of the ``ardupilotmega`` MAVLink dialect; ArduPlane reports the number in
``HEARTBEAT.custom_mode`` and accepts it as ``param2`` of ``MAV_CMD_DO_SET_MODE`` (with
``MAV_MODE_FLAG_CUSTOM_MODE_ENABLED`` in ``param1``, see ``GCS_MAVLINK::_set_mode_common``).
"""

from __future__ import annotations

from enum import IntEnum

from gcs_ppf.mavlink.enums import MAV_MODE_FLAG_SAFETY_ARMED

AUTOPILOT_COMPONENT_ID = 1
"""``MAV_COMP_ID_AUTOPILOT1``: the component id ArduPilot's flight controller sends from."""

GCS_SYSTEM_ID = 255
"""The ground station's default system id (CONVENTIONS §5; ArduPilot's ``SYSID_MYGCS`` default)."""

# How ArduPlane answers a bank demand, fitted to real ArduPlane 4.7 SITL (plane.parm;
# ``tests/sitl/test_arduplane_calibration.py``, ``tests/data/arduplane-traces``): the built-in
# SITL flies by these, the service predicts with them (``gcs_ppf.guidance.assurance``).
ROLL_LAG_PER_TCONST = 0.8
"""Lag of the bank behind its demand, × ``RLL2SRV_TCONST`` (0.25 s: 45° of bank within 0.7 s
of a course step of +90°)."""
ROLL_RATE_MAX_RAD_S = 1.5707963267948966
"""Fastest roll, rad/s (the same step rolled at ~90°/s)."""
TURN_EFFICIENCY = 0.72
"""The turn a bank gives, as a fraction of a coordinated turn's g·tan(φ)/v: real ArduPlane
SITL turned at 72–75 % of it (traces 02, 08 and 09: a 6°/s turn at 18.6° of bank where a
coordinated one needs 14.1°; trace 08 loitered 94 m wide at 40° of bank: 70 %)."""

# How ArduPlane's TECS answers a height demand, fitted the same way (traces 04 and 06:
# altitude +50 m with param3 = 0 and = 2): the built-in SITL climbs by these, the service
# predicts with them.
CLIMB_LAG_PER_TECS_TCONST = 0.4
"""Lag of the vertical speed behind TECS's climb-rate demand, × ``TECS_TIME_CONST`` (5 s: a
2 s lag; the +50 m step climbed at 3 m/s after 3 s)."""
HEIGHT_GAIN_TIMES_TECS_TCONST = 1.75
"""TECS's climb-rate demand per metre of height error, × ``TECS_TIME_CONST`` (5 s: 0.35 /s,
from the tail of the +50 m step and the param3 = 2 run)."""

GCS_COMPONENT_ID = 190
"""``MAV_COMP_ID_MISSIONPLANNER``: the component id ground stations send from."""

FORCE_ARM_DISARM_MAGIC = 21196
"""``param2`` of ``MAV_CMD_COMPONENT_ARM_DISARM`` that skips ArduPilot's arming/disarming checks."""


class PlaneMode(IntEnum):
    """ArduPlane flight modes, numbered as in ``ArduPlane/mode.h`` (``Mode::Number``)."""

    MANUAL = 0
    """Stick inputs go straight to the servos."""
    CIRCLE = 1
    """Circles gently at the current position (a failsafe mode)."""
    STABILIZE = 2
    """Self-levelling on stick release."""
    TRAINING = 3
    """Manual flight with roll and pitch limits."""
    ACRO = 4
    """Rate-based aerobatic flight."""
    FLY_BY_WIRE_A = 5
    """FBWA: sticks command roll and pitch angles, throttle manual."""
    FLY_BY_WIRE_B = 6
    """FBWB: like FBWA with altitude and airspeed held."""
    CRUISE = 7
    """FBWB that also holds the ground track."""
    AUTOTUNE = 8
    """FBWA while tuning the attitude controllers."""
    AUTO = 10
    """Flies the uploaded mission."""
    RTL = 11
    """Returns home and loiters there."""
    LOITER = 12
    """Circles the position where the mode was entered (radius ``WP_LOITER_RAD``)."""
    TAKEOFF = 13
    """Climbs to ``TKOFF_ALT`` above home once armed, then loiters (fixed-wing takeoff)."""
    AVOID_ADSB = 14
    """Set by the ADS-B avoidance library, never by a ground station."""
    GUIDED = 15
    """Flies to (and then circles) the point of the last ``MAV_CMD_DO_REPOSITION``."""
    INITIALISING = 16
    """Start-up, before the sensors are ready."""
    QSTABILIZE = 17
    """QuadPlane VTOL modes from here on."""
    QHOVER = 18
    QLOITER = 19
    QLAND = 20
    QRTL = 21
    QAUTOTUNE = 22
    QACRO = 23
    THERMAL = 24
    """Soaring: circles in rising air."""
    LOITER_ALT_QLAND = 25
    AUTOLAND = 26
    """Fixed-wing automatic landing (ArduPlane 4.6 and later)."""


def is_armed(base_mode: int) -> bool:
    """Whether ``HEARTBEAT.base_mode`` has ``MAV_MODE_FLAG_SAFETY_ARMED`` set."""
    return bool(int(base_mode) & MAV_MODE_FLAG_SAFETY_ARMED)


def plane_mode(custom_mode: int) -> PlaneMode | None:
    """The ArduPlane mode numbered ``custom_mode``, or None for a number ArduPlane lacks."""
    try:
        return PlaneMode(int(custom_mode))
    except ValueError:
        return None


def mode_name(custom_mode: int) -> str:
    """ArduPlane's name for mode ``custom_mode`` (``"GUIDED"``), ``"UNKNOWN(n)"`` if it has none."""
    mode = plane_mode(custom_mode)
    return mode.name if mode is not None else f"UNKNOWN({int(custom_mode)})"

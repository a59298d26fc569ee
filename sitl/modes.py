"""The ArduPlane modes this SITL flies and the HEARTBEAT base_mode flags it reports in each.

The mode numbers are ``gcs_ppf.mavlink.ardupilot.PlaneMode`` (ArduPlane's ``Mode::Number``,
CONVENTIONS §5), the flags ``gcs_ppf.mavlink.enums``. The base_mode computation follows
``GCS_MAVLINK_Plane::base_mode()`` in ArduPlane/GCS_Mavlink.cpp: CUSTOM_MODE_ENABLED always;
MANUAL_INPUT in MANUAL; STABILIZE in every mode but MANUAL; GUIDED in the navigating modes
(AUTO, RTL, LOITER, GUIDED, CIRCLE, TAKEOFF); ArduPlane never sets MAV_MODE_FLAG_AUTO_ENABLED;
SAFETY_ARMED when armed. Stick mixing (ArduPlane's default STICK_MIXING = 1) also sets
MANUAL_INPUT in all modes on a real plane; this SITL has no RC, so it does not.
"""

from __future__ import annotations

import math

from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.mavlink.enums import (
    MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
    MAV_MODE_FLAG_GUIDED_ENABLED,
    MAV_MODE_FLAG_MANUAL_INPUT_ENABLED,
    MAV_MODE_FLAG_SAFETY_ARMED,
    MAV_MODE_FLAG_STABILIZE_ENABLED,
)

FLOWN = frozenset(
    {
        PlaneMode.MANUAL,  # neutral sticks: attitude rates held at zero, throttle kept
        PlaneMode.CIRCLE,  # constant gentle turn, altitude held (no position reference)
        PlaneMode.AUTO,  # flies the stored mission
        PlaneMode.RTL,  # returns home at RTL_ALTITUDE and loiters there
        PlaneMode.LOITER,  # circles the point where the mode was entered
        PlaneMode.TAKEOFF,  # climbs to TKOFF_ALT, then loiters (already airborne here)
        PlaneMode.GUIDED,  # flies to and circles the guided point, or the slewed course
    }
)
"""The ArduPlane modes this SITL flies (``gcs_ppf.mavlink.ardupilot.PlaneMode`` numbers every
mode; the others are refused)."""


#: Modes whose base_mode carries MAV_MODE_FLAG_GUIDED_ENABLED on ArduPlane.
_NAVIGATING = frozenset(
    {
        PlaneMode.AUTO,
        PlaneMode.RTL,
        PlaneMode.LOITER,
        PlaneMode.GUIDED,
        PlaneMode.CIRCLE,
        PlaneMode.TAKEOFF,
    }
)


def base_mode(mode: PlaneMode, armed: bool) -> int:
    """HEARTBEAT.base_mode of an ArduPlane in ``mode`` (see the module docstring)."""
    flags = MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    if mode == PlaneMode.MANUAL:
        flags |= MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
    else:
        flags |= MAV_MODE_FLAG_STABILIZE_ENABLED
    if mode in _NAVIGATING:
        flags |= MAV_MODE_FLAG_GUIDED_ENABLED
    if armed:
        flags |= MAV_MODE_FLAG_SAFETY_ARMED
    return flags


def mode_from_number(number: float | int) -> PlaneMode | None:
    """The mode with this custom-mode number, or None if this SITL does not fly it.

    Accepts floats (COMMAND_LONG params) and rejects NaN, infinities and non-integers.
    """
    if isinstance(number, float) and not (math.isfinite(number) and number.is_integer()):
        return None
    try:
        mode = PlaneMode(int(number))
    except ValueError:
        return None
    return mode if mode in FLOWN else None

"""ArduPlane flight modes: custom-mode numbers and HEARTBEAT base_mode flags.

Numbers are ArduPlane's ``Mode::Number`` (CONVENTIONS §5). The base_mode computation follows
``GCS_MAVLINK_Plane::base_mode()`` in ArduPlane/GCS_Mavlink.cpp: CUSTOM_MODE_ENABLED always;
MANUAL_INPUT in MANUAL; STABILIZE in every mode but MANUAL; GUIDED in the navigating modes
(AUTO, RTL, LOITER, GUIDED, CIRCLE, TAKEOFF); ArduPlane never sets MAV_MODE_FLAG_AUTO_ENABLED;
SAFETY_ARMED when armed. Stick mixing (ArduPlane's default STICK_MIXING = 1) also sets
MANUAL_INPUT in all modes on a real plane; this SITL has no RC, so it does not.
"""

from __future__ import annotations

import math
from enum import IntEnum

MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = 1
MAV_MODE_FLAG_TEST_ENABLED = 2
MAV_MODE_FLAG_AUTO_ENABLED = 4
MAV_MODE_FLAG_GUIDED_ENABLED = 8
MAV_MODE_FLAG_STABILIZE_ENABLED = 16
MAV_MODE_FLAG_HIL_ENABLED = 32
MAV_MODE_FLAG_MANUAL_INPUT_ENABLED = 64
MAV_MODE_FLAG_SAFETY_ARMED = 128


class PlaneMode(IntEnum):
    """The ArduPlane modes this SITL flies (a subset of ArduPlane's)."""

    MANUAL = 0
    """Neutral sticks: the aircraft keeps its attitude rates at zero and its throttle."""
    CIRCLE = 1
    """Constant gentle turn, altitude held (no position reference)."""
    AUTO = 10
    """Flies the stored mission."""
    RTL = 11
    """Returns home at RTL_ALTITUDE and loiters there."""
    LOITER = 12
    """Circles the point where the mode was entered."""
    TAKEOFF = 13
    """Climbs to TKOFF_ALT, then loiters (already airborne here)."""
    GUIDED = 15
    """Flies to and circles the guided point (DO_REPOSITION / MISSION_ITEM_INT current=2)."""


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
        return PlaneMode(int(number))
    except ValueError:
        return None


def mode_name(mode: PlaneMode) -> str:
    return mode.name

"""GUIDED targets as ArduPlane takes them: DO_REPOSITION, the GUIDED slew commands, guided
MISSION_ITEMs and SET_POSITION_TARGET_GLOBAL_INT (ArduPlane/GCS_MAVLink_Plane.cpp)."""

from __future__ import annotations

import math
from typing import Any

from gcs_ppf import geodesy
from gcs_ppf.mavlink import enums
from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.mavlink.enums import (
    HEADING_TYPE_COURSE_OVER_GROUND,
    HEADING_TYPE_DEFAULT,
    HEADING_TYPE_HEADING,
    MAV_CMD_GUIDED_CHANGE_ALTITUDE,
    MAV_CMD_GUIDED_CHANGE_HEADING,
    MAV_CMD_GUIDED_CHANGE_SPEED,
    MAV_DO_REPOSITION_FLAGS_CHANGE_MODE,
    MAV_RESULT_ACCEPTED,
    MAV_RESULT_DENIED,
    MAV_RESULT_FAILED,
    MAV_SEVERITY_WARNING,
    SPEED_TYPE_AIRSPEED,
)
from sitl import mission_protocol as mp
from sitl.autopilot import Autopilot, Clock, GuidedAltitude, GuidedCourse, Kinematics, Outbox
from sitl.handlers.base import Src, finite

GUIDED_SLEW_COMMANDS = (
    MAV_CMD_GUIDED_CHANGE_SPEED,
    MAV_CMD_GUIDED_CHANGE_ALTITUDE,
    MAV_CMD_GUIDED_CHANGE_HEADING,
)


def guided_item(
    ap: Autopilot, item: mp.MissionItem, alt_only: bool, kin: Kinematics, clock: Clock, out: Outbox
) -> bool:
    """ArduPlane accepts a guided goto only in GUIDED; an altitude change in any mode."""
    if mp.validate_item(item) != enums.MAV_MISSION_ACCEPTED and not alt_only:
        return False
    target = ap.location_to_enu(item.frame, item.x, item.y, item.z)
    if target is None or not finite(target[2]):
        return False
    if alt_only:
        x, y, _ = ap.nav.pos_enu_m
        ap.set_nav(type(ap.nav)(ap.nav.kind, (x, y, target[2]), ap.nav.radius_m, ap.nav.direction))
        return True
    if ap.mode != PlaneMode.GUIDED or not finite(target[0], target[1]):
        return False
    ap.set_nav(ap.loiter(target, ap.guided_radius_m, ap.guided_ccw))
    return True


def on_set_position_target_global_int(
    ap: Autopilot, msg: Any, src: Src, kin: Kinematics, clock: Clock, out: Outbox
) -> None:
    """ArduPlane uses only the altitude, and only in GUIDED."""
    if ap.mode != PlaneMode.GUIDED or msg.type_mask & 0x4 or not finite(msg.alt):
        return
    frame = {0: 0, 5: 0, 3: 3, 6: 3, 10: 3, 11: 3}.get(msg.coordinate_frame)
    if frame is None:
        out.text(MAV_SEVERITY_WARNING, "Invalid coord frame in SET_POSTION_TARGET_GLOBAL_INT")
        return
    x, y, _ = ap.nav.pos_enu_m
    target = ap.location_to_enu(frame, 0, 0, msg.alt)
    if target is not None:
        ap.set_nav(type(ap.nav)(ap.nav.kind, (x, y, target[2]), ap.nav.radius_m, ap.nav.direction))


def do_reposition(ap: Autopilot, msg: Any, kin: Kinematics, clock: Clock, out: Outbox) -> int:
    """ArduPlane's handle_command_int_do_reposition."""
    if not (-900_000_000 <= msg.x <= 900_000_000 and -1_800_000_000 <= msg.y <= 1_800_000_000):
        return MAV_RESULT_DENIED
    z = msg.z if math.isfinite(msg.z) else None
    target = ap.location_to_enu(msg.frame, msg.x, msg.y, z if z is not None else 0.0)
    if target is None:
        return MAV_RESULT_DENIED
    if z is None:
        target = (target[0], target[1], kin.pos_enu_m[2])
    if not finite(*target):
        target = (kin.pos_enu_m[0], kin.pos_enu_m[1], target[2])
    flags = int(msg.param2) if math.isfinite(msg.param2) else 0
    if not (flags & MAV_DO_REPOSITION_FLAGS_CHANGE_MODE or ap.mode == PlaneMode.GUIDED):
        return MAV_RESULT_FAILED
    if ap.mode != PlaneMode.GUIDED:
        ap.set_mode(PlaneMode.GUIDED, kin, clock, out)
    ccw = math.isfinite(msg.param4) and msg.param4 != 0
    if math.isfinite(msg.param3) and msg.param3 > 0:
        ap.guided_radius_m, ap.guided_ccw = float(msg.param3), ccw
    ap.guided_course = None  # ArduPlane: target_heading_type = GUIDED_HEADING_NONE
    ap.guidance_dirty = True
    ap.set_nav(ap.loiter(target, ap.guided_radius_m, ap.guided_ccw))
    return MAV_RESULT_ACCEPTED


def guided_slew(ap: Autopilot, msg: Any, kin: Kinematics) -> int:
    """ArduPlane's ``handle_command_int_guided_slew_commands`` (COMMAND_INT only, GUIDED only).

    CHANGE_HEADING: param1 the heading type (course over ground or heading, the same here:
    no wind; HEADING_TYPE_DEFAULT cancels), param2 degrees in [0, 360), param3 the lateral
    acceleration that limits the bank (at least 0.05 m/s²); held until a mode change, a
    DO_REPOSITION or a cancel.  CHANGE_ALTITUDE: z in ``frame`` (0 and −1 are refused as
    ArduPlane does), param3 the vertical speed (0: as fast as possible); held until a mode
    change.  CHANGE_SPEED: param1 airspeed (the only type), param2 within AIRSPEED_MIN..MAX;
    param3 (the acceleration of the change) is accepted, the airframe's SIM_ACCEL_MAX and
    SIM_DECEL_MAX limit it here.
    """
    if ap.mode != PlaneMode.GUIDED:
        return MAV_RESULT_FAILED
    if msg.command == MAV_CMD_GUIDED_CHANGE_SPEED:
        result = _change_speed(ap, msg)
    elif msg.command == MAV_CMD_GUIDED_CHANGE_ALTITUDE:
        result = _change_altitude(ap, msg, kin)
    else:
        result = _change_heading(ap, msg)
    if result == MAV_RESULT_ACCEPTED:
        ap.guidance_dirty = True
    return result


def _change_speed(ap: Autopilot, msg: Any) -> int:
    p1, p2 = msg.param1, msg.param2
    if not finite(p1, p2) or int(p1) != SPEED_TYPE_AIRSPEED:
        return MAV_RESULT_DENIED
    if not ap.params["AIRSPEED_MIN"] <= p2 <= ap.params["AIRSPEED_MAX"]:
        return MAV_RESULT_FAILED
    ap.new_airspeed_m_s = float(p2)
    return MAV_RESULT_ACCEPTED


def _change_altitude(ap: Autopilot, msg: Any, kin: Kinematics) -> int:
    if not finite(msg.z) or msg.z in (0.0, -1.0):
        return MAV_RESULT_DENIED
    lat, lon, _ = geodesy.enu_to_geodetic(*kin.pos_enu_m, ap.origin)  # the altitude here
    target = ap.location_to_enu(msg.frame, round(lat * 1e7), round(lon * 1e7), float(msg.z))
    if target is None:
        return MAV_RESULT_DENIED
    p3 = msg.param3
    rate = abs(p3) if finite(p3) and p3 != 0.0 else 1000.0
    ap.guided_altitude = GuidedAltitude(target[2], rate)
    return MAV_RESULT_ACCEPTED


def _change_heading(ap: Autopilot, msg: Any) -> int:
    p1, p2, p3 = msg.param1, msg.param2, msg.param3
    if not finite(p1, p2) or not 0.0 <= p2 < 360.0:
        return MAV_RESULT_DENIED
    kind = int(p1)
    if kind == HEADING_TYPE_DEFAULT:
        ap.guided_course = None
    elif kind in (HEADING_TYPE_COURSE_OVER_GROUND, HEADING_TYPE_HEADING):
        accel = max(float(p3), 0.05) if finite(p3) else 0.05
        ap.guided_course = GuidedCourse(math.radians(90.0 - p2), accel)
    else:
        return MAV_RESULT_DENIED
    return MAV_RESULT_ACCEPTED

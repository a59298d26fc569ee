"""The parameter table of one simulated vehicle.

A small set of real ArduPlane parameters that change behaviour, plus SIM_* parameters for the
simulated airframe and faults (ArduPilot's SITL also names its simulator knobs SIM_*).
Integer parameters are reported with their MAVLink integer type and their value cast to a
float, as ArduPilot does; a PARAM_SET of an integer parameter accepts an integral float
(MAVSDK and MAVProxy send plain floats). A value out of range, NaN or a fraction for an
integer parameter is refused: the vehicle answers with the unchanged value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

from gcs_ppf.mission import Limits
from sitl.airframe import AirframeName, defaults


class ParamType(IntEnum):
    """MAV_PARAM_TYPE values used here."""

    INT8 = 2
    INT16 = 4
    INT32 = 6
    REAL32 = 9


@dataclass(frozen=True, slots=True)
class ParamSpec:
    """One parameter: name (≤ 16 chars), default, MAVLink type, inclusive range, meaning."""

    name: str
    default: float
    ptype: ParamType
    minimum: float
    maximum: float
    doc: str

    @property
    def is_integer(self) -> bool:
        return self.ptype != ParamType.REAL32


def vehicle_param_specs(
    sysid: int, limits: Limits, cruise_m_s: float, airframe: AirframeName = "auto"
) -> list[ParamSpec]:
    """Parameter definitions for a vehicle with MAVLink id ``sysid`` flying a mission with
    envelope ``limits``; the airframe's defaults come from ``sitl.airframe``."""
    a = defaults(airframe, limits, cruise_m_s)
    i8, i16, i32, f = ParamType.INT8, ParamType.INT16, ParamType.INT32, ParamType.REAL32
    return [
        ParamSpec("SYSID_THISMAV", sysid, i16, 1, 255, "MAVLink system id (after reboot)"),
        ParamSpec("SYSID_MYGCS", 255, i16, 1, 255, "system id of the GCS for the failsafe"),
        ParamSpec("INITIAL_MODE", 0, i8, 0, 24, "flight mode at start"),
        ParamSpec("AIRSPEED_MIN", a["AIRSPEED_MIN"], f, 1, 1000, "minimum airspeed, m/s"),
        ParamSpec("AIRSPEED_MAX", a["AIRSPEED_MAX"], f, 1, 1000, "maximum airspeed, m/s"),
        ParamSpec("AIRSPEED_CRUISE", a["AIRSPEED_CRUISE"], f, 1, 1000, "cruise airspeed, m/s"),
        ParamSpec("WP_RADIUS", a["WP_RADIUS"], i16, 1, 32767, "waypoint acceptance radius, m"),
        ParamSpec("WP_LOITER_RAD", a["WP_LOITER_RAD"], i16, -32767, 32767, "loiter radius, m"),
        ParamSpec("RTL_ALTITUDE", 100, f, -1, 32767, "RTL altitude above home, m; -1 current"),
        ParamSpec("FENCE_ENABLE", 0, i8, 0, 1, "fence on (the uploaded polygons and circles)"),
        ParamSpec("FENCE_TYPE", 6, i8, 0, 15, "fence types: 4 polygons, circles"),
        ParamSpec("FENCE_ACTION", 1, i8, 0, 7, "on a breach: 0 report, else RTL"),
        ParamSpec("TKOFF_ALT", a["TKOFF_ALT"], f, 0, 1000, "TAKEOFF mode altitude, m"),
        ParamSpec("TKOFF_DIST", a["TKOFF_DIST"], f, 0, 30000, "TAKEOFF loiter distance, m"),
        ParamSpec("PTCH_LIM_MAX_DEG", a["PTCH_LIM_MAX_DEG"], f, 0, 90, "maximum pitch, deg"),
        ParamSpec("PTCH_LIM_MIN_DEG", a["PTCH_LIM_MIN_DEG"], f, -90, 0, "minimum pitch, deg"),
        ParamSpec("ROLL_LIMIT_DEG", a["ROLL_LIMIT_DEG"], f, 0, 90, "maximum bank, deg"),
        ParamSpec("GUIDED_P", a["GUIDED_P"], f, 0, 1e7, "GUIDED heading gain, cdeg/rad"),
        ParamSpec("TECS_CLMB_MAX", a["TECS_CLMB_MAX"], f, 0.1, 1000, "max climb rate, m/s"),
        ParamSpec("TECS_SINK_MAX", a["TECS_SINK_MAX"], f, 0.1, 1000, "max sink rate, m/s"),
        ParamSpec("RLL2SRV_TCONST", a["RLL2SRV_TCONST"], f, 0.05, 5, "roll time constant, s"),
        ParamSpec("TECS_TIME_CONST", a["TECS_TIME_CONST"], f, 0.5, 20, "TECS time const, s"),
        ParamSpec("NAVL1_PERIOD", a["NAVL1_PERIOD"], f, 1, 60, "L1 navigation period, s"),
        ParamSpec("NAVL1_DAMPING", a["NAVL1_DAMPING"], f, 0.6, 1, "L1 navigation damping"),
        ParamSpec("FS_GCS_ENABL", 0, i8, 0, 2, "GCS failsafe: 0 off, 1 heartbeat, 2 also RSSI"),
        ParamSpec("FS_LONG_TIMEOUT", 5, f, 1, 300, "GCS-loss failsafe timeout, s"),
        ParamSpec("FS_LONG_ACTN", 0, i8, 0, 3, "0 RTL (AUTO continues), 1 RTL, 2 glide"),
        ParamSpec("SIM_YAW_RATE", a["SIM_YAW_RATE"], f, 0.1, 360, "airframe turn rate, deg/s"),
        ParamSpec("SIM_PTCH_RATE", a["SIM_PTCH_RATE"], f, 0.1, 360, "flight-path rate, deg/s"),
        ParamSpec("SIM_ACCEL_MAX", a["SIM_ACCEL_MAX"], f, 0.1, 1000, "acceleration, m/s/s"),
        ParamSpec("SIM_DECEL_MAX", a["SIM_DECEL_MAX"], f, 0.1, 1000, "deceleration, m/s/s"),
        ParamSpec("SIM_SPEED_MIN", a["SIM_SPEED_MIN"], f, 0.1, 1000, "stall speed, m/s"),
        ParamSpec("SIM_SPEED_MAX", a["SIM_SPEED_MAX"], f, 0.1, 1000, "top speed, m/s"),
        ParamSpec("SIM_SPD_HGT", a["SIM_SPD_HGT"], f, 0, 1, "speed change paid in height"),
        ParamSpec("SIM_ROLL_ZETA", a["SIM_ROLL_ZETA"], f, 0, 2, "bank damping (0: first-order)"),
        ParamSpec("SIM_SPD_OMEGA", a["SIM_SPD_OMEGA"], f, 0.05, 10, "airspeed loop, rad/s"),
        ParamSpec("SIM_SPD_ZETA", a["SIM_SPD_ZETA"], f, 0, 2, "airspeed damping (0: first-order)"),
        ParamSpec("SIM_EAS2TAS", a["SIM_EAS2TAS"], f, 0.5, 2, "true / indicated airspeed"),
        ParamSpec("SIM_GPS_NOISE", 0, f, 0, 1000, "position noise (1σ), m"),
        ParamSpec("SIM_LINK_LOSS", 0, f, 0, 100, "link packet loss, % each way"),
        ParamSpec("SIM_LINK_DELAY", 0, i32, 0, 60000, "added link latency each way, ms"),
        ParamSpec("SIM_LINK_CUT", 0, f, 0, 86400, "cut the link for this many s from now"),
        ParamSpec("SIM_KILL", 0, i8, 0, 1, "1 kills the vehicle: silent, unpowered"),
        ParamSpec("SIM_CMD_IGNORE", 0, i8, 0, 1, "1: ACK flight commands, act on none"),
    ]


class ParamTable:
    """Values of one vehicle's parameters, in a fixed order (the PARAM_VALUE index)."""

    def __init__(self, specs: list[ParamSpec]) -> None:
        self._specs = list(specs)
        self._index = {s.name: k for k, s in enumerate(self._specs)}
        self._values = [float(s.default) for s in self._specs]

    def __len__(self) -> int:
        return len(self._specs)

    def __contains__(self, name: object) -> bool:
        return name in self._index

    def __getitem__(self, name: str) -> float:
        return self._values[self._index[name]]

    def names(self) -> list[str]:
        return [s.name for s in self._specs]

    def spec(self, name: str) -> ParamSpec:
        return self._specs[self._index[name]]

    def index_of(self, name: str) -> int:
        return self._index[name]

    def at(self, index: int) -> tuple[ParamSpec, float] | None:
        """(spec, value) of parameter number ``index``, or None if out of range."""
        if 0 <= index < len(self._specs):
            return self._specs[index], self._values[index]
        return None

    def validate(self, name: str, value: float) -> float | None:
        """The value that setting ``name`` to ``value`` would store, or None if refused."""
        k = self._index.get(name)
        if k is None or not math.isfinite(value):
            return None
        spec = self._specs[k]
        if spec.is_integer:
            if abs(value - round(value)) > 1e-6:
                return None
            value = float(round(value))
        if not spec.minimum <= value <= spec.maximum:
            return None
        return value

    def set(self, name: str, value: float) -> bool:
        """Store ``value``; False (nothing changed) if it is refused."""
        checked = self.validate(name, value)
        if checked is None:
            return False
        self._values[self._index[name]] = checked
        return True


def decode_param_id(raw: str | bytes) -> str:
    """PARAM_*.param_id as text: NUL-terminated unless all 16 characters are used."""
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", errors="replace")
    return raw.split("\x00", 1)[0]

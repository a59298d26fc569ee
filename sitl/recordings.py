"""ArduPlane's recorded step responses (``tests/data/arduplane-traces/``, in the format
``sitl.record_trace`` writes) read back as Responses sampled at 10 Hz from the command.

The recordings are ArduPlane V4.7.0-dev SITL with plane.parm; their README gives the
commands and ``meta.json`` each experiment's command and the state it was given in.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pymap3d
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

TRACES = Path(__file__).resolve().parent.parent / "tests" / "data" / "arduplane-traces"


@dataclass(frozen=True, slots=True)
class Response:
    """One flight, sampled at 10 Hz from the command (t = 0): course over ground and bank
    (deg), height above home, airspeed and climb rate, east/north from the position at the
    command (m)."""

    t: FloatArray
    course_deg: FloatArray
    roll_deg: FloatArray
    rel_alt_m: FloatArray
    airspeed_m_s: FloatArray
    climb_m_s: FloatArray
    east_m: FloatArray
    north_m: FloatArray
    commanded_course_deg: FloatArray | None = None
    """The course last commanded at each sample (the ramps), unwrapped near ``course_deg``."""
    commanded_airspeed_m_s: FloatArray | None = None
    """The airspeed last commanded at each sample (the speed ramps)."""


def commanded_at(schedule: tuple[FloatArray, FloatArray], t: FloatArray) -> FloatArray:
    """The value last commanded at each of ``t``, from a schedule of (times, values)."""
    times, values = schedule
    k = np.searchsorted(times, t, side="right") - 1
    out: FloatArray = values[np.maximum(k, 0)]
    return out


def command_schedule(
    experiment: str, traces: Path = TRACES, column: str = "cmd_course_deg"
) -> tuple[FloatArray, FloatArray]:
    """When a ramp's recorder sent each new command, and its value (courses in deg,
    unwrapped; airspeeds in m/s). The course ramps' commands went out later than the ideal
    rate × t (the recorder, at speedup 4, fell behind by up to 0.8 s at 12°/s), so a replay
    must send these, not the ideal ramp."""
    with (traces / f"{experiment}.csv").open() as fh:
        return _schedule(list(csv.DictReader(fh)), column)


def _schedule(rows: list[dict[str, str]], column: str) -> tuple[FloatArray, FloatArray]:
    times: list[float] = []
    values: list[float] = []
    for r in rows:
        if r.get(column, "") in ("", "nan"):
            continue
        value = float(r[column])
        if not values or value != values[-1]:
            times.append(float(r["t_s"]))
            values.append(value)
    out = np.array(values)
    if column == "cmd_course_deg":
        out = np.degrees(np.unwrap(np.radians(out)))
    return np.array(times), out


def _column(rows: list[dict[str, str]], msg: str, name: str) -> tuple[FloatArray, FloatArray]:
    sel = [r for r in rows if r["msg"] == msg and r[name] != ""]
    return (np.array([float(r["t_s"]) for r in sel]), np.array([float(r[name]) for r in sel]))


def load_recording(experiment: str, traces: Path = TRACES) -> Response:
    """A recorded experiment resampled at 10 Hz from t = 0."""
    with (traces / f"{experiment}.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    t_end = max(float(r["t_s"]) for r in rows)
    t = np.round(np.arange(0.0, t_end + 1e-9, 0.1), 1)

    def at(msg: str, name: str) -> FloatArray:
        ts, vs = _column(rows, msg, name)
        out: FloatArray = np.interp(t, ts, vs)
        return out

    vn, ve = at("GLOBAL_POSITION_INT", "vn_m_s"), at("GLOBAL_POSITION_INT", "ve_m_s")
    lat, lon = at("GLOBAL_POSITION_INT", "lat_deg"), at("GLOBAL_POSITION_INT", "lon_deg")
    e, n, _ = pymap3d.geodetic2enu(lat, lon, 0.0, lat[0], lon[0], 0.0)
    course = np.degrees(np.unwrap(np.arctan2(ve, vn)))
    schedule = _schedule(rows, "cmd_course_deg")
    commanded = None
    if schedule[0].size:
        commanded = near(commanded_at(schedule, t), course)
    speeds = _schedule(rows, "cmd_airspeed_m_s")
    commanded_airspeed = commanded_at(speeds, t) if speeds[0].size else None
    return Response(
        t=t,
        course_deg=course,
        roll_deg=at("ATTITUDE", "roll_deg"),
        rel_alt_m=at("GLOBAL_POSITION_INT", "rel_alt_m"),
        airspeed_m_s=at("VFR_HUD", "airspeed_m_s"),
        climb_m_s=at("VFR_HUD", "climb_m_s"),
        east_m=np.asarray(e, dtype=np.float64),
        north_m=np.asarray(n, dtype=np.float64),
        commanded_course_deg=commanded,
        commanded_airspeed_m_s=commanded_airspeed,
    )


def near(commanded: FloatArray, course: FloatArray) -> FloatArray:
    """``commanded`` shifted by whole turns to the turn ``course`` is in (the lag < 180°)."""
    out: FloatArray = commanded - 360.0 * np.round((commanded - course) / 360.0)
    return out


def load_meta(traces: Path = TRACES) -> dict[str, Any]:
    with (traces / "meta.json").open() as fh:
        meta: dict[str, Any] = json.load(fh)
    return meta

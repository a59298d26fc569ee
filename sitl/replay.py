"""The recorded ArduPlane experiments flown again on the built-in SITL: the same airframe
parameters, the same commands, from the same state, sampled as the recordings are."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
import pymap3d
from numpy.typing import NDArray
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from gcs_ppf.geodesy import enu_to_geodetic
from gcs_ppf.mavlink.ardupilot import GCS_COMPONENT_ID, GCS_SYSTEM_ID, PlaneMode
from gcs_ppf.mission import Limits, Mission, Origin, Vehicle
from sitl.autopilot import Outbox
from sitl.engine import Simulation
from sitl.physics import DT_S
from sitl.recordings import Response, command_schedule, commanded_at, near

_GCS = mavlink.MAVLink(None, srcSystem=GCS_SYSTEM_ID, srcComponent=GCS_COMPONENT_ID)
_PARSER = mavlink.MAVLink(None)
#: The GUIDED experiments start from 15 s of level flight (the traces' settle procedure).
SETTLE_S = 15.0


def _deliver(sim: Simulation, msg: Any) -> int | None:
    """Hand ``msg`` to vehicle 0 as a GCS would send it; the COMMAND_ACK result, if any."""
    out = sim.handle(0, _PARSER.parse_char(msg.pack(_GCS)), link_s=0.0)
    acks = [m for m in (out.reply if out else []) if m.get_type() == "COMMAND_ACK"]
    return int(acks[0].result) if acks else None


def _command(sim: Simulation, spec: dict[str, Any]) -> int | None:
    """One command as meta.json records it (COMMAND_LONG or COMMAND_INT)."""
    p = [float(x) for x in spec["params"]]
    if spec["type"] == "COMMAND_LONG":
        p += [0.0] * (7 - len(p))
        return _deliver(sim, mavlink.MAVLink_command_long_message(1, 1, spec["command"], 0, *p))
    p += [0.0] * (4 - len(p))
    msg = mavlink.MAVLink_command_int_message(
        1,
        1,
        spec["frame"],
        spec["command"],
        0,
        0,
        *p,
        int(spec["x"]),
        int(spec["y"]),
        float(spec["z"]),
    )
    return _deliver(sim, msg)


def _vehicle_mission(
    home: dict[str, float], enu: tuple[float, float, float], yaw: float, speed: float
) -> Mission:
    """One vehicle at ``enu`` about the recording's home, the target far ahead."""
    lim = Limits(v_init=speed, v_min=10.0, v_max=30.0, collision_radius=10.0)
    return Mission(
        name="calibration",
        origin=Origin(lat=home["lat_deg"], lon=home["lon_deg"], alt=home["alt_amsl_m"]),
        limits=lim,
        target=(enu[0] + 5000.0 * math.cos(yaw), enu[1] + 5000.0 * math.sin(yaw), 100.0),
        vehicles=[Vehicle(id=1, role="leader", position=enu, pitch=0.0, yaw=yaw, speed=speed)],
    )


def _sample(sim: Simulation, t0: float, out: list[tuple[float, ...]]) -> None:
    s = sim.state
    e, n, u = (float(c) for c in s.pos_enu_m[0])
    yaw = float(s.yaw_rad[0])
    out.append(
        (
            round(sim.sim_s - t0, 2),
            math.degrees(math.atan2(math.cos(yaw), math.sin(yaw))),
            math.degrees(float(s.roll_rad[0])),
            u - sim.autopilots[0].home_enu_m[2],
            float(s.speed_m_s[0]) / sim.autopilots[0].params["SIM_EAS2TAS"],
            float(s.climb_m_s[0]),
            e,
            n,
        )
    )


def _run(sim: Simulation, seconds: float, t0: float, rows: list[tuple[float, ...]]) -> None:
    every = round(0.1 / DT_S)
    for k in range(round(seconds / DT_S)):
        sim.step(0.0)
        if (k + 1) % every == 0:
            _sample(sim, t0, rows)


def _response(rows: list[tuple[float, ...]]) -> Response:
    a = np.array(rows, dtype=np.float64)
    a = a[a[:, 0] >= -1e-6]
    return Response(
        t=a[:, 0],
        course_deg=np.degrees(np.unwrap(np.radians(a[:, 1]))),
        roll_deg=a[:, 2],
        rel_alt_m=a[:, 3],
        airspeed_m_s=a[:, 4],
        climb_m_s=a[:, 5],
        east_m=a[:, 6] - a[0, 6],
        north_m=a[:, 7] - a[0, 7],
    )


def _guided_at(e: dict[str, Any], meta: dict[str, Any]) -> Simulation:
    """A vehicle in GUIDED at the experiment's recorded state, its level commands given."""
    home = meta["simulator"]["home"]
    state = e["state_at_command"]
    yaw = math.remainder(math.radians(90.0 - state["course_deg"]), math.tau)
    speed = state["airspeed_m_s"]
    mission = _vehicle_mission(home, (0.0, 0.0, state["rel_alt_m"]), yaw, speed)
    sim = Simulation(mission, airframe="arduplane")
    ap = sim.autopilots[0]
    ap.set_mode(PlaneMode.GUIDED, sim.kinematics(0), sim.clock(0.0), Outbox())
    if speed > 25.0:  # 07b starts from the end of 07a: 28 m/s demanded
        _command(sim, {"type": "COMMAND_LONG", "command": 178, "params": [0, speed]})
    for spec in e["level_commands"]:
        _command(sim, spec)
    return sim


def fly_guided(experiment: str, meta: dict[str, Any], duration_s: float) -> Response:
    """A GUIDED experiment: level flight at the recorded state, the settle commands, 15 s,
    then the experiment's command."""
    e = meta["experiments"][experiment]
    sim = _guided_at(e, meta)
    rows: list[tuple[float, ...]] = []
    _run(sim, SETTLE_S, SETTLE_S, rows)
    cmd = dict(e["command"])
    if cmd["command"] == 192:  # DO_REPOSITION: the same offset from here as recorded
        lat, lon, _ = _offset(e, sim)
        cmd["x"], cmd["y"] = round(lat * 1e7), round(lon * 1e7)
    if _command(sim, cmd) != 0:
        raise RuntimeError(f"{experiment}: the built-in SITL refused {cmd['command_name']}")
    _run(sim, duration_s, SETTLE_S, rows)
    return _response(rows)


def fly_heading_ramp(
    meta: dict[str, Any], duration_s: float, experiment: str = "09-heading-ramp"
) -> Response:
    """The course ramp: level, then each course command when the recording sent it."""
    times, courses = command_schedule(experiment)

    def heading(course: float) -> dict[str, Any]:
        params = [0, round(course % 360.0, 2), 10.0]
        return {"type": "COMMAND_INT", "command": 43002, "frame": 0, "params": params}

    r = _fly_schedule(meta, experiment, duration_s, times, [heading(c) for c in courses])
    return replace(r, commanded_course_deg=near(commanded_at((times, courses), r.t), r.course_deg))


def fly_speed_ramp(meta: dict[str, Any], duration_s: float, experiment: str) -> Response:
    """The airspeed ramp: level, then (the climb's altitude and) each airspeed command when
    the recording sent it."""
    e = meta["experiments"][experiment]
    times, speeds = command_schedule(experiment, column="cmd_airspeed_m_s")
    first = [(0.0, c) for c in e["commands_from_t0"]]
    speed = [
        (float(t), {"type": "COMMAND_LONG", "command": 178, "params": [0, float(v), -1]})
        for t, v in zip(times, speeds, strict=True)
    ]
    sends = sorted(first + speed, key=lambda ts: ts[0])
    r = _fly_schedule(
        meta, experiment, duration_s, np.array([t for t, _ in sends]), [c for _, c in sends]
    )
    return replace(r, commanded_airspeed_m_s=commanded_at((times, speeds), r.t))


def _fly_schedule(
    meta: dict[str, Any],
    experiment: str,
    duration_s: float,
    times: NDArray[np.float64],
    commands: list[dict[str, Any]],
) -> Response:
    """Level at the experiment's state, then each command at its time (s from t = 0)."""
    sim = _guided_at(meta["experiments"][experiment], meta)
    rows: list[tuple[float, ...]] = []
    _run(sim, SETTLE_S, SETTLE_S, rows)
    every = round(0.1 / DT_S)
    sent = 0
    for k in range(round(duration_s / DT_S)):
        while sent < times.size and times[sent] <= k * DT_S + 1e-9:
            spec = {"x": 0, "y": 0, "z": 0, **commands[sent]}
            if _command(sim, spec) != 0:
                raise RuntimeError(f"{experiment}: the built-in SITL refused {spec}")
            sent += 1
        sim.step(0.0)
        if (k + 1) % every == 0:
            _sample(sim, SETTLE_S, rows)
    return _response(rows)


def _offset(e: dict[str, Any], sim: Simulation) -> tuple[float, float, float]:
    """The reposition target at the recorded bearing and distance from the vehicle now."""
    s = e["state_at_command"]
    east, north, _ = pymap3d.geodetic2enu(
        e["target_lat_deg"], e["target_lon_deg"], 0.0, s["lat_deg"], s["lon_deg"], 0.0
    )
    x, y, z = (float(c) for c in sim.state.pos_enu_m[0])
    return enu_to_geodetic(x + float(east), y + float(north), z, sim.origin)


def fly_takeoff(meta: dict[str, Any], duration_s: float) -> Response:
    """The takeoff: on the ground heading north, TKOFF_ALT 100, TAKEOFF mode, arm."""
    home = meta["simulator"]["home"]
    mission = _vehicle_mission(home, (0.0, 0.0, 0.0), math.pi / 2, 22.0)
    sim = Simulation(mission, airframe="arduplane", ground_start=True)
    sim.autopilots[0].params.set("TKOFF_ALT", 100.0)
    sim.autopilots[0].set_mode(PlaneMode.TAKEOFF, sim.kinematics(0), sim.clock(0.0), Outbox())
    rows: list[tuple[float, ...]] = []
    _sample(sim, 0.0, rows)
    if _command(sim, meta["experiments"]["01-takeoff"]["command"]) != 0:
        raise RuntimeError("01-takeoff: the built-in SITL refused to arm")
    _run(sim, duration_s, 0.0, rows)
    return _response(rows)

"""Record a step response from any MAVLink ArduPlane — real ArduPlane SITL or this one — in
the format of ``tests/data/arduplane-traces`` (one CSV row per received message).

    python -m sitl.record_trace tcp:127.0.0.1:5760 heading-ramp OUT.csv [--rate-dps 6]

``heading-ramp``: take off in TAKEOFF mode to 100 m, GUIDED, settle 15 s on the current
course and altitude, then command a course that turns at ``--rate-dps`` for 40 s (a
MAV_CMD_GUIDED_CHANGE_HEADING every 0.1 s of the vehicle's time, param3 10 m/s²) and 20 s
more on the last course: how far ArduPlane's P-only heading controller lags a turning
course. Time is the vehicle's (time_boot_ms), t = 0 at the first ramp command.

``climb-at-speed``: the same takeoff and settling, then MAV_CMD_DO_CHANGE_SPEED to
``--airspeed`` (28 m/s: near AIRSPEED_MAX, where a formation's leader flies to its target)
for 25 s, then MAV_CMD_GUIDED_CHANGE_ALTITUDE +50 m with param3 = 0 for 60 s: how TECS
shares its energy between speed and height when the speed asked is high. t = 0 at the
altitude command.

``speed-ramp``: the same takeoff and settling, then an airspeed that ramps down from
AIRSPEED_CRUISE to ``--airspeed`` at ``--rate-mss`` (a MAV_CMD_DO_CHANGE_SPEED every 0.1 s
of the vehicle's time, each for the time it is sent at), 20 s there, back up at the same
rate, 20 s more; with ``--climb-m`` a MAV_CMD_GUIDED_CHANGE_ALTITUDE that far up (param3
0) at t = 0: how far ArduPlane's airspeed lags a slowing it is asked for, level and in a
climb (a formation's wingmen are asked for such ramps in every turn). The airspeed last
commanded is the column ``cmd_airspeed_m_s``. t = 0 at the first ramp command.

``climbing-escape``: the same takeoff and settling, then a half turn at the full bank and a
climb of ``--climb-m`` (150 m if not given) commanded at once, as the run-time assurance's
climbing escape: how far ArduPlane climbs while it turns. t = 0 at the commands.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

from pymavlink import mavutil

from gcs_ppf.mavlink.ardupilot import GCS_COMPONENT_ID, GCS_SYSTEM_ID

COLUMNS = [
    "t_s",
    "msg",
    "lat_deg",
    "lon_deg",
    "alt_amsl_m",
    "rel_alt_m",
    "vn_m_s",
    "ve_m_s",
    "vd_m_s",
    "hdg_deg",
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
    "airspeed_m_s",
    "groundspeed_m_s",
    "climb_m_s",
    "throttle_pct",
    "mode",
    "cmd_course_deg",
    "cmd_airspeed_m_s",
]
TAKEOFF, GUIDED = 13, 15
STREAMS = (33, 30, 74)  # GLOBAL_POSITION_INT, ATTITUDE, VFR_HUD


class Recorder:
    """A pymavlink connection that keeps the vehicle's clock and writes trace rows."""

    def __init__(self, url: str) -> None:
        self.conn: Any = mavutil.mavlink_connection(
            url, source_system=GCS_SYSTEM_ID, source_component=GCS_COMPONENT_ID
        )
        self.conn.wait_heartbeat(timeout=60)
        self.target = self.conn.target_system
        self.boot_ms = 0
        self.mode = -1
        self.rel_alt = math.nan
        self.course = math.nan
        self.rows: list[dict[str, Any]] = []
        self.t0_ms: int | None = None
        self.cmd_course = math.nan
        self.cmd_airspeed = math.nan
        self.sent: list[dict[str, Any]] = []
        self.state: dict[str, float] = {}
        self.at_start: dict[str, Any] = {}
        for msg_id in STREAMS:
            self.command(511, msg_id, 100_000)

    def command(self, cmd: int, *p: float) -> None:
        params = [*p, *([0.0] * (7 - len(p)))]
        self.conn.mav.command_long_send(self.target, 1, cmd, 0, *params)

    def command_int(self, cmd: int, frame: int, p: tuple[float, ...], z: float = 0.0) -> None:
        params = [*p, *([0.0] * (4 - len(p)))]
        self.conn.mav.command_int_send(self.target, 1, frame, cmd, 0, 0, *params, 0, 0, z)
        self.sent.append(
            {"type": "COMMAND_INT", "command": cmd, "frame": frame, "params": params,
             "x": 0, "y": 0, "z": z, "sent_time_boot_ms": self.boot_ms}
        )  # fmt: skip

    def set_mode(self, mode: int) -> None:
        self.command(176, 1, mode)

    def pump(self, seconds: float) -> None:
        """Read messages for ``seconds`` of wall time, recording them."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            msg = self.conn.recv_match(blocking=True, timeout=0.05)
            if msg is not None and msg.get_srcSystem() == self.target:
                self._take(msg)

    def wait_sim(self, seconds: float) -> None:
        """Read messages until ``seconds`` of the vehicle's time have passed."""
        start = self.boot_ms
        while self.boot_ms - start < seconds * 1000:
            self.pump(0.05)

    def _take(self, msg: Any) -> None:
        kind = msg.get_type()
        if kind == "HEARTBEAT" and msg.autopilot != 8:
            self.mode = int(msg.custom_mode)
        if hasattr(msg, "time_boot_ms"):
            self.boot_ms = int(msg.time_boot_ms)
        row: dict[str, Any] = {
            "msg": kind,
            "mode": self.mode,
            "cmd_course_deg": self.cmd_course,
            "cmd_airspeed_m_s": self.cmd_airspeed,
        }
        if kind == "GLOBAL_POSITION_INT":
            self.rel_alt = msg.relative_alt / 1000.0
            self.course = math.degrees(math.atan2(msg.vy, msg.vx)) % 360.0
            self.state.update(lat_deg=msg.lat / 1e7, lon_deg=msg.lon / 1e7)
            self.state.update(rel_alt_m=self.rel_alt, course_deg=self.course)
            row.update(
                lat_deg=msg.lat / 1e7,
                lon_deg=msg.lon / 1e7,
                alt_amsl_m=msg.alt / 1000.0,
                rel_alt_m=self.rel_alt,
                vn_m_s=msg.vx / 100.0,
                ve_m_s=msg.vy / 100.0,
                vd_m_s=msg.vz / 100.0,
                hdg_deg=msg.hdg / 100.0,
            )
        elif kind == "ATTITUDE":
            row.update(
                roll_deg=math.degrees(msg.roll),
                pitch_deg=math.degrees(msg.pitch),
                yaw_deg=math.degrees(msg.yaw),
            )
        elif kind == "VFR_HUD":
            self.state["airspeed_m_s"] = msg.airspeed
            row.update(
                airspeed_m_s=msg.airspeed,
                groundspeed_m_s=msg.groundspeed,
                climb_m_s=msg.climb,
                throttle_pct=msg.throttle,
            )
        elif kind != "HEARTBEAT":
            return
        row["boot_ms"] = self.boot_ms
        self.rows.append(row)

    def write(self, path: Path, t0_ms: int) -> None:
        with path.open("w", newline="") as fh:
            w = csv.DictWriter(fh, COLUMNS, extrasaction="ignore")
            w.writeheader()
            for row in self.rows:
                t = (row["boot_ms"] - t0_ms) / 1000.0
                if t >= -2.0:
                    w.writerow({**row, "t_s": f"{t:.3f}"})


def take_off(rec: Recorder, altitude_m: float = 100.0) -> None:
    """TAKEOFF mode to ``altitude_m``, arming until ArduPlane's pre-arm checks pass."""
    rec.conn.mav.param_set_send(rec.target, 1, b"TKOFF_ALT", altitude_m, 9)
    rec.set_mode(TAKEOFF)
    rec.pump(1.0)
    while not (rec.rel_alt >= altitude_m - 5.0):
        if rec.mode != TAKEOFF:  # refused while the autopilot is still starting
            rec.set_mode(TAKEOFF)
        rec.command(400, 1)  # arm (refused until the EKF and GPS are ready)
        rec.pump(1.0)
        print(f"taking off: mode {rec.mode}, {rec.rel_alt:.1f} m", file=sys.stderr)


def heading_ramp(rec: Recorder, rate_dps: float) -> int:
    """The heading-ramp experiment; the vehicle time of its first ramp command, ms."""
    c0 = settle(rec)
    t0 = rec.boot_ms
    step_ms = 0
    while rec.boot_ms - t0 < 60_000:
        if rec.boot_ms - t0 >= step_ms and step_ms <= 40_000:
            rec.cmd_course = (c0 + rate_dps * step_ms / 1000.0) % 360.0
            rec.command_int(43002, 0, (0, round(rec.cmd_course, 2), 10.0))
            step_ms += 100
        rec.pump(0.02)
    return t0


def settle(rec: Recorder) -> float:
    """TAKEOFF to 100 m, GUIDED, hold the current course and altitude for 15 s; the course."""
    take_off(rec)
    rec.set_mode(GUIDED)
    rec.pump(1.0)
    c0 = round(rec.course, 1)
    rec.command_int(43002, 0, (0, c0, 10.0))
    rec.command_int(43001, 3, (0, 0, 0.0), z=round(rec.rel_alt, 1))
    rec.wait_sim(15.0)
    return c0


def climb_at_speed(rec: Recorder, airspeed_m_s: float) -> int:
    """The climb-at-speed experiment; the vehicle time of its altitude command, ms."""
    settle(rec)
    rec.command(178, 0, airspeed_m_s, -1)  # DO_CHANGE_SPEED: airspeed, throttle unchanged
    rec.wait_sim(25.0)
    target = round(rec.rel_alt + 50.0, 1)
    t0 = rec.boot_ms
    rec.command_int(43001, 3, (0, 0, 0.0), z=target)
    rec.wait_sim(60.0)
    return t0


def speed_ramp(rec: Recorder, low_m_s: float, rate_m_s2: float, climb_m: float) -> int:
    """The speed-ramp experiment; the vehicle time of its first ramp command, ms. Each
    command is the ramp's airspeed at the vehicle time it is sent at, so a late send is
    late, not behind."""
    settle(rec)
    cruise = 22.0
    down_s = (cruise - low_m_s) / rate_m_s2
    t0 = rec.boot_ms
    rec.at_start = {"state_at_command": dict(rec.state), "level_commands": list(rec.sent)}
    if climb_m:
        rec.command_int(43001, 3, (0, 0, 0.0), z=round(rec.rel_alt + climb_m, 1))
    next_ms = 0
    while rec.boot_ms - t0 < (2 * down_s + 40.0) * 1000:
        t = (rec.boot_ms - t0) / 1000.0
        if rec.boot_ms - t0 >= next_ms:
            up_t = t - down_s - 20.0
            speed = max(low_m_s, cruise - rate_m_s2 * t)
            if up_t > 0.0:
                speed = min(cruise, low_m_s + rate_m_s2 * up_t)
            rec.cmd_airspeed = round(speed, 2)
            rec.command(178, 0, rec.cmd_airspeed, -1)  # DO_CHANGE_SPEED: airspeed
            next_ms = rec.boot_ms - t0 + 100
        rec.pump(0.02)
    return t0


def climbing_escape(rec: Recorder, climb_m: float) -> int:
    """The climbing-escape experiment; the vehicle time of its commands, ms: a half turn at
    the full bank (MAV_CMD_GUIDED_CHANGE_HEADING to the course + 180°, param3 30 m/s²,
    more than the bank limit gives) and, at once, MAV_CMD_GUIDED_CHANGE_ALTITUDE
    ``climb_m`` up (param3 0), as the run-time assurance sends a climbing escape; 40 s."""
    c0 = settle(rec)
    t0 = rec.boot_ms
    rec.at_start = {"state_at_command": dict(rec.state), "level_commands": list(rec.sent)}
    rec.cmd_course = (c0 + 180.0) % 360.0
    rec.command_int(43002, 0, (0, round(rec.cmd_course, 2), 30.0))
    rec.command_int(43001, 3, (0, 0, 0.0), z=round(rec.rel_alt + climb_m, 1))
    rec.wait_sim(40.0)
    return t0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m sitl.record_trace", description=__doc__)
    p.add_argument("url", help="pymavlink connection string of the vehicle")
    p.add_argument(
        "experiment", choices=["heading-ramp", "climb-at-speed", "speed-ramp", "climbing-escape"]
    )
    p.add_argument("out", type=Path)
    p.add_argument("--rate-dps", type=float, default=6.0)
    p.add_argument("--airspeed", type=float, default=28.0)
    p.add_argument("--rate-mss", type=float, default=0.6)
    p.add_argument("--climb-m", type=float, default=0.0)
    a = p.parse_args(argv)
    rec = Recorder(a.url)
    if a.experiment == "heading-ramp":
        t0 = heading_ramp(rec, a.rate_dps)
    elif a.experiment == "speed-ramp":
        t0 = speed_ramp(rec, a.airspeed, a.rate_mss, a.climb_m)
    elif a.experiment == "climbing-escape":
        t0 = climbing_escape(rec, a.climb_m or 150.0)
    else:
        t0 = climb_at_speed(rec, a.airspeed)
    rec.write(a.out, t0)
    if rec.at_start:  # what a replay needs: the state at t = 0 and the commands before it
        sidecar = {
            **rec.at_start,
            "commands_from_t0": [c for c in rec.sent if c["sent_time_boot_ms"] >= t0],
        }
        a.out.with_suffix(".json").write_text(json.dumps(sidecar, indent=1))
    print(f"wrote {a.out}: {len(rec.rows)} messages, t0 = {t0} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())

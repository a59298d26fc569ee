"""A deterministic record of what the SITL simulates, to compare two versions of it.

``python scripts/sitl_trace.py record OUT.npz`` flies scripted scenarios through
``sitl.engine.Simulation`` alone (no sockets, no wall clock): Table 2's five vehicles in
GUIDED under a stream of DO_REPOSITION, GUIDED_CHANGE_ALTITUDE / _HEADING / _SPEED,
SET_POSITION_TARGET_GLOBAL_INT, CIRCLE, LOITER, RTL, a gliding vehicle, GPS noise; and
ArduPlane's airframe taking off from the ground and flying an AUTO mission.  It stores every
step's fleet state and every MAVLink frame the vehicles send (packed by one codec per
vehicle, unsigned).  ``python scripts/sitl_trace.py compare A.npz B.npz`` reports the
largest state difference and the frames that differ.  A faster SITL must fly the same.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from gcs_ppf.mavlink import enums
from gcs_ppf.mission import Mission
from sitl.engine import ParamOverride, Simulation
from sitl.faults import parse_fault

ROOT = Path(__file__).resolve().parent.parent
FIELDS = (
    "pos_enu_m",
    "pitch_rad",
    "yaw_rad",
    "speed_m_s",
    "roll_rad",
    "climb_m_s",
    "height_demand_m",
    "pitch_rate_rad_s",
    "yaw_rate_rad_s",
    "accel_m_s2",
    "landed",
)


class Gcs:
    """Builds decoded messages as a ground station (sysid 255) would send them."""

    def __init__(self) -> None:
        self.tx = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        self.rx = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)

    def decoded(self, msg: Any) -> Any:
        data = msg.pack(self.tx)
        out = self.rx.parse_buffer(data)
        assert out
        assert len(out) == 1
        return out[0]

    def command_long(self, sysid: int, cmd: int, *p: float) -> Any:
        params = (list(p) + [0.0] * 7)[:7]
        return self.decoded(mavlink.MAVLink_command_long_message(sysid, 1, cmd, 0, *params))

    def command_int(
        self, sysid: int, cmd: int, p1: float, p2: float, p3: float, p4: float,
        x: int, y: int, z: float, frame: int = 6,
    ) -> Any:  # fmt: skip
        return self.decoded(
            mavlink.MAVLink_command_int_message(sysid, 1, frame, cmd, 0, 0, p1, p2, p3, p4, x, y, z)
        )


class Recorder:
    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.codecs = [
            mavlink.MAVLink(None, srcSystem=ap.sysid, srcComponent=1) for ap in sim.autopilots
        ]
        self.states: dict[str, list[np.ndarray]] = {f: [] for f in FIELDS}
        self.frames: list[bytes] = []
        self.gcs = Gcs()

    def _pack(self, i: int, out: Any) -> None:
        if out is None:
            return
        for msg in [*out.broadcast, *out.reply]:
            self.frames.append(bytes(msg.pack(self.codecs[i])))

    def send(self, i: int, msg: Any) -> None:
        self._pack(i, self.sim.handle(i, msg, self.sim.sim_s))

    def step(self) -> None:
        for i, out in self.sim.step(self.sim.sim_s):
            self._pack(i, out)
        s = self.sim.state
        for f in FIELDS:
            self.states[f].append(np.array(getattr(s, f), copy=True))


def _geo(sim: Simulation, e: float, n: float) -> tuple[int, int]:
    from gcs_ppf import geodesy

    lat, lon, _ = geodesy.enu_to_geodetic(e, n, 0.0, sim.origin)
    return round(lat * 1e7), round(lon * 1e7)


def table2(rec: Recorder, seconds: float) -> None:
    """Five fast vehicles: GUIDED points moving ahead, slews, CIRCLE/LOITER/RTL, a glider."""
    sim, g = rec.sim, rec.gcs
    n = len(sim.autopilots)
    steps = round(seconds / 0.02)
    for k in range(steps):
        t = k * 0.02
        if k == 50:  # 1 s: everyone to GUIDED
            for i in range(n):
                rec.send(i, g.command_long(i + 1, enums.MAV_CMD_DO_SET_MODE, 1, 15))
        if k >= 50 and k % 5 == 0:  # 10 Hz: points ahead on a slow spiral, altitude slews
            for i in range(n):
                ang = 0.02 * t + i
                e = 3000 + 4000 * np.cos(ang) + 100 * i
                nn = 4000 + 4000 * np.sin(ang)
                lat, lon = _geo(sim, e, nn)
                alt = 300.0 + 50 * i + 20 * np.sin(t)
                if i != 3 or t < 30:
                    rec.send(i, g.command_int(i + 1, enums.MAV_CMD_DO_REPOSITION, -1, 1, 0, 0,
                                              lat, lon, alt))  # fmt: skip
                slew, alt = 3.0 * (i % 3), 350.0 + 30 * np.sin(0.1 * t)
                rec.send(i, g.command_int(i + 1, enums.MAV_CMD_GUIDED_CHANGE_ALTITUDE, 0, 0,
                                          slew, 0, 0, 0, alt))  # fmt: skip
        if k == 600:  # 12 s: speed and course slews
            rec.send(
                1, g.command_int(2, enums.MAV_CMD_GUIDED_CHANGE_SPEED, 0, 180.0, 0, 0, 0, 0, 0)
            )
            rec.send(
                2, g.command_int(3, enums.MAV_CMD_GUIDED_CHANGE_HEADING, 0, 135.0, 40.0, 0, 0, 0, 0)
            )
        if k == 900:
            rec.send(0, g.command_long(1, enums.MAV_CMD_DO_CHANGE_SPEED, 0, 250.0, -1))
            msg = mavlink.MAVLink_set_position_target_global_int_message(
                0, 4, 1, 6, 0xFFF8, 0, 0, 420.0, 0, 0, 0, 0, 0, 0, 0, 0
            )
            rec.send(3, g.decoded(msg))
        if k == 1500:  # 30 s: vehicle 4 circles, vehicle 5 loiters
            rec.send(3, g.command_long(4, enums.MAV_CMD_DO_SET_MODE, 1, 1))
            rec.send(4, g.command_long(5, enums.MAV_CMD_DO_SET_MODE, 1, 12))
        if k == 2200:
            rec.send(2, g.command_long(3, enums.MAV_CMD_NAV_RETURN_TO_LAUNCH))
        rec.step()


def takeoff_auto(rec: Recorder, seconds: float) -> None:
    """ArduPlane's airframe from the ground: arm, TAKEOFF, then an AUTO mission."""
    sim, g = rec.sim, rec.gcs
    steps = round(seconds / 0.02)
    for k in range(steps):
        if k == 10:
            for i in range(len(sim.autopilots)):
                rec.send(i, g.command_long(i + 1, enums.MAV_CMD_DO_SET_MODE, 1, 13))
                rec.send(i, g.command_long(i + 1, enums.MAV_CMD_COMPONENT_ARM_DISARM, 1))
        if k == 25 * 50:  # a mission for vehicle 1, then AUTO
            items = [(0, 0, 0.0)] + [
                (*_geo(sim, 400.0 * j, 300.0 * (j % 2)), 80.0 + 10 * j) for j in range(1, 5)
            ]
            rec.send(0, g.decoded(mavlink.MAVLink_mission_count_message(1, 1, len(items), 0)))
            for seq, (lat, lon, alt) in enumerate(items):
                msg = mavlink.MAVLink_mission_item_int_message(
                    1, 1, seq, 6, 16, 0, 1, 0, 0, 0, 0, lat, lon, alt, 0
                )
                rec.send(0, g.decoded(msg))
            rec.send(0, g.command_long(1, enums.MAV_CMD_DO_SET_MODE, 1, 10))
            rec.send(1, g.command_long(2, enums.MAV_CMD_DO_SET_MODE, 1, 11))
        rec.step()


def run() -> dict[str, Any]:
    out: dict[str, Any] = {}
    m2 = Mission.model_validate(json.loads((ROOT / "examples/paper_table2.json").read_text()))
    sim = Simulation(m2, seed=3, faults=[parse_fault("2:noise=2"), parse_fault("5:die=50")])
    rec = Recorder(sim)
    table2(rec, 60.0)
    out["table2"] = rec
    rec = Recorder(Simulation(m2))  # no noise: the telemetry's conversion shared with commands
    table2(rec, 30.0)
    out["table2_clean"] = rec
    slow = Mission.model_validate(json.loads((ROOT / "tests/sitl/mission_two.json").read_text()))
    sim2 = Simulation(slow, airframe="arduplane", ground_start=True,
                      params=[ParamOverride(None, "SIM_SPD_HGT", 0.5)])  # fmt: skip
    rec2 = Recorder(sim2)
    takeoff_auto(rec2, 60.0)
    out["takeoff"] = rec2
    return out


def record(path: Path) -> None:
    import sitl

    print(f"sitl from {Path(sitl.__file__).parent}")
    arrays: dict[str, np.ndarray] = {}
    for name, rec in run().items():
        for f, rows in rec.states.items():
            arrays[f"{name}/{f}"] = np.stack(rows)
        arrays[f"{name}/frames"] = np.array(rec.frames, dtype=object)
        digest = hashlib.sha256(b"".join(rec.frames)).hexdigest()[:16]
        print(f"{name}: {len(rec.states['pos_enu_m'])} steps, {len(rec.frames)} frames, "
              f"sha256 {digest}")  # fmt: skip
    np.savez(path, **arrays, allow_pickle=True)  # type: ignore[arg-type]


def compare(a: Path, b: Path) -> int:
    za, zb = np.load(a, allow_pickle=True), np.load(b, allow_pickle=True)
    bad = 0
    for key in sorted(za.files):
        x, y = za[key], zb[key]
        if key.endswith("/frames"):
            differ = sum(1 for p, q in zip(x, y, strict=False) if p != q)
            print(f"{key}: {len(x)} vs {len(y)} frames, {differ} differ")
            bad += differ + abs(len(x) - len(y))
            continue
        d = float(np.max(np.abs(x.astype(float) - y.astype(float)))) if x.size else 0.0
        print(f"{key}: max |diff| {d:.3g}")
        bad += d > 1e-9
    return 1 if bad else 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__)
    sub = p.add_subparsers(dest="cmd", required=True)
    sub.add_parser("record").add_argument("out", type=Path)
    c = sub.add_parser("compare")
    c.add_argument("a", type=Path)
    c.add_argument("b", type=Path)
    args = p.parse_args(argv)
    if args.cmd == "record":
        record(args.out)
        return 0
    return compare(args.a, args.b)


if __name__ == "__main__":
    sys.exit(main())

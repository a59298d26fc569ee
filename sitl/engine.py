"""The simulation without I/O: a fleet, its autopilots, and a fixed-step clock.

``Simulation.step`` advances simulated time by one physics step (``DT_S``) and returns, per
vehicle, the messages it wants to send (stream messages and autopilot events).
``Simulation.handle`` feeds one decoded inbound message to a vehicle. The shell
(``sitl.server``) owns sockets and wall-clock pacing; the benchmark drives this directly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pymap3d

from gcs_ppf.mavlink.ardupilot import PlaneMode
from gcs_ppf.mission import Mission
from sitl import handlers
from sitl import messages as mb
from sitl import streams as st
from sitl.airframe import AirframeName, resolve
from sitl.autopilot import Autopilot, Clock, Kinematics, Outbox
from sitl.faults import FaultSpec, FaultState
from sitl.mission_protocol import Transfer
from sitl.modes import mode_from_number
from sitl.params import ParamTable, vehicle_param_specs
from sitl.physics import (
    DT_S,
    FleetState,
    Guidance,
    default_envelope,
    hold_guidance,
    initial_state,
    step,
)

_POSITION_STREAMS = frozenset(
    {st.GLOBAL_POSITION_INT, st.GPS_RAW_INT, st.VFR_HUD, st.ATTITUDE, st.POSITION_TARGET_GLOBAL_INT}
)


@dataclass(frozen=True, slots=True)
class ParamOverride:
    """``--param [ID:]NAME=VALUE``: a parameter value at start (vehicle id None = all)."""

    vehicle_id: int | None
    name: str
    value: float


def parse_param_override(text: str) -> ParamOverride:
    head, sep, rest = text.partition(":")
    vehicle_id: int | None = None
    body = text
    if sep and "=" not in head:
        vehicle_id = int(head)
        body = rest
    name, eq, value = body.partition("=")
    if not eq or not name:
        raise ValueError(f"--param: {text!r} is not [ID:]NAME=VALUE")
    return ParamOverride(vehicle_id, name.strip().upper(), float(value))


class Simulation:
    """A mission's vehicles flying in simulated time (starts at 0 s, steps of DT_S).

    A vehicle spawns in the air at its start state (the paper's initial state), armed, in
    MANUAL; or, where ``ground_start`` says so, it sits on the ground at its start position,
    disarmed, in MANUAL, heading along its yaw, as an ArduPlane does after boot: it flies
    once armed in TAKEOFF mode.  ``ground_start`` None (default): on the ground where the
    airframe is ArduPlane's (``sitl.airframe.resolve``) and the start lies on the ground
    (ICS z ≤ 0), in the air elsewhere.  Started in the air at the ground's height, an
    ArduPlane-scale vehicle skimmed the ground at its start speed until its TAKEOFF got
    through (700 m on a lossy link): ArduPlane never does.
    """

    def __init__(
        self,
        mission: Mission,
        *,
        seed: int = 0,
        params: list[ParamOverride] | None = None,
        faults: list[FaultSpec] | None = None,
        boot_unix_us: int = 0,
        airframe: AirframeName = "auto",
        ground_start: bool | None = None,
    ) -> None:
        self.mission = mission
        self.origin = mission.origin
        self.boot_unix_us = boot_unix_us
        self.sim_s = 0.0
        self.steps = 0
        lim = mission.limits
        vehicles = mission.vehicles
        n = len(vehicles)
        speeds = np.array([v.speed if v.speed is not None else lim.v_init for v in vehicles])
        start = np.array([v.position for v in vehicles], dtype=np.float64)
        if ground_start is None:
            arduplane = resolve(airframe, lim) == "arduplane"
            landed = (start[:, 2] <= 0.0) & arduplane
        else:
            landed = np.full(n, ground_start)
        self.state: FleetState = initial_state(
            start,
            np.array([v.pitch for v in vehicles]),
            np.array([v.yaw for v in vehicles]),
            speeds,
            landed=landed,
        )
        z = self.state.pos_enu_m[:, 2]
        ground = np.where(landed, z, np.minimum(0.0, z))
        self.env = default_envelope(
            n,
            v_min=lim.v_min,
            v_max=lim.v_max,
            accel=lim.accel,
            decel=lim.decel,
            max_pitch_rate=lim.max_pitch_rate,
            max_yaw_rate=lim.max_yaw_rate,
            ground_z_m=ground,
        )
        self.guid: Guidance = hold_guidance(self.state)
        self.rngs = [np.random.default_rng([seed, v.id]) for v in vehicles]
        self.autopilots: list[Autopilot] = []
        overrides = params or []
        for i, v in enumerate(vehicles):
            table = ParamTable(vehicle_param_specs(v.id, lim, float(speeds[i]), airframe))
            for o in overrides:
                if o.vehicle_id in (None, v.id):
                    if o.name not in table:
                        raise ValueError(f"--param: unknown parameter {o.name}")
                    if not table.set(o.name, o.value):
                        raise ValueError(f"--param: {o.name}={o.value:g} refused (range)")
            fault = FaultState()
            for f in faults or []:
                if f.vehicle_id in (None, v.id):
                    f.apply(fault)
            fault.noise_m = max(fault.noise_m, table["SIM_GPS_NOISE"])
            home = (float(v.position[0]), float(v.position[1]), float(ground[i]))
            speed = 0.0 if landed[i] else float(speeds[i])
            ap = Autopilot(i, v.id, self.origin, home, table, fault, speed, not bool(landed[i]))
            mode = mode_from_number(table["INITIAL_MODE"]) or PlaneMode.MANUAL
            ap.set_mode(mode, self.kinematics(i), self.clock(0.0), Outbox())
            self.autopilots.append(ap)
        self._sync_commands()

    # ---- views ---------------------------------------------------------------------------
    def clock(self, link_s: float) -> Clock:
        return Clock(self.sim_s, link_s, self.boot_unix_us)

    def kinematics(self, i: int) -> Kinematics:
        s = self.state
        p = s.pos_enu_m[i]
        return Kinematics(
            (float(p[0]), float(p[1]), float(p[2])),
            float(s.yaw_rad[i]),
            float(s.pitch_rad[i]),
            float(s.speed_m_s[i]),
            bool(s.landed[i]),
        )

    def _sync_commands(self) -> None:
        for ap in self.autopilots:
            if ap.envelope_dirty:
                ap.write_envelope(self.env)
            if ap.guidance_dirty:
                ap.write_guidance(self.guid)

    # ---- inbound -------------------------------------------------------------------------
    def handle(self, i: int, msg: object, link_s: float) -> Outbox | None:
        """Deliver a decoded message to vehicle ``i``; its answer (None if silent)."""
        ap = self.autopilots[i]
        out = handlers.handle(ap, msg, self.kinematics(i), self.clock(link_s))
        if ap.reboot_requested:  # a disarmed reboot applies SYSID_THISMAV; the flight goes on
            ap.reboot_requested = False
            ap.sysid = int(ap.params["SYSID_THISMAV"])
        self._sync_commands()
        return out

    # ---- time ----------------------------------------------------------------------------
    def step(self, link_s: float) -> list[tuple[int, Outbox]]:
        """One physics step, then autopilot updates and due telemetry."""
        self.state = step(self.state, self.env, self.guid, DT_S)
        self.steps += 1
        self.sim_s = self.steps * DT_S
        clock = self.clock(link_s)
        outputs: list[tuple[int, Outbox]] = []
        for i, ap in enumerate(self.autopilots):
            if (
                ap.mode == PlaneMode.AUTO
                or ap.takeoff is not None
                or ap.last_gcs_heartbeat_s is not None
                or ap.mission_current_sent != ap.runner.current
                or ap.faults.die_at_s is not None
                or ap.mission.state != Transfer.IDLE
                or ap.fence.state != Transfer.IDLE
                or ap.fence_enabled
            ):
                out = ap.update(self.kinematics(i), clock)
                if out is not None:
                    outputs.append((i, out))
        self._sync_commands()
        self._telemetry(clock, outputs)
        return outputs

    def _telemetry(self, clock: Clock, outputs: list[tuple[int, Outbox]]) -> None:
        due: list[tuple[int, list[int]]] = []
        for i, ap in enumerate(self.autopilots):
            if ap.faults.dead:
                continue
            ids = ap.streams.due(clock.sim_s)
            if ids:
                due.append((i, ids))
        if not due:
            return
        geo = None
        if any(not _POSITION_STREAMS.isdisjoint(ids) for _, ids in due):
            geo = self._geodetic()
        vel = self.state.velocity_enu_m_s()
        roll = self.state.roll_rad
        for i, ids in due:
            ap = self.autopilots[i]
            out = Outbox()
            tel = self._telemetry_of(i, geo, vel, roll, clock) if geo is not None else None
            for msg_id in ids:
                msg = self._stream_message(ap, msg_id, tel, clock)
                if msg is not None:
                    out.broadcast.append(msg)
            outputs.append((i, out))

    def _geodetic(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        pos = self.state.pos_enu_m
        noise = np.zeros_like(pos)
        for i, ap in enumerate(self.autopilots):
            if ap.faults.noise_m > 0:
                noise[i] = self.rngs[i].normal(0.0, ap.faults.noise_m, 3)
        p = pos + noise
        o = self.origin
        lat, lon, alt = pymap3d.enu2geodetic(p[:, 0], p[:, 1], p[:, 2], o.lat, o.lon, o.alt)
        return np.asarray(lat), np.asarray(lon), np.asarray(alt)

    def _telemetry_of(
        self,
        i: int,
        geo: tuple[np.ndarray, np.ndarray, np.ndarray],
        vel: np.ndarray,
        roll: np.ndarray,
        clock: Clock,
    ) -> mb.Telemetry:
        s = self.state
        ap = self.autopilots[i]
        ve, vn, vu = (float(c) for c in vel[i])
        yaw_rate = float(s.yaw_rate_rad_s[i])
        alt = float(geo[2][i])
        return mb.Telemetry(
            time_boot_ms=clock.time_boot_ms,
            lat_deg=float(geo[0][i]),
            lon_deg=float(geo[1][i]),
            alt_amsl_m=alt,
            alt_rel_home_m=alt - ap.home_geo[2],
            vel_ned_m_s=(vn, ve, -vu),
            roll_rad=float(roll[i]),
            pitch_rad=float(s.pitch_rad[i]),
            heading_rad=(math.pi / 2 - float(s.yaw_rad[i])) % math.tau,
            roll_rate_rad_s=0.0,
            pitch_rate_rad_s=float(s.pitch_rate_rad_s[i]),
            yaw_rate_ned_rad_s=-yaw_rate,
            airspeed_m_s=float(s.speed_m_s[i]) / ap.params["SIM_EAS2TAS"],
            throttle_pct=50 if ap.thrust and not s.landed[i] else 0,
            landed=bool(s.landed[i]),
        )

    def _stream_message(
        self, ap: Autopilot, msg_id: int, tel: mb.Telemetry | None, clock: Clock
    ) -> mb.Message | None:
        if msg_id == st.HEARTBEAT:
            return ap.heartbeat()
        if msg_id == st.SYS_STATUS:
            return ap.sys_status_msg()
        if msg_id == st.FENCE_STATUS:
            return ap.fence_status_msg()
        if msg_id == st.SYSTEM_TIME:
            return mb.system_time(clock.unix_us, clock.time_boot_ms)
        if msg_id == st.EXTENDED_SYS_STATE:
            return mb.extended_sys_state(bool(self.state.landed[ap.index]))
        if msg_id == st.MISSION_CURRENT:
            return ap.mission_current_msg()
        if msg_id == st.HOME_POSITION:
            return ap.home_position(clock)
        if tel is None:
            return None
        if msg_id == st.GLOBAL_POSITION_INT:
            return mb.global_position_int(tel)
        if msg_id == st.ATTITUDE:
            return mb.attitude(tel)
        if msg_id == st.GPS_RAW_INT:
            return mb.gps_raw_int(tel, clock.unix_us)
        if msg_id == st.VFR_HUD:
            return mb.vfr_hud(tel)
        if msg_id == st.POSITION_TARGET_GLOBAL_INT:
            return ap.position_target(clock)
        return None

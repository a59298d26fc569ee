"""One simulated ArduPlane autopilot: modes, arming, parameters, mission, failsafe.

Sans I/O: ``handle`` takes a decoded message, its sender and the clocks and returns the
messages to send (to the sender, or to every client); ``update`` runs once per physics step.
The autopilot steers by writing its row of the fleet ``Guidance`` arrays (``write_guidance``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from gcs_ppf import geodesy
from gcs_ppf.mavlink import enums
from gcs_ppf.mavlink.ardupilot import (
    CLIMB_LAG_PER_TECS_TCONST,
    HEIGHT_GAIN_TIMES_TECS_TCONST,
    ROLL_LAG_PER_TCONST,
    TURN_EFFICIENCY,
    PlaneMode,
)
from gcs_ppf.mavlink.enums import MAV_SEVERITY_CRITICAL, MAV_SEVERITY_INFO, MAV_SEVERITY_WARNING
from gcs_ppf.mission import Origin
from sitl import fence
from sitl import messages as mb
from sitl import mission_protocol as mp
from sitl import streams as st
from sitl.faults import FaultState
from sitl.messages import Message
from sitl.navigation import AutoEvents, MissionRunner, NavTarget
from sitl.params import ParamTable
from sitl.physics import (
    GRAVITY_M_S2,
    ORBIT_MARGIN,
    Envelope,
    Guidance,
    GuidanceKind,
    heading_gain,
)

Vec3 = tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class Clock:
    """Simulated time (drives the vehicle) and link time (drives protocol timeouts), s."""

    sim_s: float
    link_s: float
    boot_unix_us: int = 0

    @property
    def time_boot_ms(self) -> int:
        return round(self.sim_s * 1000.0)

    @property
    def unix_us(self) -> int:
        return self.boot_unix_us + round(self.sim_s * 1e6)


@dataclass(frozen=True, slots=True)
class Kinematics:
    """One vehicle's state as the autopilot sees it (ICS, SI)."""

    pos_enu_m: Vec3
    yaw_rad: float
    pitch_rad: float
    speed_m_s: float
    landed: bool


@dataclass(frozen=True, slots=True)
class GuidedCourse:
    """MAV_CMD_GUIDED_CHANGE_HEADING: the course to hold (ENU yaw, rad) and the lateral
    acceleration that limits the bank of the turn onto it (m/s²)."""

    course_rad: float
    lateral_accel_m_s2: float


@dataclass(frozen=True, slots=True)
class GuidedAltitude:
    """MAV_CMD_GUIDED_CHANGE_ALTITUDE: the altitude to reach (ICS z, m) and the vertical
    speed to change it at (m/s)."""

    z_m: float
    rate_m_s: float


@dataclass(frozen=True, slots=True)
class TakeoffStage:
    """ArduPlane TAKEOFF mode's takeoff stage (``mode_takeoff.cpp``): roll along
    ``course_rad`` from ``start_enu_m``, climb at full throttle, until TKOFF_ALT − 2 m or
    TKOFF_DIST from the start; then loiter at ``loiter_enu_m`` (TKOFF_DIST ahead)."""

    start_enu_m: Vec3
    course_rad: float
    loiter_enu_m: Vec3


@dataclass
class Outbox:
    """Messages produced by one event: ``reply`` to the sender, ``broadcast`` to every client."""

    reply: list[Message] = field(default_factory=list)
    broadcast: list[Message] = field(default_factory=list)

    def text(self, severity: int, text: str) -> None:
        self.broadcast.append(mb.statustext(severity, text))


class Autopilot:
    """The autopilot of vehicle ``index`` of the fleet."""

    def __init__(
        self,
        index: int,
        sysid: int,
        origin: Origin,
        home_enu_m: Vec3,
        params: ParamTable,
        faults: FaultState,
        initial_speed_m_s: float,
        armed: bool = True,
    ) -> None:
        self.index = index
        self.sysid = sysid
        self.origin = origin
        self.params = params
        self.faults = faults
        self.home_enu_m = home_enu_m
        lat, lon, alt = geodesy.enu_to_geodetic(*home_enu_m, origin)
        self.home_geo = (lat, lon, alt)
        self.mission = mp.MissionServer()
        self.fence = mp.MissionServer(mp.MISSION_TYPE_FENCE, fence.validate_item)
        self.fence_areas: list[fence.Area] = []
        self.fence_breached = False
        self.fence_breach_count = 0
        self.fence_breach_time_ms = 0
        self.runner = MissionRunner([], [])
        self.streams = st.StreamSchedule.default()
        self.mode = PlaneMode.MANUAL
        self.armed = armed
        self.nav = NavTarget(GuidanceKind.HOLD, home_enu_m)
        self.new_airspeed_m_s: float | None = None
        self.manual_speed_m_s = initial_speed_m_s
        self.glide = False
        self.last_gcs_heartbeat_s: float | None = None
        self.gcs_failsafe = False
        self.guidance_dirty = True
        self.envelope_dirty = True
        self.mission_current_sent = -1
        self.guided_radius_m: float | None = None  # DO_REPOSITION param3, until a mode change
        self.guided_ccw: bool | None = None
        # GUIDED's slew targets (MAV_CMD_GUIDED_CHANGE_*), until a mode change.
        self.guided_course: GuidedCourse | None = None
        self.guided_altitude: GuidedAltitude | None = None
        self.takeoff: TakeoffStage | None = None
        self.reboot_requested = False

    # ---- geometry ------------------------------------------------------------------------
    def location_to_enu(self, frame: int, lat_e7: int, lon_e7: int, z_m: float) -> Vec3 | None:
        """A MAVLink global location as ICS metres; None for an unsupported frame.

        Latitude = longitude = 0 means "here" (x and y NaN); terrain frames are read as
        relative to home (the simulated terrain is flat at home altitude).
        """
        if frame not in mp.GLOBAL_FRAMES:
            return None
        alt_amsl = z_m + (self.home_geo[2] if frame in mp.RELATIVE_FRAMES else 0.0)
        if lat_e7 == 0 and lon_e7 == 0:
            _, _, up = geodesy.geodetic_to_enu(
                self.home_geo[0], self.home_geo[1], alt_amsl, self.origin
            )
            return (math.nan, math.nan, up)
        return geodesy.geodetic_to_enu(lat_e7 * 1e-7, lon_e7 * 1e-7, alt_amsl, self.origin)

    def rtl_point(self, kin: Kinematics) -> Vec3:
        rtl_alt = self.params["RTL_ALTITUDE"]
        z = kin.pos_enu_m[2] if rtl_alt < 0 else self.home_enu_m[2] + rtl_alt
        return (self.home_enu_m[0], self.home_enu_m[1], z)

    def loiter(
        self, center: Vec3, radius: float | None = None, ccw: bool | None = None
    ) -> NavTarget:
        rad = self.params["WP_LOITER_RAD"]
        r = abs(rad) if radius is None else radius
        counter = rad < 0 if ccw is None else ccw
        return NavTarget(GuidanceKind.ORBIT, center, r, -1.0 if counter else 1.0)

    def set_nav(self, nav: NavTarget) -> None:
        if nav != self.nav:
            self.nav = nav
            self.guidance_dirty = True

    # ---- state changes -------------------------------------------------------------------
    def set_mode(self, mode: PlaneMode, kin: Kinematics, clock: Clock, out: Outbox) -> bool:
        """Enter ``mode`` as ArduPlane does; always succeeds for the modes flown here."""
        self.mode = mode
        self.new_airspeed_m_s = None
        self.guided_radius_m = None
        self.guided_ccw = None
        self.guided_course = None
        self.guided_altitude = None
        self.takeoff = None
        self.guidance_dirty = True
        here = kin.pos_enu_m
        if mode == PlaneMode.MANUAL:
            self.manual_speed_m_s = kin.speed_m_s
            self.set_nav(NavTarget(GuidanceKind.HOLD, here))
        elif mode == PlaneMode.CIRCLE:
            rad = self.params["WP_LOITER_RAD"]
            self.set_nav(
                NavTarget(GuidanceKind.TURN, here, max(abs(rad), 1.0), -1 if rad < 0 else 1)
            )
        elif mode in (PlaneMode.LOITER, PlaneMode.GUIDED):
            self.set_nav(self.loiter(here))
        elif mode == PlaneMode.TAKEOFF:
            self._takeoff_begin(kin, out)
        elif mode == PlaneMode.RTL:
            self.set_nav(self.loiter(self.rtl_point(kin)))
        elif mode == PlaneMode.AUTO:
            self._auto_begin(kin, clock, out)
        return True

    def _takeoff_begin(self, kin: Kinematics, out: Outbox) -> None:
        """TAKEOFF: below TKOFF_ALT, climb along the current course to a loiter TKOFF_DIST
        ahead at TKOFF_ALT; above it, loiter here (ArduPlane ``ModeTakeoff::update``)."""
        here = kin.pos_enu_m
        alt = self.home_enu_m[2] + self.params["TKOFF_ALT"]
        if here[2] >= alt and not kin.landed:
            out.text(MAV_SEVERITY_INFO, "Above TKOFF alt - loitering")
            self.set_nav(self.loiter(here))
            return
        dist = self.params["TKOFF_DIST"]
        ahead = (
            here[0] + dist * math.cos(kin.yaw_rad),
            here[1] + dist * math.sin(kin.yaw_rad),
            alt,
        )
        self.takeoff = TakeoffStage(here, kin.yaw_rad, ahead)
        compass = (90.0 - math.degrees(kin.yaw_rad)) % 360.0
        out.text(
            MAV_SEVERITY_INFO,
            f"Takeoff to {self.params['TKOFF_ALT']:.0f}m for {dist:.1f}m heading {compass:.1f} deg",
        )
        self.set_nav(NavTarget(GuidanceKind.COURSE, ahead))

    def _takeoff_update(self, kin: Kinematics) -> None:
        """The takeoff stage ends 2 m below TKOFF_ALT or TKOFF_DIST from the start."""
        stage = self.takeoff
        if stage is None or kin.landed:
            return
        sx, sy, _ = stage.start_enu_m
        x, y, z = kin.pos_enu_m
        far = math.hypot(x - sx, y - sy) >= self.params["TKOFF_DIST"]
        if z >= stage.loiter_enu_m[2] - 2.0 or far:
            self.takeoff = None
            self.guidance_dirty = True
            self.set_nav(self.loiter(stage.loiter_enu_m))

    def _auto_begin(self, kin: Kinematics, clock: Clock, out: Outbox) -> None:
        events = AutoEvents()
        if self.runner.current < 1 or self.runner.current >= self.runner.count:
            self.runner.restart()
        self.runner.begin(kin.pos_enu_m, kin.yaw_rad, clock.sim_s, events)
        self._auto_events(events, kin, clock, out)
        if self.mode == PlaneMode.AUTO:
            self.set_nav(self.runner.target(self.rtl_point(kin), self.params["WP_LOITER_RAD"]))

    def _auto_events(self, events: AutoEvents, kin: Kinematics, clock: Clock, out: Outbox) -> None:
        for seq in events.reached:
            out.broadcast.append(mb.mission_item_reached(seq))
            out.text(MAV_SEVERITY_INFO, f"Reached waypoint #{seq}")
        for _type, speed in events.speed_changes:
            self.change_speed(speed, out)
        if events.landed:
            self.armed = False
            out.text(MAV_SEVERITY_INFO, "Land complete")
        if events.complete and self.mode == PlaneMode.AUTO:
            out.text(MAV_SEVERITY_INFO, "Mission complete, changing mode to RTL")
            self.set_mode(PlaneMode.RTL, kin, clock, out)

    def change_speed(self, speed_m_s: float, out: Outbox) -> bool:
        """DO_CHANGE_SPEED (airspeed): −2 returns to cruise; else within AIRSPEED_MIN/MAX."""
        if speed_m_s == -2.0:
            self.new_airspeed_m_s = None
        elif self.params["AIRSPEED_MIN"] <= speed_m_s <= self.params["AIRSPEED_MAX"]:
            self.new_airspeed_m_s = speed_m_s
            out.text(MAV_SEVERITY_INFO, f"Set airspeed {int(speed_m_s)} m/s")
        else:
            return False
        self.guidance_dirty = True
        return True

    def mission_changed(self) -> None:
        items = self.mission.items
        targets: list[Vec3 | None] = [None]
        for item in items[1:]:
            tgt = None
            if item.command in mp.NAV_WITH_LOCATION:
                tgt = self.location_to_enu(item.frame, item.x, item.y, item.z)
                if tgt is not None and item.command == enums.MAV_CMD_NAV_LAND:
                    tgt = (tgt[0], tgt[1], self.home_enu_m[2] - 50.0)  # glide into the ground
            targets.append(tgt)
        self.runner = MissionRunner(list(items), targets)

    # ---- per step ------------------------------------------------------------------------
    @property
    def speed_cmd_m_s(self) -> float:
        if self.mode == PlaneMode.MANUAL:
            return self.manual_speed_m_s
        speed = self.new_airspeed_m_s or self.params["AIRSPEED_CRUISE"]
        return min(max(speed, self.params["AIRSPEED_MIN"]), self.params["AIRSPEED_MAX"])

    @property
    def thrust(self) -> bool:
        return self.armed and not self.faults.dead and not self.glide

    def write_guidance(self, guid: Guidance) -> None:
        i = self.index
        guid.kind[i] = int(self.nav.kind)
        guid.target_enu_m[i] = self.nav.pos_enu_m
        guid.radius_m[i] = self.nav.radius_m
        guid.direction[i] = self.nav.direction
        tas = 1.0 if self.mode == PlaneMode.MANUAL else self.params["SIM_EAS2TAS"]
        guid.speed_cmd_m_s[i] = self.speed_cmd_m_s * tas  # an airspeed demand is EAS
        guid.thrust[i] = self.thrust
        guid.alt_slew_m_s[i] = math.inf
        guid.takeoff[i] = self.takeoff is not None and self.thrust
        if self.takeoff is not None:
            guid.course_rad[i] = self.takeoff.course_rad
            guid.lateral_accel_m_s2[i] = math.inf
        if self.mode == PlaneMode.GUIDED and self.guided_course is not None:
            guid.kind[i] = int(GuidanceKind.COURSE)
            guid.course_rad[i] = self.guided_course.course_rad
            guid.lateral_accel_m_s2[i] = self.guided_course.lateral_accel_m_s2
        if self.mode == PlaneMode.GUIDED and self.guided_altitude is not None:
            guid.target_enu_m[i, 2] = self.guided_altitude.z_m
            guid.alt_slew_m_s[i] = self.guided_altitude.rate_m_s
        self.guidance_dirty = False

    def write_envelope(self, env: Envelope) -> None:
        i, p = self.index, self.params
        env.v_min_m_s[i] = p["SIM_SPEED_MIN"] * p["SIM_EAS2TAS"]
        env.v_max_m_s[i] = max(p["SIM_SPEED_MAX"], p["SIM_SPEED_MIN"]) * p["SIM_EAS2TAS"]
        env.accel_m_s2[i] = p["SIM_ACCEL_MAX"]
        env.decel_m_s2[i] = p["SIM_DECEL_MAX"]
        env.max_yaw_rate_rad_s[i] = math.radians(p["SIM_YAW_RATE"])
        env.max_pitch_rate_rad_s[i] = math.radians(p["SIM_PTCH_RATE"])
        env.pitch_min_rad[i] = math.radians(p["PTCH_LIM_MIN_DEG"])
        env.pitch_max_rad[i] = math.radians(p["PTCH_LIM_MAX_DEG"])
        env.roll_limit_rad[i] = math.radians(p["ROLL_LIMIT_DEG"])
        env.heading_gain[i] = heading_gain(p["GUIDED_P"])
        env.climb_max_m_s[i] = p["TECS_CLMB_MAX"]
        env.sink_max_m_s[i] = p["TECS_SINK_MAX"]
        env.l1_period_s[i] = p["NAVL1_PERIOD"]
        env.l1_damping[i] = p["NAVL1_DAMPING"]
        env.takeoff_climb_m_s[i] = 2.0 * p["TECS_CLMB_MAX"]
        env.speed_height_coupling[i] = p["SIM_SPD_HGT"]
        env.roll_lag_s[i] = ROLL_LAG_PER_TCONST * p["RLL2SRV_TCONST"]
        env.roll_damping[i] = p["SIM_ROLL_ZETA"]
        env.speed_omega_rad_s[i] = p["SIM_SPD_OMEGA"]
        env.speed_damping[i] = p["SIM_SPD_ZETA"]
        env.climb_lag_s[i] = CLIMB_LAG_PER_TECS_TCONST * p["TECS_TIME_CONST"]
        env.height_gain_1_s[i] = HEIGHT_GAIN_TIMES_TECS_TCONST / p["TECS_TIME_CONST"]
        env.rotate_speed_m_s[i] = 0.9 * p["AIRSPEED_CRUISE"] * p["SIM_EAS2TAS"]
        self.envelope_dirty = False

    def loiter_radius_eff_m(self, kin: Kinematics) -> float:
        """The loiter radius actually flown (see physics.effective_radius_m)."""
        v = max(kin.speed_m_s, 1.0)
        bank = min(math.radians(self.params["ROLL_LIMIT_DEG"]), 1.5)
        tightest = max(
            v * v / (TURN_EFFICIENCY * GRAVITY_M_S2 * math.tan(bank)),
            v / math.radians(self.params["SIM_YAW_RATE"]),
        )
        return max(abs(self.nav.radius_m), ORBIT_MARGIN * tightest)

    def update(self, kin: Kinematics, clock: Clock) -> Outbox | None:
        """Once per physics step: mission progress, failsafe, faults. None if nothing to say."""
        out: Outbox | None = None
        if self.faults.update(clock.sim_s):
            self.guidance_dirty = True
        if self.faults.dead:
            return None
        if self.takeoff is not None:
            self._takeoff_update(kin)
        if self.mode == PlaneMode.AUTO and self.runner.active:
            events = self.runner.update(
                self.rtl_point(kin),
                kin.pos_enu_m,
                kin.yaw_rad,
                self.loiter_radius_eff_m(kin),
                self.params["WP_RADIUS"],
                clock.sim_s,
                kin.landed,
            )
            if events.reached or events.complete or events.speed_changes or events.landed:
                out = Outbox()
                self._auto_events(events, kin, clock, out)
                if self.mode == PlaneMode.AUTO:
                    self.set_nav(
                        self.runner.target(self.rtl_point(kin), self.params["WP_LOITER_RAD"])
                    )
        if self.mission_current_sent != self.runner.current:
            out = out or Outbox()
            out.broadcast.append(self.mission_current_msg())
        breach = self._fence_check(kin, clock)
        if breach is not None:
            out = out or Outbox()
            out.broadcast.extend(breach.broadcast)
        fs = self._failsafe(kin, clock)
        if fs is not None:
            out = out or Outbox()
            out.broadcast.extend(fs.broadcast)
        for server in (self.mission, self.fence):
            if server.state == mp.Transfer.RECEIVING:
                res = server.tick(clock.link_s)
                if res.replies:
                    out = out or Outbox()
                    out.broadcast.extend(res.replies)
        return out

    # ---- the fence -----------------------------------------------------------------------
    def fence_changed(self) -> bool:
        """The fence list uploaded or cleared: its areas (False: a polygon's vertices do not
        add up, and the list is refused whole, as ArduPilot does)."""
        found = fence.areas(self.fence.items)
        if found is None:
            self.fence.items = []
            self.fence_areas = []
            return False
        self.fence_areas = found
        return True

    @property
    def fence_enabled(self) -> bool:
        """FENCE_ENABLE with the polygon type (4) on and areas to keep."""
        on = self.params["FENCE_ENABLE"] != 0 and int(self.params["FENCE_TYPE"]) & 4
        return bool(on and self.fence_areas)

    def _fence_check(self, kin: Kinematics, clock: Clock) -> Outbox | None:
        """ArduPlane's fence: a breach (outside an inclusion area, inside an exclusion one)
        is a CRITICAL STATUSTEXT and, unless FENCE_ACTION is 0 (report only), RTL; the
        breach clears when the vehicle is back on the right side."""
        if not self.fence_enabled:
            self.fence_breached = False
            return None
        lat, lon, _ = geodesy.enu_to_geodetic(*kin.pos_enu_m, self.origin)
        now = bool(fence.breached(self.fence_areas, lat, lon))
        if now == self.fence_breached:
            return None
        self.fence_breached = now
        out = Outbox()
        if not now:
            out.text(MAV_SEVERITY_INFO, "Fence breach cleared")
            return out
        self.fence_breach_count += 1
        self.fence_breach_time_ms = clock.time_boot_ms
        out.text(MAV_SEVERITY_CRITICAL, "Fence Breached")
        acting = int(self.params["FENCE_ACTION"]) != 0 and self.armed and not kin.landed
        if acting and self.mode != PlaneMode.RTL:
            self.set_mode(PlaneMode.RTL, kin, clock, out)
        return out

    def fence_status_msg(self) -> Message | None:
        """FENCE_STATUS while the fence is enabled (ArduPlane sends none otherwise)."""
        if not self.fence_enabled:
            return None
        return mb.fence_status(
            self.fence_breached,
            self.fence_breach_count,
            self.fence_breach_time_ms,
            fence.BREACH_BOUNDARY if self.fence_breach_count else 0,
        )

    def sys_status_msg(self, drop_rate_comm_cpct: int = 0) -> Message:
        return mb.sys_status(
            drop_rate_comm_cpct,
            fence_present=bool(self.fence_areas),
            fence_enabled=self.fence_enabled,
            fence_breached=self.fence_breached,
        )

    def _failsafe(self, kin: Kinematics, clock: Clock) -> Outbox | None:
        """ArduPlane's long GCS failsafe: no heartbeat from SYSID_MYGCS for FS_LONG_TIMEOUT."""
        if self.params["FS_GCS_ENABL"] == 0 or self.last_gcs_heartbeat_s is None:
            return None
        silent = clock.sim_s - self.last_gcs_heartbeat_s > self.params["FS_LONG_TIMEOUT"]
        if silent and not self.gcs_failsafe:
            self.gcs_failsafe = True
            out = Outbox()
            out.text(MAV_SEVERITY_CRITICAL, "Failsafe. Long event on: type=2/reason=2")
            action = int(self.params["FS_LONG_ACTN"])
            if action == 2:
                self.glide = True
                self.guidance_dirty = True
            elif not (action == 0 and self.mode == PlaneMode.AUTO):
                self.set_mode(PlaneMode.RTL, kin, clock, out)
            return out
        if not silent and self.gcs_failsafe:
            self.gcs_failsafe = False
            self.glide = False
            self.guidance_dirty = True
            out = Outbox()
            out.text(MAV_SEVERITY_WARNING, "Long failsafe cleared")
            return out
        return None

    def mission_current_msg(self) -> Message:
        total = max(self.runner.count - 1, 0)
        seq = self.runner.current if self.runner.count > 1 else 0
        state = 1 if self.runner.count <= 1 else (3 if self.mode == PlaneMode.AUTO else 4)
        if self.runner.count > 1 and not self.runner.active and self.mode == PlaneMode.AUTO:
            state = 5
        self.mission_current_sent = self.runner.current
        return mb.mission_current(seq, total, state, 1 if self.mode == PlaneMode.AUTO else 0)

    def system_status(self) -> int:
        if self.faults.dead:
            return enums.MAV_STATE_POWEROFF
        if self.gcs_failsafe:
            return enums.MAV_STATE_CRITICAL
        return enums.MAV_STATE_ACTIVE if self.armed else enums.MAV_STATE_STANDBY

    def heartbeat(self) -> Message:
        return mb.heartbeat(self.mode, self.armed, self.system_status())

    def home_position(self, clock: Clock) -> Message:
        return mb.home_position(*self.home_geo, clock.unix_us)

    def position_target(self, clock: Clock) -> Message | None:
        if self.mode == PlaneMode.MANUAL:
            return None
        x, y, z = self.nav.pos_enu_m
        lat, lon, alt = geodesy.enu_to_geodetic(x, y, z, self.origin)
        return mb.position_target_global_int(clock.time_boot_ms, lat, lon, alt)

"""AUTO mode: executing the stored mission, as ArduPlane's mission code does in outline.

Pure: the runner gets the items, their targets in the ICS and the vehicle's kinematics, and
returns the navigation target plus events (item reached, speed change, mission complete).
A NAV_WAYPOINT is reached within its acceptance radius (param2, else WP_RADIUS) or when the
vehicle has passed the line through the waypoint perpendicular to the leg (ArduPlane's
"passed waypoint"); loiters complete after param1 seconds or turns once on the circle;
DO_JUMP and DO_CHANGE_SPEED run when they become current. After the last item the mission
is complete (the autopilot then switches to RTL, as ArduPlane does).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from gcs_ppf.mavlink import enums
from sitl import mission_protocol as mp
from sitl.physics import GuidanceKind

Vec3 = tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class NavTarget:
    """Where the guidance flies: a point to pursue or a circle to loiter on (ICS metres)."""

    kind: GuidanceKind
    pos_enu_m: Vec3
    radius_m: float = 60.0
    direction: float = 1.0  # +1 clockwise (ArduPlane's positive loiter radius)


@dataclass
class AutoEvents:
    """What happened during one AUTO update."""

    reached: list[int] = field(default_factory=list)
    speed_changes: list[tuple[int, float]] = field(default_factory=list)  # (type, m/s)
    complete: bool = False
    landed: bool = False


@dataclass
class MissionRunner:
    """Progress through a mission. ``targets[k]`` is item k's ICS position (None if it has
    none; x and y NaN for "here", latitude = longitude = 0, as ArduPilot reads it)."""

    items: list[mp.MissionItem]
    targets: list[Vec3 | None]
    current: int = 1
    active: bool = False
    _leg_start: Vec3 = (0.0, 0.0, 0.0)
    _goal: Vec3 = (0.0, 0.0, 0.0)
    _start_s: float = 0.0
    _on_circle_s: float | None = None
    _turned_rad: float = 0.0
    _last_yaw: float = 0.0
    _jumps_done: dict[int, int] = field(default_factory=dict)

    @property
    def count(self) -> int:
        return len(self.items)

    def restart(self) -> None:
        self.current = 1
        self.active = False
        self._jumps_done.clear()

    def set_current(self, seq: int) -> bool:
        if not 1 <= seq < max(self.count, 1):
            return False
        self.current = seq
        self.active = False
        return True

    # ------------------------------------------------------------------------------------
    def begin(self, pos: Vec3, yaw: float, now_s: float, events: AutoEvents) -> None:
        """Make ``current`` a navigation item, running DO items on the way."""
        guard = 0
        while self.current < self.count and guard < 1000:
            guard += 1
            item = self.items[self.current]
            if item.command in mp.NAV_COMMANDS:
                break
            if item.command == enums.MAV_CMD_DO_CHANGE_SPEED:
                events.speed_changes.append((int(item.param1), item.param2))
                self.current += 1
            elif item.command == enums.MAV_CMD_DO_JUMP:
                self._jump(item, events)
            else:
                self.current += 1
        if self.current >= self.count:
            events.complete = True
            self.active = False
            return
        self.active = True
        goal = self.targets[self.current]
        if goal is None:
            goal = pos
        elif math.isnan(goal[0]):  # lat = lon = 0: here, at the item's altitude
            goal = (pos[0], pos[1], goal[2])
        if self.items[self.current].command == enums.MAV_CMD_NAV_TAKEOFF:
            goal = (pos[0] + 1e4 * math.cos(yaw), pos[1] + 1e4 * math.sin(yaw), goal[2])
        self._goal = goal
        self._leg_start = pos
        self._start_s = now_s
        self._on_circle_s = None
        self._turned_rad = 0.0
        self._last_yaw = yaw

    def _jump(self, item: mp.MissionItem, events: AutoEvents) -> None:
        target = int(item.param1)
        repeat = int(item.param2)
        done = self._jumps_done.get(self.current, 0)
        if 1 <= target < self.count and (repeat < 0 or done < repeat):
            self._jumps_done[self.current] = done + 1
            self.current = target
        else:
            self.current += 1

    def target(self, home: Vec3, wp_loiter_rad: float) -> NavTarget:
        """Navigation target of the current item."""
        if not self.active or self.current >= self.count:
            return NavTarget(GuidanceKind.ORBIT, home, abs(wp_loiter_rad), _dir(wp_loiter_rad))
        item = self.items[self.current]
        tgt = self._goal
        cmd = item.command
        if cmd == enums.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return NavTarget(GuidanceKind.ORBIT, home, abs(wp_loiter_rad), _dir(wp_loiter_rad))
        if cmd in (enums.MAV_CMD_NAV_LOITER_UNLIM, enums.MAV_CMD_NAV_LOITER_TIME):
            radius = item.param3 if item.param3 != 0 else wp_loiter_rad
            return NavTarget(GuidanceKind.ORBIT, tgt, abs(radius), _dir(radius))
        if cmd == enums.MAV_CMD_NAV_LOITER_TURNS:
            radius = item.param3 if item.param3 != 0 else wp_loiter_rad
            return NavTarget(GuidanceKind.ORBIT, tgt, abs(radius), _dir(radius))
        return NavTarget(GuidanceKind.GOTO, tgt)

    def update(
        self,
        home: Vec3,
        pos: Vec3,
        yaw: float,
        loiter_radius_eff_m: float,
        wp_radius_m: float,
        now_s: float,
        landed: bool,
    ) -> AutoEvents:
        """Check whether the current item is done; if so advance (events say what happened)."""
        events = AutoEvents()
        if not self.active:
            return events
        item = self.items[self.current]
        tgt = self._goal
        if item.command == enums.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            tgt = home
        dx, dy = tgt[0] - pos[0], tgt[1] - pos[1]
        dist = math.hypot(dx, dy)
        done = False
        cmd = item.command
        if cmd == enums.MAV_CMD_NAV_WAYPOINT:
            accept = item.param2 if item.param2 > 0 else wp_radius_m
            lx, ly = tgt[0] - self._leg_start[0], tgt[1] - self._leg_start[1]
            passed = (lx * lx + ly * ly) > 1.0 and (-dx * lx - dy * ly) > 0.0
            done = dist <= accept or passed
        elif cmd == enums.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            done = dist <= max(wp_radius_m, loiter_radius_eff_m * 1.2)
        elif cmd == enums.MAV_CMD_NAV_TAKEOFF:
            done = pos[2] >= tgt[2] - 5.0
        elif cmd == enums.MAV_CMD_NAV_LAND:
            done = landed
            events.landed = landed
        elif cmd in (enums.MAV_CMD_NAV_LOITER_TIME, enums.MAV_CMD_NAV_LOITER_TURNS):
            on_circle = abs(dist - loiter_radius_eff_m) < max(0.25 * loiter_radius_eff_m, 20.0)
            if self._on_circle_s is None and on_circle:
                self._on_circle_s = now_s
                self._turned_rad = 0.0
            if self._on_circle_s is not None:
                step = math.remainder(yaw - self._last_yaw, math.tau)
                self._turned_rad += abs(step)
                if cmd == enums.MAV_CMD_NAV_LOITER_TIME:
                    done = now_s - self._on_circle_s >= max(item.param1, 0.0)
                else:
                    done = self._turned_rad >= math.tau * max(item.param1, 0.0)
        self._last_yaw = yaw
        if done:
            events.reached.append(self.current)
            self.current += 1
            self.begin(pos, yaw, now_s, events)
            if events.complete:
                self.current = max(self.count - 1, 1) if self.count > 1 else 0
        return events


def _dir(radius: float) -> float:
    return -1.0 if radius < 0 else 1.0

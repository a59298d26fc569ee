"""Telemetry stream scheduling of one vehicle's link, in simulated time.

Streams flow by default (MAVSDK never sends REQUEST_DATA_STREAM); REQUEST_DATA_STREAM sets
the rate of an ArduPilot stream group and MAV_CMD_SET_MESSAGE_INTERVAL the interval of one
message. Every client of a vehicle port shares one schedule, as clients of one ArduPilot
serial link do.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

HEARTBEAT = 0
SYS_STATUS = 1
SYSTEM_TIME = 2
GPS_RAW_INT = 24
ATTITUDE = 30
GLOBAL_POSITION_INT = 33
MISSION_CURRENT = 42
VFR_HUD = 74
POSITION_TARGET_GLOBAL_INT = 87
FENCE_STATUS = 162
AUTOPILOT_VERSION = 148
HOME_POSITION = 242
EXTENDED_SYS_STATE = 245

#: Default rates in Hz (simulated time).
DEFAULT_RATES_HZ: dict[int, float] = {
    HEARTBEAT: 1.0,
    SYS_STATUS: 1.0,
    GPS_RAW_INT: 2.0,
    GLOBAL_POSITION_INT: 10.0,
    ATTITUDE: 10.0,
    VFR_HUD: 4.0,
    SYSTEM_TIME: 1.0,
    EXTENDED_SYS_STATE: 1.0,
    MISSION_CURRENT: 1.0,
    POSITION_TARGET_GLOBAL_INT: 1.0,
    FENCE_STATUS: 1.0,  # sent only while a fence is enabled, as ArduPlane does
    HOME_POSITION: 0.0,
}

#: REQUEST_DATA_STREAM groups (MAV_DATA_STREAM) → messages, as ArduPilot groups them.
STREAM_GROUPS: dict[int, tuple[int, ...]] = {
    2: (SYS_STATUS, GPS_RAW_INT, MISSION_CURRENT, POSITION_TARGET_GLOBAL_INT, FENCE_STATUS),
    6: (GLOBAL_POSITION_INT,),  # POSITION
    10: (ATTITUDE,),  # EXTRA1
    11: (VFR_HUD,),  # EXTRA2
    12: (SYSTEM_TIME, EXTENDED_SYS_STATE),  # EXTRA3
}
STREAM_GROUPS[0] = tuple(m for group in STREAM_GROUPS.values() for m in group)  # ALL

#: Highest rate accepted, Hz (ArduPilot caps streams near its loop rate; ours is 50 Hz).
MAX_RATE_HZ = 50.0


@dataclass
class StreamSchedule:
    """Interval (seconds, 0 = off) and next due time of each streamed message."""

    interval_s: dict[int, float] = field(default_factory=dict)
    next_due_s: dict[int, float] = field(default_factory=dict)
    _earliest_s: float = 0.0

    @classmethod
    def default(cls, now_s: float = 0.0) -> StreamSchedule:
        sched = cls()
        for msg_id, hz in DEFAULT_RATES_HZ.items():
            sched.set_rate(msg_id, hz, now_s)
        return sched

    def supports(self, msg_id: int) -> bool:
        return msg_id in DEFAULT_RATES_HZ

    def set_rate(self, msg_id: int, hz: float, now_s: float) -> None:
        hz = min(max(hz, 0.0), MAX_RATE_HZ) if math.isfinite(hz) else 0.0
        self.interval_s[msg_id] = 1.0 / hz if hz > 0 else 0.0
        self.next_due_s[msg_id] = now_s
        self._earliest_s = min(self._earliest_s, now_s)

    def set_interval_us(self, msg_id: int, interval_us: float, now_s: float) -> bool:
        """MAV_CMD_SET_MESSAGE_INTERVAL semantics: −1 off, 0 default, >0 interval (µs)."""
        if msg_id not in DEFAULT_RATES_HZ or not math.isfinite(interval_us):
            return False
        if interval_us < 0:
            self.set_rate(msg_id, 0.0, now_s)
        elif interval_us == 0:
            self.set_rate(msg_id, DEFAULT_RATES_HZ[msg_id], now_s)
        else:
            self.set_rate(msg_id, 1e6 / interval_us, now_s)
        return True

    def interval_us(self, msg_id: int) -> int:
        """MESSAGE_INTERVAL.interval_us: −1 when off."""
        interval = self.interval_s.get(msg_id, 0.0)
        return round(interval * 1e6) if interval > 0 else -1

    def request_data_stream(self, stream_id: int, hz: float, start: bool, now_s: float) -> None:
        for msg_id in STREAM_GROUPS.get(stream_id, ()):
            self.set_rate(msg_id, hz if start else 0.0, now_s)

    def due(self, now_s: float) -> list[int]:
        """Messages due at ``now_s``; their next due times move on by one interval."""
        if now_s < self._earliest_s:
            return []
        out: list[int] = []
        earliest = math.inf
        for msg_id, interval in self.interval_s.items():
            if interval <= 0:
                continue
            nxt = self.next_due_s[msg_id]
            if nxt <= now_s + 1e-9:
                out.append(msg_id)
                nxt += interval
                if nxt <= now_s:  # fell behind: do not burst
                    nxt = now_s + interval
                self.next_due_s[msg_id] = nxt
            earliest = min(earliest, nxt)
        self._earliest_s = earliest
        return out

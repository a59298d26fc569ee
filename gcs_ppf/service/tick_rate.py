"""Whether the flown loop keeps its rate: each tick's work (its phases, decoding since the
last one included, ``service.tick_phases``) against its period, and the rate the ticks
come at, in the vehicles' seconds.

A tick whose work outlasts its period makes the next one late: the service then ticks
slower than ``tick_hz``, plans from older telemetry, and the lag accounting widens the
margins by what it measures (``guidance.lag``).  That is said, not left silent: a
``tick_overrun`` event when the ticks start overrunning, ``tick_rate_kept`` once
``KEPT_AFTER_TICKS`` ticks in a row have kept their period again, and the measured rate in
the status (``tick_rate``) and on the operator's page.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any

RATE_WINDOW_S = 5.0
"""Vehicle seconds of the latest ticks the measured rate is over."""
KEPT_AFTER_TICKS = 20
"""Ticks in a row within their period after which an overrunning loop has kept its rate
again (2 s at 10 Hz: no event chatter while it hovers at its limit)."""


@dataclass
class TickRate:
    """The ticks' rate and overruns over a run (vehicle seconds; work in ours × the
    vehicles' clock rate)."""

    target_hz: float
    times_s: deque[float] = field(default_factory=deque)
    """Vehicle times of the ticks within the last ``RATE_WINDOW_S``."""
    overruns: int = 0
    """Ticks whose work outlasted their period, over the run."""
    overrunning: bool = False
    """Since a ``tick_overrun``, until ``KEPT_AFTER_TICKS`` ticks in a row kept their period."""
    on_time: int = 0
    """Ticks in a row within their period, lately."""
    last_work_s: float = 0.0
    """The latest tick's work (vehicle seconds)."""

    @property
    def period_s(self) -> float:
        return 1.0 / self.target_hz

    def update(self, now_s: float, work_s: float) -> str | None:
        """One tick at vehicle time ``now_s`` that worked ``work_s`` (vehicle seconds): the
        event it raises (``tick_overrun``, ``tick_rate_kept``), or None."""
        self.times_s.append(now_s)
        while self.times_s and self.times_s[0] < now_s - RATE_WINDOW_S:
            self.times_s.popleft()
        self.last_work_s = work_s
        if work_s > self.period_s:
            self.overruns += 1
            self.on_time = 0
            if not self.overrunning:
                self.overrunning = True
                return "tick_overrun"
            return None
        self.on_time += 1
        if self.overrunning and self.on_time >= KEPT_AFTER_TICKS:
            self.overrunning = False
            return "tick_rate_kept"
        return None

    def measured_hz(self) -> float | None:
        """Ticks per vehicle second over the last ``RATE_WINDOW_S``; None before two."""
        if len(self.times_s) < 2 or self.times_s[-1] <= self.times_s[0]:
            return None
        return (len(self.times_s) - 1) / (self.times_s[-1] - self.times_s[0])

    def as_dict(self) -> dict[str, Any]:
        """The status's ``tick_rate``."""
        hz = self.measured_hz()
        return {
            "target_hz": self.target_hz,
            "measured_hz": None if hz is None else round(hz, 2),
            "overrunning": self.overrunning,
            "overruns": self.overruns,
            "last_work_s": round(self.last_work_s, 4),
        }

    def event_detail(self) -> dict[str, Any]:
        """What a ``tick_overrun`` or ``tick_rate_kept`` event says."""
        hz = self.measured_hz()
        return {
            "work_s": round(self.last_work_s, 3),
            "period_s": round(self.period_s, 3),
            "measured_hz": None if hz is None else round(hz, 2),
            "target_hz": self.target_hz,
            "overruns": self.overruns,
        }

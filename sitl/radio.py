"""A telemetry radio's bytes per second: what a 57,600-baud SiK link carries, and what it
drops when more is offered than fits.

A serial line at BAUD baud, 8N1, carries BAUD / 10 bytes a second each way.  A radio takes
bytes into a buffer and sends them at that rate; offered faster, its buffer fills and what
does not fit is lost (a SiK radio drops bytes; here whole frames, as the SITL writes them).
Time is the simulation's, so a budget holds at every speed-up.
"""

from __future__ import annotations

from dataclasses import dataclass

BITS_PER_BYTE = 10
"""A start bit, 8 data bits, a stop bit (8N1)."""
BUFFER_S = 0.5
"""The radio's buffer, in seconds of its rate (a modelling choice: a burst of this much
passes, a steady excess is dropped)."""


@dataclass
class RadioBudget:
    """One direction of one radio link: ``admit`` a frame of ``n`` bytes at ``now_s``."""

    baud: int
    level_bytes: float = 0.0
    last_s: float | None = None
    dropped_bytes: int = 0
    passed_bytes: int = 0

    @property
    def bytes_per_s(self) -> float:
        return self.baud / BITS_PER_BYTE

    def admit(self, n: int, now_s: float) -> bool:
        """True if the frame fits (sent), False if the buffer is full (dropped)."""
        if self.last_s is not None:
            drained = max(now_s - self.last_s, 0.0) * self.bytes_per_s
            self.level_bytes = max(self.level_bytes - drained, 0.0)
        self.last_s = now_s
        if self.level_bytes + n > BUFFER_S * self.bytes_per_s:
            self.dropped_bytes += n
            return False
        self.level_bytes += n
        self.passed_bytes += n
        return True

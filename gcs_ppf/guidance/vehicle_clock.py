"""How fast a vehicle's clock runs against ours.

Timeouts of CONVENTIONS §5 are in vehicle time: a SITL at ``--speedup K`` lives K seconds
per wall second, so 5 s of its silence pass in 5/K s of ours.  The vehicle's clock is the
``time_boot_ms`` it stamps on its messages; its rate is measured over at least
``MIN_SPAN_S`` of our (monotonic) clock, and taken as the median of the last
``RATES_KEPT`` measurements: a ground station busy with something else reads messages late
by a varying amount, which put single measurements 30–40 % low (measured at ×10 under load:
6.3 for 10.4, a dead leader declared lost after 8.4 of its seconds, not 5).  Pure: the
caller passes both clocks in.
"""

from __future__ import annotations

import statistics
from collections import deque
from dataclasses import dataclass, field

MIN_SPAN_S = 1.0
"""Our seconds between two rate measurements."""
RATES_KEPT = 5
"""Measurements the rate is the median of."""


@dataclass
class VehicleClock:
    """Rate of one vehicle's clock; never taken slower than ours (a stalled or slow clock
    must not delay noticing a silent vehicle beyond the timeout in our seconds)."""

    rate: float = 1.0
    """Vehicle seconds per second of ours (≥ 1)."""
    _anchor_s: float | None = None
    _anchor_boot_ms: int = 0
    _rates: deque[float] = field(default_factory=lambda: deque(maxlen=RATES_KEPT))

    @property
    def measured(self) -> bool:
        """Its rate has been measured (``MIN_SPAN_S`` after it was first heard)."""
        return bool(self._rates)

    def observe(self, now_s: float, time_boot_ms: int) -> None:
        """A message stamped ``time_boot_ms`` arrived at our ``now_s``."""
        if self._anchor_s is None or time_boot_ms < self._anchor_boot_ms:  # first, or reboot
            self._anchor_s, self._anchor_boot_ms = now_s, time_boot_ms
            self._rates.clear()
            return
        span = now_s - self._anchor_s
        if span >= MIN_SPAN_S:
            self._rates.append((time_boot_ms - self._anchor_boot_ms) / 1000.0 / span)
            self.rate = max(1.0, statistics.median(self._rates))
            self._anchor_s, self._anchor_boot_ms = now_s, time_boot_ms

    def vehicle_seconds(self, our_seconds: float) -> float:
        """How long ``our_seconds`` of ours last on this vehicle's clock."""
        return our_seconds * self.rate

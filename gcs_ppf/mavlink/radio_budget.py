"""What the service's traffic with one vehicle costs a telemetry radio, and the rate that
fits a radio carrying several: pure arithmetic on bytes a second.

A serial line at BAUD baud, 8N1, carries BAUD / 10 bytes a second each way.  Per vehicle the
service's traffic is a fixed part (heartbeats, SYS_STATUS, SYSTEM_TIME, VFR_HUD's share,
TIMESYNC, the parameters) and a part that grows with the rate r at which positions stream
and ticks command: the positions and the course, altitude and speed commands with their
COMMAND_ACKs.  Fitted to what the built-in SITL's radios measured (Table 3 on serial links,
``GET /links`` byte counts, docs/service.md#telemetry-radios): 1.6 kB/s down and 0.97 kB/s
up a vehicle at 10 Hz; five vehicles on one 57,600-baud radio at 5 Hz, 91–95 % of it down
and 50–53 % up.
"""

from __future__ import annotations

DOWN_FIXED_B_S = 540.0
"""Bytes a second a vehicle sends whatever the rate."""
DOWN_PER_HZ_B = 106.0
"""Bytes a vehicle sends per hertz of the position stream and tick (positions, acks)."""
UP_FIXED_B_S = 210.0
"""Bytes a second the service sends a vehicle whatever the rate."""
UP_PER_HZ_B = 76.0
"""Bytes the service sends a vehicle per hertz of its tick (its commands)."""
FULL = 0.9
"""The share of a radio's bytes the traffic is fitted to (beyond it a SiK radio's buffer
fills and it drops what does not fit; the service warns from it on)."""
MIN_RATE_HZ = 1.0
"""No fit goes below this: a radio that cannot carry it carries too many vehicles."""


def bytes_per_s(rate_hz: float) -> tuple[float, float]:
    """A vehicle's traffic (down, up), bytes a second, at ``rate_hz``."""
    return DOWN_FIXED_B_S + DOWN_PER_HZ_B * rate_hz, UP_FIXED_B_S + UP_PER_HZ_B * rate_hz


def fitted_rate_hz(baud: int, vehicles: int, wanted_hz: float) -> float:
    """The position stream and tick rate (at most ``wanted_hz``, at least ``MIN_RATE_HZ``)
    at which ``vehicles`` vehicles fill a radio of ``baud`` baud to ``FULL`` at most, either
    way; a tenth of a hertz down."""
    if vehicles <= 0:
        return wanted_hz
    each = FULL * baud / 10.0 / vehicles
    down = (each - DOWN_FIXED_B_S) / DOWN_PER_HZ_B
    up = (each - UP_FIXED_B_S) / UP_PER_HZ_B
    fit = int(min(down, up) * 10.0) / 10.0
    return min(wanted_hz, max(fit, MIN_RATE_HZ))

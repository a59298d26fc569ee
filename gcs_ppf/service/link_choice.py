"""One vehicle heard on two links (a telemetry radio and a backup): whether it is one vehicle
or two with one system id, and which link commands it.

Pure: fed with what each link carried of the vehicle, it decides; ``service.fleet`` keeps
the record and sends on the link chosen.  One vehicle reports the same position at the same
``time_boot_ms`` on every link, however late a slow link brings it; two vehicles with one
id report different positions at the same time.  The link that commands it is the one that
keeps up with it: it stays while it does, and gives way when another carries the vehicle's
clock ``BEHIND_S`` further on (a radio unplugged or out of range falls silent, one carrying
more than its baud rate falls behind), then stays at least ``DWELL_S``.  Compared by their
message counts instead, two links of a vehicle at ×10 took turns every few tenths of a
second: the ground station reads one link's burst before the other's.
"""

from __future__ import annotations

import bisect
import math
from collections import deque
from dataclasses import dataclass, field

SAME_CLOCK_MS = 500
"""A position on one link is compared with the other link's nearest in time, at most this
far apart on the vehicle's clock (positions come at 10 Hz: five periods)."""
SAME_PLACE_M = 50.0
"""Two positions of one vehicle are at most this far apart, besides its travel between
their times."""
FASTEST_M_S = 350.0
"""The travel allowance's speed: faster than any vehicle of a mission (Table 3's 300 m/s)."""
FIXES_KEPT = 300
"""Positions kept per link: 30 s at 10 Hz, the furthest one link may lag another."""
BEHIND_S = 0.5
"""Vehicle seconds another link may carry the vehicle's clock ahead of the commanding link
(five positions at 10 Hz) before the commands move to it ..."""
BEHIND_OURS_S = 0.25
"""... and at least this many of ours: the ground station reads its links one burst at a
time (at ×10, a link's 0.5 vehicle seconds come in one read)."""
DWELL_S = 2.0
"""Our seconds a link keeps the commands once given them, unless it falls silent for good."""
EARTH_RADIUS_M = 6_371_000.0


@dataclass(frozen=True, slots=True)
class Fix:
    """A position the vehicle reported on a link: its clock (ms) and where (degrees)."""

    boot_ms: int
    lat_deg: float
    lon_deg: float


@dataclass
class LinkSeen:
    """The positions one link carried of one vehicle (the last ``FIXES_KEPT``, in the order
    they came)."""

    fixes: deque[Fix] = field(default_factory=lambda: deque(maxlen=FIXES_KEPT))

    @property
    def fix(self) -> Fix | None:
        """The latest position it carried."""
        return self.fixes[-1] if self.fixes else None

    def nearest(self, boot_ms: int) -> Fix | None:
        """Its position nearest in time to ``boot_ms`` (None: it carried none)."""
        if not self.fixes:
            return None
        times = [f.boot_ms for f in self.fixes]
        k = bisect.bisect_left(times, boot_ms)
        near = [self.fixes[j] for j in (k - 1, k) if 0 <= j < len(times)]
        return min(near, key=lambda f: abs(f.boot_ms - boot_ms))


def apart_m(a: Fix, b: Fix) -> float:
    """Horizontal distance between two fixes (equirectangular: metres apart matter here)."""
    lat = math.radians((a.lat_deg + b.lat_deg) / 2.0)
    dx = math.radians(b.lon_deg - a.lon_deg) * math.cos(lat) * EARTH_RADIUS_M
    dy = math.radians(b.lat_deg - a.lat_deg) * EARTH_RADIUS_M
    return math.hypot(dx, dy)


def same_vehicle(links: list[LinkSeen]) -> bool | None:
    """Whether the links carry one vehicle: for each pair, the latest position of the one
    behind, and the other's nearest to it in time, within ``SAME_CLOCK_MS`` on the clock
    and ``SAME_PLACE_M`` plus the travel between them in place.  None: not known (a link
    without a position yet, or none of the other's near it in time)."""
    for i, a in enumerate(links):
        for b in links[i + 1 :]:
            fa, fb = a.fix, b.fix
            if fa is None or fb is None:
                return None
            behind, other = (fa, b) if fa.boot_ms <= fb.boot_ms else (fb, a)
            match = other.nearest(behind.boot_ms)
            if match is None or abs(match.boot_ms - behind.boot_ms) > SAME_CLOCK_MS:
                return None
            travel = FASTEST_M_S * abs(match.boot_ms - behind.boot_ms) / 1000.0
            if apart_m(behind, match) > SAME_PLACE_M + travel:
                return False
    return True


def better_link(
    current: int,
    seen: dict[int, LinkSeen],
    live: tuple[int, ...],
    clock_rate: float,
    since_switch_s: float,
) -> tuple[int, str | None]:
    """The link to command the vehicle on, of the ``live`` ones, and why it changed
    (``"gone"``: the commanding link is not live; ``"behind"``; None: it did not).
    ``clock_rate``: the vehicle's seconds per ours; ``since_switch_s``: our seconds since
    the commands last moved."""

    def clock_ms(lid: int) -> float:
        fix = seen[lid].fix if lid in seen else None
        return -math.inf if fix is None else fix.boot_ms

    others = [lid for lid in live if lid != current]
    if not others:
        return current, None
    ahead = max(others, key=clock_ms)
    if current not in live:
        return ahead, "gone"
    if since_switch_s < DWELL_S:
        return current, None
    behind_ms = 1000.0 * max(BEHIND_S, BEHIND_OURS_S * clock_rate)
    if clock_ms(ahead) - clock_ms(current) > behind_ms:
        return ahead, "behind"
    return current, None

"""The SITL's clock under a starved CPU: it slips, as ArduPilot's SITL does, rather than
flying seconds of vehicle time in one burst once it gets the CPU back."""

from __future__ import annotations

import asyncio
import time

import pytest

from sitl.physics import DT_S
from sitl.server import MAX_CATCH_UP_S, MAX_STEPS_UNREAD, pace

pytestmark = pytest.mark.realtime  # what is flown in 50 ms of wall time


class StalledSim:
    """A simulation whose steps are free, and whose process loses the CPU for ``stall_s``
    of wall time (the event loop blocked) at its ``stall_at`` step; records the wall time
    of every step."""

    def __init__(self, stall_at: int, stall_s: float) -> None:
        self.sim_s = 0.0
        self.steps: list[tuple[float, float]] = []
        self._stall_at, self._stall_s = stall_at, stall_s

    def step(self, now: float) -> list[tuple[int, object]]:
        if len(self.steps) == self._stall_at:
            time.sleep(self._stall_s)  # the CPU taken away: nothing runs meanwhile
        self.sim_s += DT_S
        self.steps.append((time.monotonic(), self.sim_s))
        return []


def test_a_stalled_sitl_catches_up_at_most_max_catch_up_of_wall_time() -> None:
    speedup = 10.0
    sim = StalledSim(stall_at=20, stall_s=0.6)
    stop = asyncio.Event()

    async def main() -> None:
        async with asyncio.timeout(10.0):
            await pace(sim, [], speedup, stop, duration_s=8.0)  # type: ignore[arg-type]

    asyncio.run(main())
    wall = [w for w, _ in sim.steps]
    after = next(k for k in range(1, len(wall)) if wall[k] - wall[k - 1] > 0.5)
    # Simulated time flown in the first 50 ms of wall time after the stall: at most the
    # catch-up allowance and the schedule itself (not the 6 s of vehicle time it missed).
    burst = [s for w, s in sim.steps[after:] if w - wall[after] < 0.05]
    flown = burst[-1] - sim.steps[after - 1][1]
    assert flown <= (MAX_CATCH_UP_S + 0.05) * speedup + MAX_STEPS_UNREAD * DT_S
    assert flown >= MAX_CATCH_UP_S * speedup * 0.5  # it does catch up that much

"""Where a tick's time goes: our seconds (``time.perf_counter``) spent in each phase of the
flown loop, per tick, over the latest ticks, as the status (``tick_phases_ms``) and
``gcs_ppf.tools.service_benchmark`` report them.

A phase counts its own time only: one entered inside another (the store's write inside an
event, an event inside the commanding) is taken out of the outer one, so that the phases of
a tick add up to its work.  Decoding is not inside a tick: it is the reading and decoding of
MAVLink the links did since the last tick (``Fleet.decoding_s``).
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np

PHASES: dict[str, str] = {
    "decoding": "MAVLink read and decoded into each vehicle's telemetry, since the last tick",
    "prediction": "positions to the ICS, on one instant, and carried on to when commands act",
    "monitoring": "the safety monitor, the formation watch, the run's separations",
    "planning": "the tick's plan (PPF, the separation guard) and the speed reference",
    "assurance": "every command judged by the run-time assurance (escapes searched)",
    "confirmation": "losses and obedience: which vehicles fly the commands they were sent",
    "commanding": "commands built and handed to the links",
    "storage": "the store's writes (events, sampled telemetry)",
    "events": "the run's events (logged) and the live stream's snapshot",
}
"""The phases, in the order a tick runs them, with what each one counts."""

TICKS_KEPT = 200
"""Ticks the percentiles are over (20 s at 10 Hz)."""


class TickPhases:
    """Each phase's own time in the tick under way, and in the latest ``TICKS_KEPT``."""

    def __init__(self) -> None:
        self._now = dict.fromkeys(PHASES, 0.0)
        self._inner = [0.0]  # time of the phases inside each phase under way, innermost last
        self.recent: deque[dict[str, float]] = deque(maxlen=TICKS_KEPT)

    @contextmanager
    def phase(self, name: str) -> Iterator[None]:
        """Time the block as ``name`` (its own time: phases inside it are theirs)."""
        start = time.perf_counter()
        self._inner.append(0.0)
        try:
            yield
        finally:
            elapsed = time.perf_counter() - start
            inner = self._inner.pop()
            self._now[name] += elapsed - inner
            self._inner[-1] += elapsed

    def begin_tick(self) -> None:
        """A tick begins: what was timed since the last one ended (between ticks) is not its."""
        self._now = dict.fromkeys(PHASES, 0.0)
        self._inner = [0.0]

    def add(self, name: str, seconds: float) -> None:
        """``seconds`` more of ``name`` in the tick under way (measured elsewhere)."""
        self._now[name] += seconds

    def end_tick(self) -> dict[str, float]:
        """The tick under way is done: its phases, kept; the next one starts at zero."""
        done, self._now = self._now, dict.fromkeys(PHASES, 0.0)
        self._inner = [0.0]
        self.recent.append(done)
        return done

    def summary_ms(self) -> dict[str, dict[str, float]] | None:
        """Per phase, its p50, p99 and mean over the latest ticks (ms); None before any."""
        if not self.recent:
            return None
        out = {}
        for name in PHASES:
            ms = np.array([t[name] for t in self.recent]) * 1e3
            out[name] = {
                "p50": round(float(np.percentile(ms, 50)), 3),
                "p99": round(float(np.percentile(ms, 99)), 3),
                "mean": round(float(ms.mean()), 3),
            }
        return out

"""Lag, measured: how old the telemetry a tick plans from is and how late its commands take
effect, in each vehicle's own seconds, and whether that stays within the budget.

Pure.  A position is ``age`` old when the tick reads it (since it arrived) plus the downlink
(half the link's TIMESYNC round trip); a command takes effect after the tick's own work plus
the uplink (the other half).  Flown at 10× a tick's 20 ms of wall time is 200 ms of vehicle
time; a telemetry radio adds hundreds of milliseconds each way: the planner plans from the
states carried on to the moment its commands arrive (``Lag.total_s``), and the margins grow
by what that lag can cost.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

RELEASE_FRACTION = 0.8
"""Back within the budget once under this fraction of it (no event chatter at the edge)."""


@dataclass(frozen=True, slots=True)
class Lag:
    """One vehicle's lag at one tick, vehicle seconds."""

    telemetry_age_s: float
    """Since the vehicle sampled the position planned from: age since arrival + downlink."""
    command_delay_s: float
    """Until a command sent now acts: the tick's own work + uplink."""

    @property
    def total_s(self) -> float:
        """From the state planned from to the moment the command acts on it."""
        return self.telemetry_age_s + self.command_delay_s

    def as_dict(self) -> dict[str, float]:
        return {
            "telemetry_age_s": round(self.telemetry_age_s, 3),
            "command_delay_s": round(self.command_delay_s, 3),
            "total_s": round(self.total_s, 3),
        }


def vehicle_lag(
    age_since_arrival_s: float, round_trip_s: float | None, tick_work_s: float, rate: float
) -> Lag:
    """A vehicle's lag from our measurements (our seconds; ``rate``: its seconds per ours).
    Without a round trip measured yet, the link counts as instantaneous."""
    half_trip = 0.0 if round_trip_s is None else 0.5 * round_trip_s
    return Lag((age_since_arrival_s + half_trip) * rate, (tick_work_s + half_trip) * rate)


def hold_s(
    tick_gaps_s: Iterable[float],
    tick_period_s: float,
    telemetry_interval_s: float,
    lag: Lag,
    starvation_s: float = 0.0,
) -> float:
    """How long a vehicle may fly the command it is sent now (vehicle seconds): until the
    next tick's command acts, the tick coming as late as the latest ticks came
    (``tick_gaps_s``: a ground station starved of CPU ticked 1.5–3 s of vehicle time apart
    at 5×, where the period is 0.1 s) and at least ``starvation_s`` late (the service's
    allowance for being starved, in vehicle seconds: a first stall comes after ticks on
    time), from a state as old as a telemetry interval, and that command as late as this
    one."""
    gap = max(max(tick_gaps_s, default=0.0), tick_period_s + starvation_s)
    return gap + telemetry_interval_s + lag.command_delay_s


def worst(lags: list[Lag]) -> Lag:
    """The fleet's lag: each part at its worst vehicle."""
    if not lags:
        return Lag(0.0, 0.0)
    return Lag(max(x.telemetry_age_s for x in lags), max(x.command_delay_s for x in lags))


@dataclass
class Budget:
    """Whether the fleet's lag stays within ``budget_s`` (vehicle seconds): ``update``
    says when it goes over and when it is back, and keeps the worst seen."""

    budget_s: float
    over: bool = False
    worst_s: float = 0.0

    def update(self, total_s: float) -> str | None:
        """``"lag_over_budget"``, ``"lag_within_budget"`` or None (no change)."""
        self.worst_s = max(self.worst_s, total_s)
        if not self.over and total_s > self.budget_s:
            self.over = True
            return "lag_over_budget"
        if self.over and total_s < RELEASE_FRACTION * self.budget_s:
            self.over = False
            return "lag_within_budget"
        return None

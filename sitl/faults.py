"""Fault injection: link loss, latency, cuts, position noise, vehicle death, ignored commands.

Faults are set per vehicle from the command line (``--fault``) and at run time through the
SIM_* parameters (SIM_LINK_LOSS, SIM_LINK_DELAY, SIM_LINK_CUT, SIM_GPS_NOISE, SIM_KILL,
SIM_CMD_IGNORE). All times are simulated seconds, so a scenario means the same thing at every
speedup; a latency of L ms delays each packet by L / speedup wall milliseconds.

``--fault`` syntax: ``[ID:]key=value[,key=value…]`` with keys ``loss`` (%), ``latency`` (ms),
``noise`` (m, 1σ), ``cut`` (``START+DURATION`` s), ``die`` (s) and ``ignore`` (s). Without
``ID:`` the fault applies to every vehicle.

``ignore=T`` (or SIM_CMD_IGNORE=1 at run time, from that moment; 0 ends it) is an autopilot
stuck on its last command: from simulated second T the vehicle answers every command that
would change how it flies with ACCEPTED (COMMAND_ACK, or MISSION_ACK for a guided
MISSION_ITEM_INT) whatever it carries, and does nothing with it, so it keeps its mode and
flies on what it was last told (its course, altitude, guided point, speed).  Those commands
are ``IGNORED_COMMANDS`` in ``sitl.handlers``: mode changes (SET_MODE, DO_SET_MODE,
MISSION_START, NAV_RETURN_TO_LAUNCH, NAV_LOITER_UNLIM), DO_REPOSITION, the GUIDED slews,
DO_CHANGE_SPEED, DO_SET_MISSION_CURRENT / MISSION_SET_CURRENT, arming and disarming, guided
MISSION_ITEM_INT (current 2 and 3) and SET_POSITION_TARGET_GLOBAL_INT (which is never
acknowledged anyway).  Its telemetry stays true (HEARTBEAT shows the mode it is really in),
and the rest of the link works: parameters, stream requests, the mission protocol (a plan
is stored, not flown differently), so a ground station can only tell from what the vehicle
does.  The autopilot's own decisions go on (the GCS failsafe, AUTO's mission progress).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass
class FaultState:
    """Faults of one vehicle now. ``cuts`` are (start_s, end_s) intervals of simulated time."""

    loss_pct: float = 0.0
    latency_ms: float = 0.0
    noise_m: float = 0.0
    cuts: list[tuple[float, float]] | None = None
    die_at_s: float | None = None
    dead: bool = False
    ignore_from_s: float | None = None

    def ignoring_commands(self, now_s: float) -> bool:
        """True if the vehicle acknowledges but does not act on flight commands now."""
        return self.ignore_from_s is not None and now_s >= self.ignore_from_s

    def link_cut(self, now_s: float) -> bool:
        return any(a <= now_s < b for a, b in self.cuts or ())

    def add_cut(self, start_s: float, duration_s: float) -> None:
        self.cuts = [*(self.cuts or []), (start_s, start_s + duration_s)]

    def update(self, now_s: float) -> bool:
        """Apply scheduled events; True if the vehicle died just now."""
        if not self.dead and self.die_at_s is not None and now_s >= self.die_at_s:
            self.dead = True
            return True
        return False


@dataclass(frozen=True, slots=True)
class FaultSpec:
    """One ``--fault`` option: vehicle id (None = all) and its settings."""

    vehicle_id: int | None
    loss_pct: float | None = None
    latency_ms: float | None = None
    noise_m: float | None = None
    cut: tuple[float, float] | None = None
    die_at_s: float | None = None
    ignore_from_s: float | None = None

    def apply(self, state: FaultState) -> None:
        if self.loss_pct is not None:
            state.loss_pct = self.loss_pct
        if self.latency_ms is not None:
            state.latency_ms = self.latency_ms
        if self.noise_m is not None:
            state.noise_m = self.noise_m
        if self.cut is not None:
            state.add_cut(*self.cut)
        if self.die_at_s is not None:
            state.die_at_s = self.die_at_s
        if self.ignore_from_s is not None:
            state.ignore_from_s = self.ignore_from_s


def _number(key: str, text: str, low: float, high: float) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"--fault {key}: {text!r} is not a number") from None
    if not math.isfinite(value) or not low <= value <= high:
        raise ValueError(f"--fault {key}: {value:g} outside [{low:g}, {high:g}]")
    return value


def parse_fault(text: str) -> FaultSpec:
    """Parse one ``--fault`` value (see the module docstring); ValueError names the key."""
    vehicle_id: int | None = None
    body = text.strip()
    head, sep, rest = body.partition(":")
    if sep and "=" not in head:
        try:
            vehicle_id = int(head)
        except ValueError:
            raise ValueError(f"--fault: vehicle id {head!r} is not an integer") from None
        body = rest
    fields: dict[str, object] = {}
    for part in filter(None, (p.strip() for p in body.split(","))):
        key, eq, value = part.partition("=")
        if not eq:
            raise ValueError(f"--fault: {part!r} is not key=value")
        if key == "loss":
            fields["loss_pct"] = _number(key, value, 0, 100)
        elif key == "latency":
            fields["latency_ms"] = _number(key, value, 0, 600_000)
        elif key == "noise":
            fields["noise_m"] = _number(key, value, 0, 10_000)
        elif key == "die":
            fields["die_at_s"] = _number(key, value, 0, 1e9)
        elif key == "ignore":
            fields["ignore_from_s"] = _number(key, value, 0, 1e9)
        elif key == "cut":
            start, plus, duration = value.partition("+")
            if not plus:
                raise ValueError("--fault cut: expected START+DURATION seconds")
            fields["cut"] = (_number(key, start, 0, 1e9), _number(key, duration, 0, 1e9))
        else:
            raise ValueError(
                f"--fault: unknown key {key!r} (loss, latency, noise, cut, die, ignore)"
            )
    if not fields:
        raise ValueError("--fault: nothing to set")
    return FaultSpec(vehicle_id, **fields)  # type: ignore[arg-type]

"""The formation as a figure of the flight: each wingman's distance from its slot now, whether
the formation is held, when it formed and broke, and the run's formation figures.

Pure: fed, tick by tick, the mission time (vehicle seconds, the clock the service ticks on)
and each wingman's slot error; no clock, no I/O.

* **Slot error** (``slot_errors_m``): the distance from a wingman's reported position to its
  slot carried into the ICS by the leader's flight path, G_i = P_0 + A(ψ0) B(θ0) s_i (Eq. 6,
  ``frames.local_target_point``), with the leader's pitch θ0 and yaw ψ0 from its reported
  velocity (not its attitude: an aircraft flies at an angle of attack and in a crab).
* **In formation**: every wingman measured within ``limits.target_accuracy`` of its slot at
  the same moment (CONVENTIONS §4's ``formation_time_s`` is the first such moment offline).
* **Hysteresis** (``FormationWatch``): the formation *forms* at the first tick every wingman
  is within the accuracy, and *breaks* only once the worst wingman has stayed out of it for
  ``BREAK_AFTER_S`` of mission time; an excursion shorter than that is forgiven, so that
  noise at the threshold raises no events.  A broken formation is dated back to the tick
  the worst wingman first went out: that is when the hold ended, and the ticks of a failed
  grace count as out of formation.  A tick with no wingman measured (every one lost, or the
  leader without a velocity), or with a wingman that counts left unmeasured, is out of
  formation; the service counts every wingman not lost.

Figures of a run (``Figures``), over the ticks fed:

* ``time_to_form_s``: mission time of the first forming (None if never);
* ``fraction_in_formation``: the time in formation (holds, their forgiven excursions
  included) over the time since the first forming;
* ``rms_slot_error_m``, ``p95_slot_error_m``: over every wingman's slot error at every tick
  in formation (per tick, not per second: the service ticks at a steady rate);
* ``longest_hold_s``: the longest hold, from a forming to its break (or to the last tick);
* ``holds``: how many times it formed.
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from gcs_ppf.frames import attitude_of, local_target_point

BREAK_AFTER_S = 1.0
"""Mission seconds the worst wingman must stay out of the target accuracy before the
formation counts as broken (10 ticks at 10 Hz): a wingman a metre either side of the
threshold, as measured positions jitter, raises no events."""

MIN_LEADER_SPEED_M_S = 1.0
"""Below this speed the leader's flight path (and so every slot) is undefined."""

Position = Sequence[float]


def slot_errors_m(
    leader_pos_m: Position,
    leader_velocity_m_s: Position,
    wingmen: Mapping[int, tuple[Position, Position]],
) -> dict[int, float]:
    """Each wingman's distance (m) from its slot (Eq. 6) in the leader's flight-path frame.

    ``leader_pos_m`` and ``leader_velocity_m_s`` are ICS (ENU, m and m/s); ``wingmen`` maps
    a wingman's id to (its ICS position, its mission ``slot`` in the leader's VCS).  Empty
    when the leader's position or velocity is not finite or it flies slower than
    ``MIN_LEADER_SPEED_M_S``; a wingman whose position or slot is not three finite numbers
    is left out."""
    lead = _vector(leader_pos_m)
    velocity = _vector(leader_velocity_m_s)
    if lead is None or velocity is None or float(np.linalg.norm(velocity)) < MIN_LEADER_SPEED_M_S:
        return {}
    pitch_rad, yaw_rad = attitude_of(velocity)
    out: dict[int, float] = {}
    for wingman_id, (pos_m, slot_m) in wingmen.items():
        pos, slot = _vector(pos_m), _vector(slot_m)
        if pos is None or slot is None:
            continue
        point = local_target_point(lead, pitch_rad, yaw_rad, slot)
        out[wingman_id] = float(np.linalg.norm(pos - point))
    return out


def _vector(values: Position) -> np.ndarray[Any, np.dtype[np.float64]] | None:
    try:
        v = np.asarray(values, dtype=float).reshape(3)
    except (TypeError, ValueError):
        return None
    return v if bool(np.all(np.isfinite(v))) else None


@dataclass(frozen=True)
class Change:
    """The formation formed or broke."""

    kind: Literal["formation_formed", "formation_broken"]
    since_s: float
    """Mission time it formed, or the worst wingman first went out of the accuracy."""
    worst_wingman_id: int | None
    """The wingman farthest from its slot at the tick it was noticed (None: none measured)."""
    worst_error_m: float | None


@dataclass(frozen=True)
class Figures:
    """A run's formation figures (see the module docstring)."""

    time_to_form_s: float | None
    fraction_in_formation: float | None
    rms_slot_error_m: float | None
    p95_slot_error_m: float | None
    longest_hold_s: float
    holds: int

    def as_dict(self) -> dict[str, Any]:
        """Rounded for the status, the stream and the stored summary."""
        return {
            "time_to_form_s": _round(self.time_to_form_s, 2),
            "fraction_in_formation": _round(self.fraction_in_formation, 4),
            "rms_slot_error_m": _round(self.rms_slot_error_m, 2),
            "p95_slot_error_m": _round(self.p95_slot_error_m, 2),
            "longest_hold_s": round(self.longest_hold_s, 2),
            "holds": self.holds,
        }


def _round(x: float | None, digits: int) -> float | None:
    return None if x is None else round(x, digits)


class FormationWatch:
    """The formation, fed each tick (``update``): held or not, with hysteresis, and the
    run's figures (``figures``)."""

    def __init__(self, accuracy_m: float, break_after_s: float = BREAK_AFTER_S) -> None:
        self.accuracy_m = accuracy_m
        self.break_after_s = break_after_s
        self.formed = False
        """In formation now (an excursion within its grace still counts)."""
        self.errors_m: dict[int, float] = {}
        """Each measured wingman's slot error at the latest tick."""
        self.mission_time_s: float | None = None
        """The latest tick fed."""
        self._first_formed_s: float | None = None
        self._formed_since_s: float | None = None  # the current hold's start
        self._out_since_s: float | None = None  # the current excursion's start, while formed
        self._held_s = 0.0  # time in the holds already broken
        self._longest_s = 0.0  # the longest hold already broken
        self._holds = 0
        self._formed_errors_m = array("d")  # every wingman's error, every tick in formation
        self._grace_errors_m: list[float] = []  # the same, during the current excursion

    @property
    def worst(self) -> tuple[int, float] | None:
        """(wingman id, its slot error) of the wingman farthest from its slot now."""
        if not self.errors_m:
            return None
        return max(self.errors_m.items(), key=lambda item: (item[1], -item[0]))

    def hold_s(self) -> float:
        """How long the current hold has lasted (0 when not in formation)."""
        if not self.formed or self._formed_since_s is None or self.mission_time_s is None:
            return 0.0
        return self.mission_time_s - self._formed_since_s

    def update(
        self, mission_time_s: float, slot_errors_m: Mapping[int, float], unmeasured: int = 0
    ) -> list[Change]:
        """One tick: ``slot_errors_m`` maps each wingman measured to its slot error (m);
        ``unmeasured`` wingmen that count but could not be measured (not heard yet) keep the
        formation from being in formation.  Errors that are not finite non-negative numbers
        are left out; a tick earlier than the last one fed, or at a time that is not finite,
        is ignored.  Returns what changed (at most one)."""
        if not math.isfinite(mission_time_s) or (
            self.mission_time_s is not None and mission_time_s < self.mission_time_s
        ):
            return []
        self.mission_time_s = mission_time_s
        self.errors_m = {int(k): float(e) for k, e in slot_errors_m.items() if _is_distance(e)}
        worst = self.worst
        worst_id, worst_m = worst if worst is not None else (None, None)
        within = worst_m is not None and worst_m <= self.accuracy_m and unmeasured <= 0
        errors = list(self.errors_m.values())
        if not self.formed:
            if not within:
                return []
            self.formed = True
            self._formed_since_s = mission_time_s
            self._holds += 1
            if self._first_formed_s is None:
                self._first_formed_s = mission_time_s
            self._formed_errors_m.extend(errors)
            return [Change("formation_formed", mission_time_s, worst_id, worst_m)]
        if within:  # held; an excursion that ended within its grace is forgiven
            self._out_since_s = None
            self._formed_errors_m.extend(self._grace_errors_m)
            self._grace_errors_m.clear()
            self._formed_errors_m.extend(errors)
            return []
        if self._out_since_s is None:
            self._out_since_s = mission_time_s
        self._grace_errors_m.extend(errors)
        if mission_time_s - self._out_since_s < self.break_after_s:
            return []
        since = self._out_since_s
        assert self._formed_since_s is not None
        hold = since - self._formed_since_s
        self._held_s += hold
        self._longest_s = max(self._longest_s, hold)
        self.formed = False
        self._formed_since_s = self._out_since_s = None
        self._grace_errors_m.clear()
        return [Change("formation_broken", since, worst_id, worst_m)]

    def figures(self) -> Figures:
        """The run's formation figures over the ticks fed so far."""
        current = self.hold_s()
        held = self._held_s + current
        fraction = None
        if self._first_formed_s is not None and self.mission_time_s is not None:
            elapsed = self.mission_time_s - self._first_formed_s
            fraction = min(1.0, held / elapsed) if elapsed > 0 else 1.0
        errors = (
            np.frombuffer(self._formed_errors_m, dtype=float) if self._formed_errors_m else None
        )
        return Figures(
            time_to_form_s=self._first_formed_s,
            fraction_in_formation=fraction,
            rms_slot_error_m=None if errors is None else float(np.sqrt(np.mean(errors**2))),
            p95_slot_error_m=None if errors is None else float(np.percentile(errors, 95)),
            longest_hold_s=max(self._longest_s, current),
            holds=self._holds,
        )

    def status(self) -> dict[str, Any]:
        """What the API's status and the live stream show of the formation now."""
        worst = self.worst
        return {
            "formed": self.formed,
            "accuracy_m": self.accuracy_m,
            "wingmen": [
                {"id": k, "slot_error_m": round(e, 2), "within": e <= self.accuracy_m}
                for k, e in sorted(self.errors_m.items())
            ],
            "worst_wingman_id": None if worst is None else worst[0],
            "worst_error_m": None if worst is None else round(worst[1], 2),
            "current_hold_s": round(self.hold_s(), 2),
            **self.figures().as_dict(),
        }


def _is_distance(e: object) -> bool:
    try:
        x = float(e)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False
    return math.isfinite(x) and x >= 0.0

"""Turning in formation: the leader's speed and turn rate that every slot can follow.

A slot is fixed in the leader's frame (Eq. 6), so when the leader turns at ω the slot
s = (x, y) swings round with it: in the leader's frame it moves at (v − ω·y, ω·x), where v
is the leader's speed.  A wingman holds its slot through the turn only if that speed lies
in its envelope, for a turn either way:

    (v + |ω·y|)² + (ω·x)² ≤ v_max²       the slot on the outside of the turn
    v − |ω·y| ≥ v_min                     the slot on the inside

and |ω| ≤ ω_max.  And the turn must not break the formation as it begins: when the leader
rolls in, the slot's speed changes at once by ω·|y|, which the wingman makes good at its
acceleration a (the smaller of accel and decel), falling (ω·y)²/2a behind; no more than
the target accuracy ε:

    ω·|y| ≤ √(2·a·ε)

(planned without it, ArduPlane's 3-vehicle route turned at the first two limits alone
and the wingmen fell 25–33 m off their slots through each turn; with it, 16 m, and 13 m
with each wingman matching its slot's speed rather than the leader's:
``formation.slot_point_speed``).

The paper's leader speeds up to v_max once the formation has formed and turns at ω_max:
no wingman with a lateral offset can then follow it round (the outer one would need more
than v_max), and a leader at v_min leaves the inner one nothing to slow down by.  A leader
that turns in formation therefore cruises at the speed at which the formation can turn
fastest and turns no faster than that (ArduPilot's ``plane_follow.lua`` schedules each
follower's airspeed by the ratio of the turn radii: the same relation seen from the
follower).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from gcs_ppf.planning.ppf.primitives import KernelLimits

SPEED_SAMPLES = 401  # leader speeds tried across [v_min, v_max]
TURN_RATE_FLOOR_SHARE = 0.05
"""A formation that cannot turn at all (v_min = v_max with slots abreast) still turns at
this share of ω_max: its route must be flown, the formation breaking in the turns.  At a
tenth, the floor was above what ArduPlane's five-vehicle V (slots 200 m abreast) holds,
0.0173 rad/s, and turned 100° and 190° it held 63 % and 60 % of the flight after forming
(offline); at its own rate, 92 % and 96 %."""

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class TurnEnvelope:
    """The leader's cruise speed and the fastest turn every slot follows at it."""

    cruise_speed_m_s: float
    turn_rate_rad_s: float

    @property
    def turn_radius_m(self) -> float:
        return self.cruise_speed_m_s / self.turn_rate_rad_s


def slot_turn_rates(speeds_m_s: FloatArray, slots: FloatArray, lim: KernelLimits) -> FloatArray:
    """[S] the fastest turn (rad/s, either way) a leader at each of ``speeds_m_s`` makes with
    every slot ([K,3] in its frame) followed within ``lim`` (the module docstring); 0
    where even a straight line is not."""
    v_min, v_max = lim.v_min, lim.v_max
    v = np.asarray(speeds_m_s, dtype=float)[:, None]
    s = np.asarray(slots, dtype=float).reshape(-1, 3)
    x, y = s[None, :, 0], np.abs(s[None, :, 1])
    omega = np.full(v.shape[0], lim.max_yaw_rate)
    roll_in = math.sqrt(2.0 * min(lim.accel, lim.decel) * lim.target_accuracy)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        inner = np.where(y > 0.0, np.minimum(v - v_min, roll_in) / y, np.inf)
        r2 = x * x + y * y
        disc = np.maximum(v * v * y * y - r2 * (v * v - v_max * v_max), 0.0)
        outer = np.where(r2 > 0.0, (-v * y + np.sqrt(disc)) / r2, np.inf)
    if s.shape[0]:
        omega = np.minimum(omega, np.minimum(inner, outer).min(axis=1))
    inside = (v[:, 0] >= v_min) & (v[:, 0] <= v_max)
    out: FloatArray = np.where(inside, np.maximum(omega, 0.0), 0.0)
    return out


def speed_sweep(slots: FloatArray, lim: KernelLimits) -> tuple[FloatArray, FloatArray]:
    """``SPEED_SAMPLES`` leader speeds across [v_min, v_max] and the fastest turn every slot
    follows at each (``slot_turn_rates``), read-only.  The same slots and limits come back
    every tick of a run (``turn_envelope`` and ``held_speed_range`` each ask), so the sweep
    is kept: 0.8 ms for the 99 slots of ``formation_100``."""
    s = np.ascontiguousarray(slots, dtype=float).reshape(-1, 3)
    free = lim._replace(leader_cruise_speed=math.inf, leader_turn_rate=math.inf)
    return _sweep(s.tobytes(), free)


@lru_cache(maxsize=16)
def _sweep(slots: bytes, lim: KernelLimits) -> tuple[FloatArray, FloatArray]:
    speeds = np.linspace(lim.v_min, lim.v_max, SPEED_SAMPLES)
    rates = slot_turn_rates(speeds, np.frombuffer(slots).reshape(-1, 3), lim)
    speeds.flags.writeable = rates.flags.writeable = False
    return speeds, rates


def turn_envelope(slots: FloatArray, lim: KernelLimits) -> TurnEnvelope:
    """The leader's cruise speed with the fastest formation turn (``slot_turn_rates``): the
    middle of the speeds that tie for it (the roll-in limit can leave a range), so that
    the slots inside and outside the turn keep equal margins to v_min and v_max."""
    speeds, rates = speed_sweep(slots, lim)
    best = np.flatnonzero(rates >= rates.max() - 1e-9)
    k = int(best[len(best) // 2])
    return TurnEnvelope(float(speeds[k]), float(rates[k]))


def held_speed_range(slots: FloatArray, lim: KernelLimits) -> tuple[float, float] | None:
    """The leader's speeds (m/s, low and high) at which every slot follows the formation's
    turn, ``lim.leader_turn_rate`` (``slot_turn_rates``): a leader held below the low end
    leaves the slot inside its turn slower than v_min.  None when the formation does not
    hold turns; the best speeds when none follows that rate (the rate's floor)."""
    if not math.isfinite(lim.leader_turn_rate):
        return None
    speeds, rates = speed_sweep(slots, lim)
    followed = np.flatnonzero(rates >= min(lim.leader_turn_rate, float(rates.max())) - 1e-9)
    return float(speeds[followed[0]]), float(speeds[followed[-1]])


def formation_turn_limits(lim: KernelLimits, slots: FloatArray) -> KernelLimits:
    """``lim`` with the leader's cruise speed and turn rate of ``turn_envelope`` (the turn
    rate no less than ``TURN_RATE_FLOOR_SHARE`` of ω_max)."""
    env = turn_envelope(slots, lim)
    rate = max(env.turn_rate_rad_s, TURN_RATE_FLOOR_SHARE * lim.max_yaw_rate)
    return lim._replace(leader_cruise_speed=env.cruise_speed_m_s, leader_turn_rate=rate)

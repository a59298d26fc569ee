"""Calibration of the built-in SITL against real ArduPlane: each recorded experiment flown
again here and compared with its recording metric by metric, each metric to a tolerance.

The recordings are ``sitl.recordings`` (``tests/data/arduplane-traces/``), the flights
``sitl.replay``, the metrics ``sitl.step_metrics``. ``python -m sitl.calibration`` prints the
comparison; ``tests/sitl/test_arduplane_calibration.py`` holds every metric to its tolerance.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pymap3d

from sitl.recordings import TRACES, Response, load_meta, load_recording
from sitl.replay import fly_guided, fly_heading_ramp, fly_speed_ramp, fly_takeoff
from sitl.step_metrics import (
    airspeed_metrics,
    altitude_metrics,
    heading_metrics,
    ramp_metrics,
    reposition_metrics,
    speed_ramp_metrics,
    takeoff_metrics,
)


@dataclass(frozen=True, slots=True)
class Tolerance:
    """A metric agrees when |simulated − recorded| ≤ max(absolute, relative × |recorded|)."""

    absolute: float
    relative: float = 0.0

    def allows(self, recorded: float, simulated: float) -> bool:
        if math.isnan(recorded) or math.isnan(simulated):
            return math.isnan(recorded) and math.isnan(simulated)
        return abs(simulated - recorded) <= max(self.absolute, self.relative * abs(recorded))


S, M = 1.0, 1.0  # readable tolerance units: seconds, metres

#: Each experiment: how long to fly, how to fly it here, its metrics, and the tolerance of
#: each metric (stated before the fit; see sitl/README.md "Calibration").
Experiment = tuple[
    float,
    Callable[[dict[str, Any], float], Response],
    Callable[[Response, dict[str, Any]], dict[str, float]],
    dict[str, Tolerance],
]


def _reposition_target(meta: dict[str, Any]) -> tuple[float, float]:
    e = meta["experiments"]["08-reposition-right-1000m"]
    s = e["state_at_command"]
    east, north, _ = pymap3d.geodetic2enu(
        e["target_lat_deg"], e["target_lon_deg"], 0.0, s["lat_deg"], s["lon_deg"], 0.0
    )
    return float(east), float(north)


EXPERIMENTS: dict[str, Experiment] = {
    "01-takeoff": (
        30.0,
        lambda meta, d: fly_takeoff(meta, d),
        lambda r, meta: takeoff_metrics(r),
        {
            "t_liftoff_s": Tolerance(1.0 * S),
            "t_95m_s": Tolerance(3.0 * S, 0.15),
            "max_climb_m_s": Tolerance(2.0),
            "max_alt_m": Tolerance(3.0 * M),
            "final_alt_m": Tolerance(3.0 * M),
        },
    ),
    "02-heading-plus90": (
        40.0,
        lambda meta, d: fly_guided("02-heading-plus90", meta, d),
        lambda r, meta: heading_metrics(r, 90.0),
        {
            "t_10pct_s": Tolerance(0.5 * S),
            "t_90pct_s": Tolerance(1.5 * S, 0.2),
            "t_within_2deg_s": Tolerance(3.0 * S, 0.25),
            "peak_roll_deg": Tolerance(8.0),
            "course_change_3s_deg": Tolerance(8.0),
            "overshoot_deg": Tolerance(3.0),
            "alt_excursion_m": Tolerance(3.0 * M),
        },
    ),
    "04-alt-plus50-rate0": (
        60.0,
        lambda meta, d: fly_guided("04-alt-plus50-rate0", meta, d),
        lambda r, meta: altitude_metrics(r, 50.0),
        {
            "t_10pct_s": Tolerance(1.0 * S),
            "t_90pct_s": Tolerance(2.0 * S, 0.15),
            "mean_climb_10_90_m_s": Tolerance(0.6),
            "peak_climb_m_s": Tolerance(0.6),
            "overshoot_m": Tolerance(2.0 * M),
            "change_at_end_m": Tolerance(2.0 * M),
        },
    ),
    "06-alt-plus50-rate2": (
        60.0,
        lambda meta, d: fly_guided("06-alt-plus50-rate2", meta, d),
        lambda r, meta: altitude_metrics(r, 50.0),
        {
            "t_10pct_s": Tolerance(math.inf),
            "t_90pct_s": Tolerance(math.inf),
            "mean_climb_10_90_m_s": Tolerance(math.inf),
            "peak_climb_m_s": Tolerance(0.5),
            "overshoot_m": Tolerance(math.inf),
            "change_at_end_m": Tolerance(3.0 * M),
        },
    ),
    "07a-airspeed-to-28": (
        40.0,
        lambda meta, d: fly_guided("07a-airspeed-to-28", meta, d),
        lambda r, meta: airspeed_metrics(r, 28.0),
        {
            "t_10pct_s": Tolerance(1.0 * S),
            "t_90pct_s": Tolerance(2.0 * S, 0.2),
            "overshoot_m_s": Tolerance(1.0),
            "alt_excursion_max_m": Tolerance(3.0 * M),
            "alt_excursion_min_m": Tolerance(3.0 * M),
        },
    ),
    "07b-airspeed-to-18": (
        40.0,
        lambda meta, d: fly_guided("07b-airspeed-to-18", meta, d),
        lambda r, meta: airspeed_metrics(r, 18.0),
        {
            "t_10pct_s": Tolerance(1.0 * S),
            "t_90pct_s": Tolerance(2.0 * S, 0.2),
            "overshoot_m_s": Tolerance(1.0),
            "alt_excursion_max_m": Tolerance(3.0 * M),
            "alt_excursion_min_m": Tolerance(3.0 * M),
        },
    ),
    "09-heading-ramp": (
        60.0,
        lambda meta, d: fly_heading_ramp(meta, d),
        lambda r, meta: ramp_metrics(r),
        {
            "steady_lag_deg": Tolerance(3.0, 0.1),
            "steady_roll_deg": Tolerance(3.0),
            "t_lag_within_2deg_after_s": Tolerance(2.0 * S, 0.25),
            "alt_excursion_m": Tolerance(3.0 * M),
        },
    ),
    "08-reposition-right-1000m": (
        60.0,
        lambda meta, d: fly_guided("08-reposition-right-1000m", meta, d),
        lambda r, meta: reposition_metrics(r, *_reposition_target(meta)),
        {
            "t_course_80pct_s": Tolerance(1.5 * S, 0.25),
            "peak_roll_deg": Tolerance(10.0),
            "t_within_100m_s": Tolerance(3.0 * S, 0.1),
            "loiter_radius_m": Tolerance(25.0 * M),
            "loiter_roll_deg": Tolerance(10.0),
        },
    ),
}


#: Course steps recorded on ArduPlane 4.7.0-dev (90700977): every one flown from level
#: flight at 22 and at 28 m/s, metrics and tolerances as the +90° step's.
COURSE_STEPS = {"plus20": 20.0, "minus20": -20.0, "plus45": 45.0, "minus45": -45.0,
                "plus90": 90.0, "minus90": -90.0, "plus135": 135.0, "minus135": -135.0,
                "180": 180.0}  # fmt: skip
HEADING_TOLERANCES = EXPERIMENTS["02-heading-plus90"][3]


def _course_step(name: str, delta_deg: float) -> Experiment:
    return (
        40.0,
        lambda meta, d: fly_guided(name, meta, d),
        lambda r, meta: heading_metrics(r, delta_deg),
        HEADING_TOLERANCES,
    )


def _ramp(name: str) -> Experiment:
    return (
        60.0,
        lambda meta, d: fly_heading_ramp(meta, d, name),
        lambda r, meta: ramp_metrics(r),
        EXPERIMENTS["09-heading-ramp"][3],
    )


for _step, _delta in COURSE_STEPS.items():
    for _speed in (22, 28):
        _name = f"10-course-{_step}-as{_speed}"
        EXPERIMENTS[_name] = _course_step(_name, _delta)
for _rate in (6, 12):
    EXPERIMENTS[f"11-heading-ramp-{_rate}dps"] = _ramp(f"11-heading-ramp-{_rate}dps")

#: The airspeed ramps (22 → 16 → 22 m/s at 0.6 m/s², level and in a 60 m climb).
SPEED_RAMP_TOLERANCES = {
    "lag_slowing_m_s": Tolerance(0.5),
    "lag_speeding_m_s": Tolerance(0.5),
    "t_within_0_5_after_slowing_s": Tolerance(3.0 * S, 0.25),
    "overshoot_m_s": Tolerance(0.5),
    "t_overshoot_s": Tolerance(3.0 * S, 0.25),
    "alt_excursion_m": Tolerance(3.0 * M),
}


def _speed_ramp(name: str) -> Experiment:
    return (
        62.0,
        lambda meta, d: fly_speed_ramp(meta, d, name),
        lambda r, meta: speed_ramp_metrics(r),
        SPEED_RAMP_TOLERANCES,
    )


for _kind in ("level", "climb"):
    EXPERIMENTS[f"12-speed-ramp-{_kind}"] = _speed_ramp(f"12-speed-ramp-{_kind}")


@dataclass(frozen=True, slots=True)
class Comparison:
    experiment: str
    metric: str
    recorded: float
    simulated: float
    tolerance: Tolerance

    @property
    def agrees(self) -> bool:
        return self.tolerance.allows(self.recorded, self.simulated)


def compare(experiment: str, traces: Path = TRACES) -> list[Comparison]:
    """Fly ``experiment`` on the built-in SITL and compare it with the recording."""
    duration, fly, metrics, tolerances = EXPERIMENTS[experiment]
    meta = load_meta(traces)
    recorded = metrics(load_recording(experiment, traces), meta)
    simulated = metrics(fly(meta, duration), meta)
    return [
        Comparison(experiment, name, recorded[name], simulated[name], tol)
        for name, tol in tolerances.items()
    ]


def main() -> int:
    failed = 0
    print(f"{'experiment':<26} {'metric':<22} {'ArduPlane':>10} {'built-in':>10} {'tol':>8}  ok")
    for name in EXPERIMENTS:
        for c in compare(name):
            tol = c.tolerance
            text = f"±{tol.absolute:g}" + (f"/{tol.relative:.0%}" if tol.relative else "")
            print(
                f"{c.experiment:<26} {c.metric:<22} {c.recorded:>10.2f} {c.simulated:>10.2f} "
                f"{text:>8}  {'yes' if c.agrees else 'NO'}"
            )
            failed += not c.agrees
    print(f"{failed} metric(s) outside tolerance")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

"""The built-in SITL against real ArduPlane: every recorded step response
(tests/data/arduplane-traces, ArduPlane V4.7.0-dev SITL, plane.parm) flown again here with
the same parameters and commands from the same state, each metric within its tolerance but
the known gaps, which must still be gaps (mend the model, then the list)."""

from __future__ import annotations

import pytest

from sitl.calibration import EXPERIMENTS, compare
from sitl.recordings import TRACES, load_meta


def test_the_recordings_are_real_arduplane_4_7() -> None:
    meta = load_meta()
    assert meta["ardupilot_version"].startswith("ArduPlane V4.7.0")
    assert sorted(p.stem for p in TRACES.glob("*.csv")) == sorted(EXPERIMENTS)


KNOWN_GAPS = {
    # ArduPlane's roll overshoots its demand (a 180° reversal at 22 m/s banked 54.7°, every
    # other step of 90° or more 50.1–50.3°); the model's bank follows it first-order: 45.6°.
    ("10-course-180-as22", "peak_roll_deg"),
    # Turning at 12°/s, ArduPlane's course lags the command 46.1°, the model's 40.4° (at 6°/s
    # 23.1° and 22.2°): its effective heading gain falls with the error, the model's does not.
    ("11-heading-ramp-12dps", "steady_lag_deg"),
}


@pytest.mark.parametrize("experiment", sorted(EXPERIMENTS))
def test_step_response_matches_arduplane(experiment: str) -> None:
    rows = compare(experiment)
    for c in rows:
        print(f"{c.experiment} {c.metric}: ArduPlane {c.recorded:.2f}, built-in {c.simulated:.2f}")
    off = [c for c in rows if not c.agrees and (c.experiment, c.metric) not in KNOWN_GAPS]
    assert not off, ", ".join(
        f"{c.metric}: ArduPlane {c.recorded:.2f}, built-in {c.simulated:.2f}" for c in off
    )
    mended = [c.metric for c in rows if c.agrees and (c.experiment, c.metric) in KNOWN_GAPS]
    assert not mended, f"{mended} now agree: take them off KNOWN_GAPS"

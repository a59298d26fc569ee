"""Crash recovery on loopback (issue 26 item 3): ``gcs-ppf serve`` killed with SIGKILL in
the middle of Table 3 at x10, the built-in SITL's GCS failsafe on (FS_GCS_ENABL 1), judged
by the independent observer (``gcs_ppf.tools.campaign_crash``, conditions j and l).  Two
flights (about 70 s here): ``make campaign-check``, not ``make test``."""

from __future__ import annotations

from pathlib import Path

import pytest

from gcs_ppf.tools.campaign import CONDITIONS, fly_once
from tests.conftest import EXAMPLES

RTL_WITHIN_S = 5.0 + 3.0  # FS_LONG_TIMEOUT, and the last heartbeat's and the SITL's steps


@pytest.mark.integration
@pytest.mark.campaign
def test_killed_mid_run_started_again_and_resumed_the_run_completes(tmp_path: Path) -> None:
    """Killed 15 s in: every vehicle switches itself to RTL within FS_LONG_TIMEOUT of our
    last heartbeat; the service started again on the same database opens the links it was
    given, still answers every event it answered before the kill, says the run is
    ``interrupted``; ``resume`` (202) takes the vehicles back and the run completes, with
    no violation the observer saw while the service commanded them."""
    rec = fly_once(EXAMPLES / "paper_table3.json", CONDITIONS["j"], tmp_path, seed=1)
    event = rec["event"]
    assert event is not None, rec
    assert event["state_after_restart"] == "interrupted"
    assert event["events_kept"]
    assert event["events_before"] > 0
    assert event["answer"] == 202
    assert rec["state"] == "completed", rec
    delays = rec["failsafe_after_s"]
    assert all(d is not None and d <= RTL_WITHIN_S for d in delays.values()), delays
    assert rec["violations_commanded"] == [], rec
    kinds = [k for k, _ in rec["events"]]
    assert kinds.index("run_interrupted") < kinds.index("run_resumed") < len(kinds) - 1
    print(
        f"\nkilled at {event['mission_time_s']} s of mission time, down "
        f"{event['down_vehicle_s']} s of vehicle time, RTL after {delays}; completed at "
        f"{rec['mission_time_s']} s; while down: {rec['down']}; commanded: separation "
        f"{rec['min_separation_m']} m overall"
    )


@pytest.mark.integration
@pytest.mark.campaign
def test_left_dead_every_vehicle_s_own_failsafe_returns_it(tmp_path: Path) -> None:
    """Killed and never started again: each vehicle's long GCS failsafe (its STATUSTEXT and
    its HEARTBEAT's mode, heard by the observer) takes it to RTL within FS_LONG_TIMEOUT."""
    rec = fly_once(EXAMPLES / "paper_table3.json", CONDITIONS["l"], tmp_path, seed=1)
    assert rec["state"] == "failsafe", rec
    delays = rec["failsafe_after_s"]
    assert all(d is not None and d <= RTL_WITHIN_S for d in delays.values()), delays
    print(f"\nleft dead: RTL after {delays}; while down: {rec['down']}")

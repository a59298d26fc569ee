"""A route flown closed loop: ``python -m sitl`` and ``gcs-ppf serve`` as real processes,
the waypoints judged from an independent pymavlink listener's record of the leader."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gcs_ppf.geodesy import geodetic_to_enu
from gcs_ppf.guidance import failsafe
from gcs_ppf.mission import Mission
from gcs_ppf.planning.route import Loitering, leg_flown, legs, on_circle
from gcs_ppf.tools.demo import http_json as http
from gcs_ppf.tools.observer import resample
from tests.checks import wait_for
from tests.conftest import EXAMPLES
from tests.integration.test_service_sitl import SPEEDUP, check_safety, fly


@pytest.mark.integration
def test_the_arduplane_route_is_flown_waypoint_by_waypoint(tmp_path: Path) -> None:
    """Three vehicles take off together and fly a route north, east and back west (a 90°
    and a 162° turn in formation): the run completes safely, the leader's own track
    passes each waypoint (within its acceptance radius or across its finish line) in
    order, and the service said so in its events."""
    doc = json.loads((EXAMPLES / "arduplane_route_3.json").read_text())
    seen: dict[str, Any] = {}

    def read_back(api: str, mission_id: int) -> None:
        seen["events"] = http("GET", f"{api}/missions/{mission_id}/events")
        seen["runs"] = http("GET", f"{api}/runs")

    flight = fly(tmp_path, doc, after=read_back)
    assert flight.final["state"] == "completed", flight.final
    check_safety(flight)

    leader = flight.tracks[flight.mission.leader.id][:, 1:4]
    k = 1
    for leg in legs(flight.mission)[:-1]:
        while k < len(leader) and not leg_flown(leg, leader[k - 1], leader[k]):
            k += 1
        assert k < len(leader), f"the leader never flew leg {leg.index} (to {leg.end_m})"
        k += 1

    status, events = seen["events"]
    assert status == 200
    reached = [e for e in events if e["kind"] == "waypoint_reached"]
    assert [e["detail"]["waypoint"] for e in reached] == [0, 1]
    times = [e["mission_time_s"] for e in reached]
    assert times == sorted(times)
    status, runs = seen["runs"]
    summary = runs[-1]["summary"]
    assert np.allclose(summary["waypoint_times_s"], times, atol=1e-3)


@pytest.mark.integration
def test_a_mission_that_ends_in_rtl_brings_every_vehicle_home_over_every_keep_out(
    tmp_path: Path,
) -> None:
    """Table 3 with ``at_end: "rtl"``: after the arrival each vehicle holds on a circle at a
    level over every sphere, then flies ArduPlane's RTL home at it (``returning_home``, its
    RTL_ALTITUDE read back).  The observer sees every vehicle over its home's vertical at the
    end, and the whole flight, the way home included, keeps both safe distances."""
    doc = json.loads((EXAMPLES / "paper_table3.json").read_text())
    doc["at_end"] = "rtl"
    homes = {v["id"]: np.array(v["position"]) for v in doc["vehicles"]}
    seen: dict[str, Any] = {}

    def home_events(api: str, mid: int) -> list[dict[str, Any]]:
        status, events = http("GET", f"{api}/missions/{mid}/events")
        kinds = ("returning_home", "return_not_clear")
        return [e for e in events if e["kind"] in kinds] if status == 200 else []

    def until_home(api: str, mid: int) -> None:
        seen["returns"] = wait_for(
            lambda: (r := home_events(api, mid)) and len(r) == len(homes) and r, 60, "returns"
        )

        def all_home() -> bool:
            _, vehicles = http("GET", f"{api}/vehicles")
            for v in vehicles:
                p = v["position"]
                x, y, _ = geodetic_to_enu(p["lat_deg"], p["lon_deg"], p["alt_amsl_m"], origin)
                if np.hypot(x - homes[v["system_id"]][0], y - homes[v["system_id"]][1]) > 1000:
                    return False
            return True

        wait_for(all_home, 60, "every vehicle near its home")
        time.sleep(20.0 / SPEEDUP)  # round its home for 20 of its seconds

    origin = Mission.model_validate(doc).origin
    flight = fly(tmp_path, doc, after=until_home)
    assert flight.final["state"] == "completed", flight.final
    check_safety(flight)
    returns = seen["returns"]
    assert sorted(e["vehicle_id"] for e in returns) == sorted(homes)
    assert {e["kind"] for e in returns} == {"returning_home"}, returns
    floor = failsafe.return_floor_m(flight.mission, {v: 0.0 for v in homes}, 0.0)
    tracks = flight.tracks
    first, last = max(tr[0, 0] for tr in tracks.values()), min(tr[-1, 0] for tr in tracks.values())
    pos = resample(tracks, np.arange(first, last, 0.05))  # the run and the way home
    gaps = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=-1)
    gaps[:, np.arange(len(homes)), np.arange(len(homes))] = np.inf
    separation = float(gaps.min())
    clearance = min(
        float((np.linalg.norm(pos - np.array(o.center), axis=-1) - o.radius).min())
        for o in flight.mission.obstacles
    )
    for vid, tr in tracks.items():
        end = tr[-1, 1:4]
        assert np.hypot(*(end[:2] - homes[vid][:2])) < 1000.0, (vid, end)
        assert end[2] >= floor - 50.0, (vid, end)
    levels = sorted(e["detail"]["rtl_altitude_m"] for e in returns)
    print(
        f"\nRTL at the end: every vehicle home, {levels} m over their homes; the whole "
        f"flight: separation {separation:.1f} m, clearance {clearance:.1f} m"
    )
    lim = flight.mission.limits
    assert separation >= lim.safe_distance_uav
    assert clearance >= lim.safe_distance_obstacle, closest_pass(flight.mission, tracks)


def closest_pass(mission: Mission, tracks: dict[int, np.ndarray]) -> str:
    """Where each vehicle came nearest an obstacle's surface: the time (its clock), its
    nearest at its own telemetry samples, and the gap between the two samples about that
    moment (across a gap resampling draws a straight line) — said when the flight's
    clearance fails, so that a failure names its moment."""
    out = []
    centres = [(np.array(o.center), o.radius) for o in mission.obstacles]
    for vid, tr in sorted(tracks.items()):
        t = np.arange(tr[0, 0], tr[-1, 0], 0.05)
        pos = resample({vid: tr}, t)[:, 0]
        depth = np.min([np.linalg.norm(pos - c, axis=-1) - r for c, r in centres], axis=0)
        k = int(np.argmin(depth))
        own = np.min([np.linalg.norm(tr[:, 1:4] - c, axis=-1) - r for c, r in centres], axis=0)
        after = min(int(np.searchsorted(tr[:, 0], t[k], side="right")), len(tr) - 1)
        gap = float(tr[after, 0] - tr[max(after - 1, 0), 0])
        out.append(
            f"vehicle {vid}: {depth[k]:.1f} m at {t[k]:.1f} s (its samples: "
            f"{own.min():.1f} m; {gap:.2f} s between the samples about it)"
        )
    return "; ".join(out)


@pytest.mark.integration
@pytest.mark.campaign
def test_a_loiter_at_a_waypoint_is_flown_round_it_in_formation(tmp_path: Path) -> None:
    """``arduplane_route_loiter_3``: one clockwise turn round the first waypoint on a 632 m
    circle (the tightest this formation holds), then on.  The leader's own track sweeps the
    one turn round the waypoint on the circle between ``loiter_began`` and
    ``waypoint_reached`` (the leader's clock), and flies out to a turn point before it turns
    onto the target; the run is safe.  In ``make
    campaign-check``: ``make test`` is near its time budget."""
    doc = json.loads((EXAMPLES / "arduplane_route_loiter_3.json").read_text())
    seen: dict[str, Any] = {}

    def read_back(api: str, mission_id: int) -> None:
        seen["events"] = http("GET", f"{api}/missions/{mission_id}/events")

    flight = fly(tmp_path, doc, after=read_back)
    assert flight.final["state"] == "completed", flight.final
    check_safety(flight)
    status, events = seen["events"]
    assert status == 200
    kinds = [(e["kind"], e["detail"]["waypoint"]) for e in events
             if e["kind"] in ("loiter_began", "waypoint_reached")]  # fmt: skip
    assert kinds == [("loiter_began", 0), ("waypoint_reached", 0), ("waypoint_reached", 1)]
    # the target lies inside the V's turn from the last waypoint: a turn point first
    assert [e["detail"]["waypoint"] for e in events if e["kind"] == "turn_point"][-1:] == [2]
    zero_s = next(e for e in events if e["kind"] == "run_running")["detail"]["leader_clock_zero_s"]
    began_s, done_s = (next(e["mission_time_s"] for e in events if e["kind"] == kind)
                       for kind in ("loiter_began", "waypoint_reached"))  # fmt: skip

    leg = legs(flight.mission)[0]
    track = flight.tracks[flight.mission.leader.id]  # on the leader's clock
    during = (track[:, 0] >= zero_s + began_s - 0.5) & (track[:, 0] <= zero_s + done_s + 0.5)
    flown = track[during, 1:4]
    loiter = Loitering(flown[0]).on(leg, flown[1:], 0.0)
    turns = loiter.swept / (2 * np.pi)
    on = [on_circle(leg, p) for p in flown]
    radii = np.hypot(*(flown[on, :2] - leg.end_m[:2]).T)
    print(
        f"\nloiter: {turns:.2f} turns swept by the observer's leader track, radius "
        f"{np.median(radii):.0f} m (asked {leg.loiter_radius_m:.0f} m)"
    )
    assert 0.97 <= turns <= 1.2

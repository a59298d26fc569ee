"""Real ArduPlane SITL: ``gcs-ppf arduplane-sitl`` starts one ArduPilot instance per vehicle,
``gcs-ppf serve`` flies the formation on their serial0 ports, and an independent pymavlink
observer (``gcs_ppf.tools.observer``) on each instance's serial1 port judges the flight.

Needs an ArduPlane SITL binary (docs/arduplane.md):
``ARDUPLANE_SITL=…/build/sitl/bin/arduplane .venv/bin/pytest -m arduplane -s``; skipped
otherwise.  ``ARDUPLANE_SITL_SPEEDUP`` (default 5) sets the simulation speed-up.
"""

from __future__ import annotations

import json
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from gcs_ppf.geodesy import geodetic_to_enu
from gcs_ppf.mission import Mission
from gcs_ppf.service.store import Store
from gcs_ppf.tools.arduplane_sitl import find_plane_parm
from gcs_ppf.tools.campaign import process
from gcs_ppf.tools.formation_report import STEP_S, formation_flown, straight_and_turns
from gcs_ppf.tools.observer import (
    Observer,
    closest_pass,
    formation_offsets,
    free_port_block,
    longest_formed_s,
    resample,
    slot_distances,
    tracks_on_common_clock,
)
from tests.checks import wait_for
from tests.conftest import EXAMPLES
from tests.integration.test_service_sitl import _finished, _vehicle_count

BINARY = os.environ.get("ARDUPLANE_SITL", "")
SPEEDUP = float(os.environ.get("ARDUPLANE_SITL_SPEEDUP", "5"))
AFTER_S = 30.0  # vehicle seconds watched after the run ends
HELD_S = 10.0  # "formed and held": every wingman within the target accuracy this long at once
AIRBORNE_M = 10.0  # "after takeoff": from a vehicle's first sample this high above its home
OBSERVER_SYSID = 202  # neither a vehicle's id nor the service's 255

pytestmark = [
    pytest.mark.arduplane,
    pytest.mark.skipif(
        not (BINARY and Path(BINARY).is_file()),
        reason=f"ARDUPLANE_SITL={BINARY!r} does not name an ArduPlane SITL binary "
        "(set it to …/ardupilot/build/sitl/bin/arduplane to fly real ArduPlane)",
    ),
]


def fly_arduplane(
    tmp_path: Path,
    mission_path: Path,
    *,
    wait_prearm: bool = True,
    formation: bool = True,
    extra_defaults: str = "",
    env_extra: dict[str, str] | None = None,
    kill_after_s: float | None = None,
    after_end: Callable[[str, int], None] | None = None,
) -> dict[Any, Any]:
    """Fly ``mission_path`` on real ArduPlane SITL and judge it (the run completed, safe
    distances kept, no ground hit; with ``formation`` also formed and held ``HELD_S``);
    the final status.  ``wait_prearm``: start once the observer sees every vehicle pre-arm
    healthy (otherwise the moment the service hears them all, after boot);
    ``extra_defaults``: parameter lines added to plane.parm for every instance;
    ``kill_after_s``: the service killed (SIGKILL) this long (wall) after the run is
    running, and what the vehicles do then returned (``fenced_after_kill``);
    ``after_end``: called with the API and the mission once the run has ended, the observer
    listening (its tracks, judged, run on to its return)."""
    doc = json.loads(mission_path.read_text())
    mission = Mission.model_validate(doc)
    lim, n = mission.limits, len(mission.vehicles)
    base = free_port_block(10 * n)
    api_port = free_port_block(1)
    api = f"http://127.0.0.1:{api_port}"
    service_ports = {v.id: base + 10 * k for k, v in enumerate(mission.vehicles)}
    observer_ports = {v.id: p + 2 for v, p in zip(mission.vehicles, service_ports.values(),
                                                  strict=True)}  # fmt: skip
    launcher = [sys.executable, "-m", "gcs_ppf.cli", "arduplane-sitl", str(mission_path),
                "--binary", BINARY, "--speedup", f"{SPEEDUP:g}", "--base-port", str(base),
                "--workdir", str(tmp_path / "sitl")]  # fmt: skip
    if extra_defaults:
        plane = find_plane_parm(Path(BINARY))
        assert plane is not None, "extra_defaults needs the ArduPilot tree's plane.parm"
        defaults = tmp_path / "plane-extra.parm"
        defaults.write_text(plane.read_text() + "\n" + extra_defaults + "\n")
        launcher += ["--defaults", str(defaults)]
    links = [a for p in service_ports.values() for a in ("--link", f"tcp:127.0.0.1:{p}")]
    serve = [sys.executable, "-m", "gcs_ppf.cli", "serve", "--port", str(api_port),
             "--db", str(tmp_path / "gcs.db"), *links]  # fmt: skip
    env = {"GCS_PPF_TLOG_DIR": str(tmp_path / "tlogs"), **(env_extra or {})}
    launcher_log = tmp_path / "arduplane-sitl.log"
    wall_budget = (mission.planner.max_time + 120.0) / SPEEDUP + 60.0
    with process(launcher, launcher_log):
        wait_for(lambda: "ready" in launcher_log.read_text(), 60, f"the fleet ({launcher_log})")
        with (
            process(serve, tmp_path / "gcs.log", env) as serve_proc,
            Observer(observer_ports, sysid=OBSERVER_SYSID, request_streams=True) as obs,
        ):
            wait_for(lambda: _vehicle_count(api) == n, 60, "the service to see every vehicle")
            t_ready = time.monotonic()
            try:  # GPS and EKF settle before ArduPlane will arm
                if wait_prearm:
                    wait_for(lambda: all(r.prearm_ok for r in obs.records.values()), 120, "pre-arm")
            except AssertionError:
                late = [s for s, r in obs.records.items() if not r.prearm_ok]
                print(f"\nnot pre-arm healthy, started anyway: vehicles {late}")
            healthy = sorted(s for s, r in obs.records.items() if r.prearm_ok)
            print(f"\n{n} vehicles heard, started after {time.monotonic() - t_ready:.1f} s "
                  f"wall; pre-arm healthy then: {healthy}")  # fmt: skip
            with httpx.Client(base_url=api, timeout=10) as client:
                r = client.post("/missions", json=doc)
                assert r.status_code == 201, r.text
                mid = r.json()["id"]
                t0_wall = time.time()  # the observer's arrival clock
                r = client.post(f"/missions/{mid}/start")
                assert r.status_code == 202, r.text
            if kill_after_s is not None:
                return fenced_after_kill(api, mid, serve_proc, obs, kill_after_s)
            final = wait_for(lambda: _finished(api, mid), wall_budget, "the run to end")
            if final["state"] == "failed":  # a start refused: nothing flew to judge
                return dict(final)
            end_s = (time.time() - t0_wall) * SPEEDUP  # on the common clock
            end_ms = obs.latest_boot_ms()
            if after_end is not None:
                after_end(api, mid)

            def watched_after() -> bool:
                now_ms = obs.latest_boot_ms()
                return all(now_ms[s] >= end_ms[s] + AFTER_S * 1000 for s in now_ms)

            wait_for(watched_after, 3 * AFTER_S / SPEEDUP + 10, "vehicle time after the end")

    record = {s: {"pos": r.pos, "texts": r.texts} for s, r in obs.records.items()}
    (tmp_path / "observer.json").write_text(json.dumps({"t0_wall": t0_wall, **record}))
    tracks = tracks_on_common_clock(obs, mission, t0_wall, SPEEDUP)
    start = max(tr[0, 0] for tr in tracks.values())
    end = min(tr[-1, 0] for tr in tracks.values())
    pos = resample(tracks, np.arange(start, end, 0.05))
    gaps = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=-1)
    gaps[:, np.arange(n), np.arange(n)] = np.inf
    separation = float(gaps.min())
    clearance = min(
        [float((np.linalg.norm(tr[:, 1:4] - np.array(o.center), axis=1) - o.radius).min())
         for tr in tracks.values() for o in mission.obstacles] or [np.inf]
    )  # fmt: skip
    hits = {}
    for sysid, rec in obs.records.items():
        up = [tbm for _, tbm, *_, h in rec.pos if h >= AIRBORNE_M]
        hits[sysid] = [t for b, t in rec.texts if "Hit ground" in t and up and b >= up[0]]
    # The run's clock starts once the vehicles are launched: its window ends at end_s.
    window = (end_s - final["mission_time_s"], final["mission_time_s"])
    best, formation_error = formation_offsets(mission, tracks, *window)
    held = longest_formed_s(mission, tracks, *window)
    to_target = closest_pass(tracks[mission.leader.id], np.array(mission.target))
    flown = formation_flown(mission, tracks, window[0], window[0] + window[1])
    share = (
        "never formed"
        if flown is None or flown.formed_after_s is None
        else (f"in formation {flown.in_formation_share:.0%} of the flight after forming")
    )
    reformed = reformed_after_passage_s(mission, tracks, window[0], window[0] + window[1])
    split = straight_and_turns(mission, tracks, window[0], window[0] + window[1])
    if split is not None:
        level = "-" if split.level_m is None else f"{split.level_m:.1f}"
        share += (
            f" (RMS slot error {split.straight_m:.1f} m straight, {level} m straight and "
            f"level, {split.turns_m:.1f} m in the turns)"
        )
    print(
        f"{mission.name} on ArduPlane SITL (×{SPEEDUP:g}): run {final['state']} "
        f"({final.get('outcome')}), flight time {final['mission_time_s']:.1f} s ({end_s:.1f} s "
        "from the start command, takeoff included); observer: "
        f"min separation {separation:.1f} m (safe {lim.safe_distance_uav:g}), min clearance "
        f"{clearance:.1f} m (safe {lim.safe_distance_obstacle:g}), leader's closest to the "
        f"target {to_target:.1f} m, formation error {formation_error:.1f} m (worst wingman at the "
        "best moment; each wingman's best "
        + ", ".join(f"{vid}: {d:.1f} m" for vid, d in best.items())
        + f"), held {held:.1f} s, {share}, formed again "
        + ("never" if reformed is None else f"{reformed:.1f} s")
        + " after the leader's closest pass to the obstacle, 'Hit ground' after takeoff: "
        + ", ".join(f"{s}: {len(h)}" for s, h in hits.items())
    )
    assert final["state"] == "completed", final
    assert separation >= lim.safe_distance_uav
    assert clearance >= lim.safe_distance_obstacle
    assert not any(hits.values()), hits
    if formation:
        assert formation_error <= lim.target_accuracy
        assert held >= HELD_S, f"formed, but held only {held:.1f} s"
    return dict(final)


@pytest.mark.arduplane
@pytest.mark.parametrize(
    "mission", ["arduplane_3", "arduplane_5", "arduplane_formation_takeoff_3",
                "arduplane_formation_takeoff_5"],
)  # fmt: skip
def test_formation_flown_on_arduplane_sitl(mission: str, tmp_path: Path) -> None:
    """From a ground start (line abreast 272 m apart, or a formation takeoff from runway
    positions at the slots): the run completes, separation and obstacle clearance stay safe,
    no vehicle hits the ground once airborne, and every wingman is within the target
    accuracy of its local target point (Eq. 6, from the observer's tracks) at one moment
    and all of them stay within it for HELD_S together."""
    fly_arduplane(tmp_path, EXAMPLES / f"{mission}.json")


@pytest.mark.arduplane
@pytest.mark.parametrize("mission", ["arduplane_route_uturn_3", "arduplane_route_loiter_3"])
def test_a_route_is_flown_in_formation_on_arduplane_sitl(mission: str, tmp_path: Path) -> None:
    """A route of three legs, a 90° and a 180° turn (or one loiter turn round a waypoint),
    taken off together: judged as above, the worst wingman's RMS slot error on the straight
    legs and in the turns printed."""
    fly_arduplane(tmp_path, EXAMPLES / f"{mission}.json")


@pytest.mark.arduplane
@pytest.mark.parametrize("run", range(3))
def test_a_start_as_soon_as_the_vehicles_are_heard_waits_for_them(run: int, tmp_path: Path) -> None:
    """Started the moment the service hears every vehicle after boot (ArduPlane refuses to
    arm while its EKF and GPS settle): the start waits for each vehicle's pre-arm checks
    (``prearm_waiting`` with its own reasons, then ``prearm_passed``) or retries the arm it
    refused, and the run completes safely (judged as above; the formation reported)."""
    final = fly_arduplane(tmp_path, EXAMPLES / "arduplane_3.json", wait_prearm=False,
                          formation=False)  # fmt: skip
    store = Store(tmp_path / "gcs.db")
    events = store.events(store.runs()[0].id)
    waited = [(e.kind, e.vehicle_id, e.detail) for e in events
              if e.kind in ("prearm_waiting", "prearm_passed", "arm_refused")]  # fmt: skip
    print(f"run {run}: {final['state']}; the start's waits: {waited}")
    assert final["state"] == "completed"


@pytest.mark.arduplane
def test_a_start_that_can_never_arm_fails_with_the_vehicle_s_reason(tmp_path: Path) -> None:
    """Every instance asks for more battery than it has to arm (BATT_ARM_VOLT 30 V): the
    start waits its bound (here 20 s), then the run fails naming the vehicle's own PreArm:
    reason; no vehicle is commanded to fly, and nothing in the service's log is an
    exception."""
    final = fly_arduplane(
        tmp_path,
        EXAMPLES / "arduplane_3.json",
        wait_prearm=False,
        extra_defaults="BATT_ARM_VOLT 30",
        env_extra={"GCS_PPF_PREARM_TIMEOUT_S": "20"},
    )
    print(f"refused for good: {final['state']}: {final.get('outcome')}")
    assert final["state"] == "failed"
    assert "PreArm" in str(final.get("outcome")), final
    log = (tmp_path / "gcs.log").read_text(errors="replace")
    assert "Traceback" not in log
    store = Store(tmp_path / "gcs.db")
    kinds = [e.kind for e in store.events(store.runs()[0].id)]
    assert "prearm_failed" in kinds
    assert "takeoff" not in kinds


def fenced_after_kill(
    api: str, mid: int, serve: Any, obs: Observer, kill_after_s: float
) -> dict[Any, Any]:
    """The run running for ``kill_after_s`` (wall), the service killed; then, by the
    observer, each vehicle's first "Fence Breached" after the kill and its mode after it
    (vehicle s since the kill)."""

    def running() -> bool:
        final = _finished(api, mid)
        assert final is None, final
        with httpx.Client(base_url=api, timeout=5) as client:
            return bool(client.get(f"/missions/{mid}/status").json().get("state") == "running")

    wait_for(running, 120, "the run running")
    time.sleep(kill_after_s)
    killed_ms = obs.latest_boot_ms()
    serve.kill()
    serve.wait()

    def breach(vid: int) -> int | None:
        hits = [b for b, t in obs.records[vid].texts
                if "fence" in t.lower() and b >= killed_ms[vid]]  # fmt: skip
        return hits[0] if hits else None

    wait_for(lambda: all(breach(v) is not None for v in obs.records), 240, "every fence breach")
    time.sleep(10 / SPEEDUP + 1)  # their mode changes are heard
    out: dict[Any, Any] = {"state": "killed"}
    for vid, rec in obs.records.items():
        at = breach(vid)
        assert at is not None
        before = [m for b, m in rec.modes if b < at][-1:]  # the mode in effect, then changes
        after = before + [m for b, m in rec.modes if b >= at]
        texts = [t for b, t in rec.texts if b >= at][:3]
        out[vid] = {"breach_after_s": (at - killed_ms[vid]) / 1000.0, "modes": after,
                    "texts": texts}  # fmt: skip
    return out


def reformed_after_passage_s(
    mission: Mission, tracks: dict[int, np.ndarray], start_s: float, end_s: float
) -> float | None:
    """How long after the leader's closest pass to an obstacle's surface every wingman was
    within the target accuracy of its slot again (0: never out of it; None: not again)."""
    if not mission.obstacles:
        return None
    t = np.arange(start_s, end_s, STEP_S)
    lead = resample({0: tracks[mission.leader.id]}, t)[:, 0]
    surface = np.min(
        [np.linalg.norm(lead - np.array(o.center), axis=1) - o.radius for o in mission.obstacles],
        axis=0,
    )
    passed = int(np.argmin(surface))
    worst = np.max(np.stack(list(slot_distances(mission, tracks, t).values())), axis=0)
    again = np.flatnonzero(worst[passed:] <= mission.limits.target_accuracy)
    return None if again.size == 0 else float(again[0] * STEP_S)


@pytest.mark.arduplane
def test_the_zones_are_real_arduplane_s_fence_for_the_run(tmp_path: Path) -> None:
    """``arduplane_3`` inside a stay-inside square 2.5 km round it: the service uploads it
    as each ArduPlane's fence at the launch, reads it back as sent and enables it
    (``fence_set``); the run completes with the fence up."""
    doc = json.loads((EXAMPLES / "arduplane_3.json").read_text())
    square = [[-2500.0, -2500.0], [2500.0, -2500.0], [2500.0, 5500.0], [-2500.0, 5500.0]]
    doc["zones"] = [{"kind": "polygon", "name": "operation area", "inclusion": True,
                     "vertices": square}]  # fmt: skip
    path = tmp_path / "arduplane_3_fenced.json"
    path.write_text(json.dumps(doc))
    final = fly_arduplane(tmp_path, path, formation=False)
    store = Store(tmp_path / "gcs.db")
    events = store.events(store.runs()[0].id)
    fenced = {e.vehicle_id: e.detail for e in events if e.kind == "fence_set"}
    failed = [(e.vehicle_id, e.detail) for e in events if e.kind == "fence_failed"]
    restored = sorted(e.vehicle_id or 0 for e in events if e.kind == "fence_restored")
    print(f"fences on ArduPlane: set {fenced}, failed {failed}, restored {restored}")
    assert final["state"] == "completed"
    assert failed == []
    assert set(fenced) == {1, 2, 3}
    for detail in fenced.values():
        assert detail is not None
        assert detail["verified"]
        assert detail["fence_enable"] == 1
        assert int(detail["fence_type"]) & 4


@pytest.mark.arduplane
def test_with_the_service_dead_real_arduplane_s_own_fence_turns_it_home(tmp_path: Path) -> None:
    """The same fenced mission, the service killed 20 s (wall, ×5) into the run and left
    dead (no GCS failsafe: plane.parm's FS_GCS_ENABL 0): each ArduPlane flies on its last
    GUIDED course until its own fence, then reports the breach and turns home in RTL."""
    doc = json.loads((EXAMPLES / "arduplane_3.json").read_text())
    square = [[-1500.0, -1500.0], [1500.0, -1500.0], [1500.0, 4500.0], [-1500.0, 4500.0]]
    doc["zones"] = [{"kind": "polygon", "name": "operation area", "inclusion": True,
                     "vertices": square}]  # fmt: skip
    path = tmp_path / "arduplane_3_fenced.json"
    path.write_text(json.dumps(doc))
    seen = fly_arduplane(tmp_path, path, formation=False, kill_after_s=20.0)
    print(f"the service killed; each vehicle then: {seen}")
    for vid in (1, 2, 3):
        assert seen[vid]["modes"][-1] == 11, seen[vid]  # RTL, by its own fence


@pytest.mark.arduplane
def test_a_mission_ending_in_rtl_brings_real_arduplane_home(tmp_path: Path) -> None:
    """Line abreast 3 with ``at_end: "rtl"``: after the arrival every ArduPlane holds at a
    level over the sphere, says where its home is (HOME_POSITION) and flies RTL home at it
    (``returning_home``, RTL_ALTITUDE read back); the observer's tracks, the way home
    included, keep both safe distances (``fly_arduplane``) and end over each home."""
    doc = json.loads((EXAMPLES / "arduplane_3.json").read_text())
    doc["at_end"] = "rtl"
    path = tmp_path / "arduplane_3_rtl.json"
    path.write_text(json.dumps(doc))
    mission = Mission.model_validate(doc)
    seen: dict[str, Any] = {}

    def home(api: str, mid: int) -> None:
        def returns() -> list[dict[str, Any]]:
            events = httpx.get(f"{api}/missions/{mid}/events", timeout=10).json()
            kinds = ("returning_home", "return_not_clear")
            found = [e for e in events if e["kind"] in kinds]
            return found if len(found) == len(mission.vehicles) else []

        seen["returns"] = wait_for(returns, 300 / SPEEDUP + 30, "every vehicle's return")

        def all_home() -> bool:
            vehicles = httpx.get(f"{api}/vehicles", timeout=10).json()
            modes = {v["system_id"]: v["mode"] for v in vehicles}
            seen["modes"] = modes
            return all(m == "RTL" for m in modes.values()) and all(
                _horizontal_m(v, mission) < 300.0 for v in vehicles
            )

        wait_for(all_home, 300 / SPEEDUP + 30, "every vehicle over its home")

    fly_arduplane(tmp_path, path, formation=False, after_end=home)
    kinds = sorted((e["vehicle_id"], e["kind"]) for e in seen["returns"])
    assert kinds == [(v.id, "returning_home") for v in mission.vehicles], seen["returns"]
    levels = [e["detail"]["rtl_altitude_m"] for e in seen["returns"]]
    print(f"RTL at the end on ArduPlane: every vehicle home, RTL_ALTITUDE {sorted(levels)} m")


def _horizontal_m(vehicle: dict[str, Any], mission: Mission) -> float:
    """How far (m) a vehicle of GET /vehicles is from its start (its home) across the ground."""
    p = vehicle["position"]
    x, y, _ = geodetic_to_enu(p["lat_deg"], p["lon_deg"], p["alt_amsl_m"], mission.origin)
    start = next(v.position for v in mission.vehicles if v.id == vehicle["system_id"])
    return float(np.hypot(x - start[0], y - start[1]))

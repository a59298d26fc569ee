"""The campaign's service crashes (issue 26 item 3): the service killed (``kill -9``) at a
moment of the run drawn from its seed (``moment_s``), then started again on the same
database and the run resumed or aborted, or left dead while the vehicles' own GCS failsafe
(FS_GCS_ENABL 1, set on the SITL) acts.

What is judged here, beside the campaign's own separation and clearance: that every event
the API answered before the kill is still answered after the restart, what the resume or
the abort answered, how long the service was down in vehicle seconds, and how long after
the kill each vehicle switched itself to RTL (its HEARTBEAT's mode, as the observer heard
it).
"""

from __future__ import annotations

import random
import signal
import subprocess
import time
from collections.abc import Callable
from contextlib import AbstractContextManager, ExitStack
from dataclasses import dataclass
from typing import Any

import httpx

from gcs_ppf.mission import Mission, zone_clearance, zone_footprint
from gcs_ppf.tools.observer import Observer

KINDS = ("crash_resume", "crash_abort", "crash_dead", "crash_fenced")
LEFT_DEAD = ("crash_dead", "crash_fenced")
MOMENT_S = (5.0, 60.0)
"""The mission times a run's kill is drawn from (its seed's): anywhere in the flight."""
FS_LONG_TIMEOUT_S = 5.0  # ArduPlane's default, the SITL's too
FAILSAFE_SLACK_S = 3.0  # the last heartbeat up to 1 s before the kill, and the SITL's step
RTL_MODE = 11  # ArduPlane's custom_mode of RTL (the observer shares no code with the service)
DEAD_WATCH_S = 20.0  # vehicle seconds watched after the kill when the service stays dead
FENCED_WATCH_S = 60.0  # …and with no failsafe, until the vehicles reach their fences


@dataclass
class ServiceProcess:
    """``gcs-ppf serve`` as the campaign runs it, killed and started again on demand."""

    stack: ExitStack
    start_process: Callable[[], AbstractContextManager[subprocess.Popen[bytes]]]
    proc: subprocess.Popen[bytes] | None = None

    def start(self) -> None:
        self.proc = self.stack.enter_context(self.start_process())

    def kill(self) -> None:
        """SIGKILL: nothing of the service runs after it (no holds, no last writes)."""
        assert self.proc is not None
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait()


def moment_s(seed: int) -> float:
    """When the service is killed in the run of ``seed`` (mission time)."""
    return random.Random(seed).uniform(*MOMENT_S)


def _latest_v(obs: Observer) -> float:
    return max(obs.latest_boot_ms().values()) / 1000.0


def get_json(api: httpx.Client, path: str) -> Any:
    """The JSON of a 200 answer to GET ``path``; None for anything else (a dead service)."""
    try:
        r = api.get(path)
    except httpx.HTTPError:
        return None
    return r.json() if r.status_code == 200 else None


def wait_for(predicate: Callable[[], Any], timeout_s: float, what: str) -> Any:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.1)
    raise TimeoutError(f"timed out waiting for {what}")


def crash(
    kind: str,
    api: httpx.Client,
    mission_id: int,
    service: ServiceProcess,
    obs: Observer,
    vehicle_ids: list[int],
    status: dict[str, Any],
    speedup: float,
) -> dict[str, Any]:
    """Kill the service now; then, by ``kind``, start it again and resume or abort the run,
    or watch ``DEAD_WATCH_S`` of vehicle time.  What was done and seen (JSON-able)."""
    before = get_json(api, f"/missions/{mission_id}/events") or []
    killed_v = _latest_v(obs)
    service.kill()
    out: dict[str, Any] = {
        "kind": kind,
        "wall_s": time.time(),
        "mission_time_s": status.get("mission_time_s"),
        "vehicle_s": round(killed_v, 1),
        "events_before": len(before),
    }
    if kind in LEFT_DEAD:
        watch = FENCED_WATCH_S if kind == "crash_fenced" else DEAD_WATCH_S
        wait_for(lambda: _latest_v(obs) >= killed_v + watch, watch / speedup * 4 + 30,
                 "vehicle time after the kill")  # fmt: skip
        return out
    service.start()
    wait_for(lambda: get_json(api, "/missions") is not None, 180, "the service started again")

    def all_heard() -> bool:
        heard = {v["system_id"] for v in get_json(api, "/vehicles") or [] if not v["lost"]}
        return set(vehicle_ids) <= heard

    wait_for(all_heard, 60, "the vehicles heard again (the links reopened)")
    after = get_json(api, f"/missions/{mission_id}/events") or []
    out["events_kept"] = all(e in after for e in before)
    out["state_after_restart"] = (get_json(api, f"/missions/{mission_id}/status") or {}).get(
        "state"
    )
    action = "resume" if kind == "crash_resume" else "abort"
    r = api.post(f"/missions/{mission_id}/{action}")
    out["answer"] = r.status_code
    out["down_vehicle_s"] = round(_latest_v(obs) - killed_v, 1)
    return out


def failsafe_delays_s(obs: Observer, killed_v: float) -> dict[int, float | None]:
    """Each vehicle's vehicle seconds from the kill to its first switch to RTL after it
    (None: it never did)."""
    out: dict[int, float | None] = {}
    for vid, rec in obs.records.items():
        switched = [
            tbm / 1000.0 - killed_v
            for tbm, mode in rec.modes
            if mode == RTL_MODE and tbm / 1000.0 >= killed_v
        ]
        out[vid] = round(min(switched), 1) if switched else None
    return out


def fence_breaches_s(obs: Observer, killed_v: float) -> dict[int, float | None]:
    """Each vehicle's vehicle seconds from the kill to its first "Fence Breached" (None:
    none)."""
    out: dict[int, float | None] = {}
    for vid, rec in obs.records.items():
        hits = [tbm / 1000.0 - killed_v for tbm, text in rec.texts
                if "Fence Breached" in text and tbm / 1000.0 >= killed_v]  # fmt: skip
        out[vid] = round(min(hits), 1) if hits else None
    return out


def outside_m(mission: Mission, tracks: dict[int, Any], start_s: float) -> dict[int, float]:
    """How far each vehicle went outside the mission's inclusion zones (or into its
    exclusion ones) after ``start_s`` (vehicle s), by the observer's tracks; 0: never."""
    shapes = [(z, zone_footprint(z, mission.origin)) for z in mission.zones]
    out: dict[int, float] = {}
    for vid, track in tracks.items():
        worst = 0.0
        for row in track[track[:, 0] >= start_s]:
            for zone, footprint in shapes:
                worst = max(worst, -zone_clearance(zone, footprint, row[1:4]))
        out[vid] = round(worst, 1)
    return out


def judge_crash(rec: dict[str, Any], obs: Observer, event: dict[str, Any] | None) -> bool:
    """The crash's figures into ``rec``; True when it went as it should: the failsafe of
    every vehicle within FS_LONG_TIMEOUT (and the slack) of the kill, and after a restart
    every event kept and the resume or abort accepted."""
    if event is None:
        return False
    delays = failsafe_delays_s(obs, float(event["vehicle_s"]))
    rec["failsafe_after_s"] = delays
    if event["kind"] == "crash_fenced":  # RTL by the fence, not by a failsafe
        breaches = fence_breaches_s(obs, float(event["vehicle_s"]))
        rec["fence_breach_after_s"] = breaches
        fenced = all(b is not None and d is not None and d >= b
                     for b, d in zip(breaches.values(), delays.values(), strict=True))  # fmt: skip
        rec["state"] = "fenced" if fenced else "not fenced"
        return fenced
    if event["kind"] == "crash_dead":
        rec["state"] = "failsafe" if all(d is not None for d in delays.values()) else "no failsafe"
    in_time = all(d is not None and d <= FS_LONG_TIMEOUT_S + FAILSAFE_SLACK_S
                  for d in delays.values())  # fmt: skip
    if event["kind"] == "crash_dead":
        return in_time
    return in_time and bool(event.get("events_kept")) and event.get("answer") in (200, 202)

"""The formation each campaign run flew, as its independent observer saw it.

``python -m gcs_ppf.tools.formation_report CAMPAIGN_DIR [--axes]`` reads a campaign's
``runs.jsonl`` and each run's ``observer.json`` (the pymavlink observer's samples on the
vehicles' own clock; nothing from the service) and prints, per mission and condition, how
long the formation took to form after the run started, the share of the flight after that
in formation (every wingman within the target accuracy of its slot at once, Eq. 6), the
worst wingman's RMS and 95th-percentile slot error while formed, the longest hold, and the
flight time; with ``--axes``, each wingman's RMS slot error along the leader's flight-path
axes (forward, left, up) after first forming: which loop misses the slot.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray
from pymavlink.dialects.v20.ardupilotmega import PLANE_MODE_TAKEOFF

from gcs_ppf.geodesy import geodetic_to_enu
from gcs_ppf.mission import Mission
from gcs_ppf.tools.campaign import AFTER_S, EXAMPLES, mission_path
from gcs_ppf.tools.observer import held_s, slot_distances, slot_errors

STEP_S = 0.1
FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class FormationFlown:
    """One run's formation, from ``formed_after_s`` (since the run started) to its end."""

    formed_after_s: float | None
    in_formation_share: float
    formed_rms_m: float | None
    formed_p95_m: float | None
    held_s: float
    flown_s: float


def _formation_tracks(
    mission: Mission, tracks: dict[int, FloatArray], start_s: float, end_s: float
) -> dict[int, FloatArray] | None:
    """The leader's and the wingmen's tracks, or None when there is no formation to judge
    over [start_s, end_s] (a lone leader, an empty window, a vehicle never heard)."""
    ids = [mission.leader.id, *(w.id for w in mission.wingmen)]
    if not mission.wingmen or end_s <= start_s or any(len(tracks.get(v, ())) == 0 for v in ids):
        return None
    return {v: tracks[v] for v in ids}


def _worst(
    mission: Mission, tracks: dict[int, FloatArray], start_s: float, end_s: float
) -> tuple[FloatArray, FloatArray, dict[int, FloatArray]] | None:
    """The times over [start_s, end_s] every ``STEP_S``, the worst wingman's distance from
    its slot at each, and the tracks (None: no formation to judge, ``_formation_tracks``)."""
    flown_tracks = _formation_tracks(mission, tracks, start_s, end_s)
    if flown_tracks is None:
        return None
    t = np.arange(start_s, end_s, STEP_S)
    offsets = slot_distances(mission, flown_tracks, t)
    return t, np.max(np.stack(list(offsets.values())), axis=0), flown_tracks


def formation_flown(
    mission: Mission, tracks: dict[int, FloatArray], start_s: float, end_s: float
) -> FormationFlown | None:
    """The formation over [start_s, end_s] of vehicle time (None for a lone leader or a
    vehicle never heard)."""
    worst_of = _worst(mission, tracks, start_s, end_s)
    if worst_of is None:
        return None
    t, worst, _ = worst_of
    accuracy = mission.limits.target_accuracy
    formed = worst <= accuracy
    flown = end_s - start_s
    if not formed.any():
        return FormationFlown(None, 0.0, None, None, 0.0, flown)
    first = int(np.argmax(formed))
    after = formed[first:]
    while_formed = worst[formed]
    return FormationFlown(
        formed_after_s=float(t[first] - start_s),
        in_formation_share=float(after.mean()),
        formed_rms_m=float(np.sqrt(np.mean(while_formed**2))),
        formed_p95_m=float(np.percentile(while_formed, 95)),
        held_s=held_s(worst, accuracy, STEP_S),
        flown_s=flown,
    )


def observed_tracks(path: Path, mission: Mission) -> dict[int, FloatArray]:
    """[K,5] rows (vehicle s, ICS x, y, z, height above home) per vehicle, from a run's
    ``observer.json`` (``campaign.fly_once``)."""
    raw = json.loads(path.read_text())
    out = {}
    for key, rec in raw.items():
        if not key.isdigit():
            continue
        rows = [
            (tbm / 1000.0, *geodetic_to_enu(la, lo, al, mission.origin), h)
            for _, tbm, la, lo, al, h in rec["pos"]
        ]
        out[int(key)] = np.array(rows, dtype=float).reshape(-1, 5)
    return out


def takeoff_ended_s(path: Path) -> float | None:
    """The vehicle second by which every vehicle that flew TAKEOFF had left it (the
    observer's HEARTBEAT modes in a run's ``observer.json``); None if none flew it."""
    raw = json.loads(path.read_text())
    ended: list[float] = []
    for key, rec in raw.items():
        if not key.isdigit():
            continue
        modes = rec.get("modes", [])
        took = [k for k, (_, mode) in enumerate(modes) if mode == PLANE_MODE_TAKEOFF]
        if took:
            after = [tbm for tbm, mode in modes[took[0] :] if mode != PLANE_MODE_TAKEOFF]
            ended.append(after[0] / 1000.0 if after else math.inf)
    return max(ended) if ended else None


def record_mission(rec: dict[str, Any]) -> Mission:
    """The mission a campaign record flew: its ``mission_file``, or the example of its name."""
    if "mission_file" in rec:
        return Mission.model_validate(json.loads(mission_path(rec["mission_file"]).read_text()))
    for path in sorted(EXAMPLES.glob("*.json")):
        mission = Mission.model_validate(json.loads(path.read_text()))
        if mission.name == rec["mission"]:
            return mission
    raise ValueError(f"no mission file for {rec['mission']!r}: the record has no mission_file")


def run_formation(rec: dict[str, Any], after_s: float = AFTER_S) -> FormationFlown | None:
    """The formation of one campaign record (its observer's window less the watch after it)."""
    return formation_flown(*_observed(rec, after_s))


def _observed(
    rec: dict[str, Any], after_s: float
) -> tuple[Mission, dict[int, FloatArray], float, float]:
    """A campaign record's mission, observed tracks and window (less the watch after it)."""
    mission = record_mission(rec)
    start, end = rec["window_s"][0], rec["window_s"][1] - after_s
    return mission, observed_tracks(Path(rec["dir"]) / "observer.json", mission), start, end


def _median(values: list[float]) -> float | None:
    return float(np.median(values)) if values else None


def _cell(x: float | None, width: int, digits: int = 1) -> str:
    return f"{'-' if x is None else f'{x:.{digits}f}':>{width}}"


def report(records: list[dict[str, Any]]) -> str:
    """One line per (mission, condition): runs, formed (of runs), time to form (min /
    median / max), share in formation after it (min / median), RMS and p95 while formed
    (median), longest hold (median), flight time (median)."""
    groups: dict[tuple[str, str], list[FormationFlown | None]] = {}
    for rec in records:
        groups.setdefault((rec["mission"], rec["condition"]), []).append(run_formation(rec))
    head = (
        f"{'mission':<14}{'cond':>5}{'runs':>5}{'formed':>7}{'form s min/med/max':>21}"
        f"{'share min/med':>15}{'rms':>6}{'p95':>6}{'held':>6}{'flown':>7}"
    )
    lines = [head]
    for (name, cond), runs in sorted(groups.items()):
        seen = [r for r in runs if r is not None and r.formed_after_s is not None]
        times = [r.formed_after_s for r in seen if r.formed_after_s is not None]
        shares = [r.in_formation_share for r in seen]
        flown = [r.flown_s for r in runs if r is not None]
        spread = (min(times, default=None), _median(times), max(times, default=None))
        form = "/".join(_cell(x, 5).strip() for x in spread)
        low_share = min(shares, default=None)
        share = "/".join(_cell(x, 4, 2).strip() for x in (low_share, _median(shares)))
        lines.append(
            f"{name:<14}{cond:>5}{len(runs):>5}{len(seen):>7}{form:>21}{share:>15}"
            f"{_cell(_median([r.formed_rms_m for r in seen if r.formed_rms_m is not None]), 6)}"
            f"{_cell(_median([r.formed_p95_m for r in seen if r.formed_p95_m is not None]), 6)}"
            f"{_cell(_median([r.held_s for r in seen]), 6)}{_cell(_median(flown), 7)}"
        )
    return "\n".join(lines) + "\n"


def run_axes(rec: dict[str, Any], after_s: float = AFTER_S) -> dict[int, FloatArray] | None:
    """Each wingman's RMS slot error [3] (forward, left, up; m) in one campaign record,
    from the first moment in formation to the end (the whole flight if it never formed)."""
    mission, tracks, start, end = _observed(rec, after_s)
    flown_tracks = _formation_tracks(mission, tracks, start, end)
    if flown_tracks is None:
        return None
    errors = slot_errors(mission, flown_tracks, np.arange(start, end, STEP_S))
    worst = np.max(np.stack([np.linalg.norm(e, axis=1) for e in errors.values()]), axis=0)
    formed = worst <= mission.limits.target_accuracy
    first = int(np.argmax(formed)) if formed.any() else 0
    return {vid: np.sqrt(np.mean(e[first:] ** 2, axis=0)) for vid, e in errors.items()}


Measured = TypeVar("Measured")


def _by_row(
    records: list[dict[str, Any]], measure: Callable[[dict[str, Any]], Measured | None]
) -> dict[tuple[str, str], list[Measured]]:
    """Each run's ``measure`` (those not None), grouped by (mission, condition)."""
    groups: dict[tuple[str, str], list[Measured]] = {}
    for rec in records:
        m = measure(rec)
        if m is not None:
            groups.setdefault((rec["mission"], rec["condition"]), []).append(m)
    return groups


def axes_report(records: list[dict[str, Any]]) -> str:
    """One line per (mission, condition, wingman): the median over the runs of its RMS
    slot error forward / left / up after first forming (``run_axes``)."""
    groups = _by_row(records, run_axes)
    lines = [f"{'mission':<14}{'cond':>5}{'wingman':>8}{'runs':>5}  rms m forward / left / up"]
    for (name, cond), runs in sorted(groups.items()):
        for vid in sorted(runs[0]):
            rms = np.median(np.stack([r[vid] for r in runs if vid in r]), axis=0)
            cells = " / ".join(f"{x:.1f}" for x in rms)
            lines.append(f"{name:<14}{cond:>5}{vid:>8}{len(runs):>5}  {cells}")
    return "\n".join(lines) + "\n"


TURNING_RAD_S = math.radians(0.5)
"""The leader turns while its course changes faster than this (over ``COURSE_SPAN_S``)."""
COURSE_SPAN_S = 1.0


LEVEL_RAD = math.radians(1.0)
"""The leader flies level while its flight-path angle (over ``COURSE_SPAN_S``) is within
this: a slot d behind swings d·γ vertically in its climbing frame (36 m at 100 m behind in
ArduPlane's 20° takeoff climb)."""


@dataclass(frozen=True)
class StraightAndTurns:
    """The worst wingman's RMS slot error (m) on the straight legs, on those flown level,
    and in the turns (None where there were none); and on the straight legs from the first
    moment in formation after the takeoff (None without one)."""

    straight_m: float
    level_m: float | None
    turns_m: float
    airborne_m: float | None = None


def run_turns(rec: dict[str, Any], after_s: float = AFTER_S) -> StraightAndTurns | None:
    """``straight_and_turns`` of one campaign record, with its takeoff's end
    (``takeoff_ended_s``)."""
    airborne = takeoff_ended_s(Path(rec["dir"]) / "observer.json")
    return straight_and_turns(*_observed(rec, after_s), airborne_s=airborne)


def straight_and_turns(
    mission: Mission,
    tracks: dict[int, FloatArray],
    start: float,
    end: float,
    airborne_s: float | None = None,
) -> StraightAndTurns | None:
    """The worst wingman's RMS slot error on the straight legs (all, and level only) and in
    the turns of ``tracks`` ([K,4] rows of vehicle s, x, y, z) from ``start`` to ``end``,
    from the first moment in formation (None if it never formed, or it never turned): the
    leader turns while its course over the ground changes faster than ``TURNING_RAD_S``,
    flies level while its flight-path angle is within ``LEVEL_RAD``.  With ``airborne_s``
    (the vehicle second the takeoff ended), the straight legs also from the first moment in
    formation after it: a formation takeoff is "formed" on the runway, and in the leader's
    takeoff climb (20° at ArduPlane's scale) a slot 100 m behind lies 34 m below the
    wingman climbing beside it."""
    worst_of = _worst(mission, tracks, start, end)
    if worst_of is None:
        return None
    t, worst, flown_tracks = worst_of
    formed = worst <= mission.limits.target_accuracy
    if not formed.any():
        return None
    leader = flown_tracks[mission.leader.id]
    x, y, z = (np.interp(t, leader[:, 0], leader[:, k]) for k in (1, 2, 3))
    span = max(1, round(COURSE_SPAN_S / STEP_S))

    def over_span(rate: FloatArray) -> FloatArray:
        return np.concatenate([rate, np.full(span, rate[-1] if rate.size else 0.0)])

    course = np.unwrap(np.arctan2(np.gradient(y), np.gradient(x)))
    turning = over_span(np.abs(course[span:] - course[:-span]) / (span * STEP_S)) > TURNING_RAD_S
    run = np.hypot(x[span:] - x[:-span], y[span:] - y[:-span])
    level = np.abs(over_span(np.arctan2(z[span:] - z[:-span], run))) <= LEVEL_RAD
    after = np.arange(t.size) >= int(np.argmax(formed))
    if not (turning & after).any():
        return None

    def rms(where: NDArray[np.bool_]) -> float:
        return float(np.sqrt(np.mean(worst[where] ** 2)))

    flat = after & ~turning & level
    airborne_m = None
    if airborne_s is not None:
        up = formed & (t >= airborne_s)
        since = after & (np.arange(t.size) >= int(np.argmax(up)))
        airborne_m = rms(since & ~turning) if up.any() and (since & ~turning).any() else None
    return StraightAndTurns(
        rms(after & ~turning),
        rms(flat) if flat.any() else None,
        rms(after & turning),
        airborne_m,
    )


def turns_report(records: list[dict[str, Any]]) -> str:
    """One line per (mission, condition): the median over its runs of the worst wingman's
    RMS slot error on the straight legs, on those flown level, in the turns, and on the
    straight legs after the takeoff (``run_turns``), with the runs' min–max."""
    groups = _by_row(records, run_turns)
    head = "rms m straight / level / turns / straight after takeoff (min–max)"
    lines = [f"{'mission':<14}{'cond':>5}{'runs':>5}  {head}"]
    for (name, cond), runs in sorted(groups.items()):
        cells = [
            _spread([getattr(r, k) for r in runs])
            for k in ("straight_m", "level_m", "turns_m", "airborne_m")
        ]
        lines.append(f"{name:<14}{cond:>5}{len(runs):>5}  {' / '.join(cells)}")
    return "\n".join(lines) + "\n"


def _spread(values: list[float | None]) -> str:
    """The median of ``values`` and their min–max ("-" without any)."""
    known = np.array([v for v in values if v is not None])
    if not known.size:
        return "-"
    return f"{np.median(known):.1f} ({known.min():.1f}–{known.max():.1f})"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m gcs_ppf.tools.formation_report", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("campaign", type=Path, help="a campaign's --out directory")
    parser.add_argument(
        "--axes", action="store_true", help="each wingman's slot error forward / left / up"
    )
    parser.add_argument(
        "--turns", action="store_true", help="the slot error on the straight legs and in turns"
    )
    args = parser.parse_args(argv)
    files = sorted(args.campaign.rglob("runs.jsonl"))
    if not files:
        parser.error(f"no runs.jsonl under {args.campaign}")
    records = [json.loads(line) for f in files for line in f.read_text().splitlines() if line]
    print(report(records), end="")
    if args.axes:
        print(axes_report(records), end="")
    if args.turns:
        print(turns_report(records), end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

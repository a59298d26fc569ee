"""The closed-loop campaign's tables (``gcs_ppf.tools.campaign``): a line per run as it ends,
and per condition a table with a row per mission — runs, violations, runs ending as
expected, separation and clearance, the formation, flown and wall time — all from the
records the campaign wrote (the independent observer's figures, never the service's)."""

from __future__ import annotations

import statistics
from collections.abc import Mapping, Sequence
from typing import Any, Protocol


class Labelled(Protocol):
    """What a table says of a condition: its label and the end a good run has."""

    @property
    def label(self) -> str: ...

    @property
    def expect(self) -> str: ...


def progress_line(rec: dict[str, Any]) -> str:
    """One run, as it ends."""
    if rec.get("error"):
        return f"{rec['mission']} ({rec['condition']}) run {rec['run']}: ERROR {rec['error']}"
    extra = f" handover {rec['handover_delay_s']} s" if "handover_delay_s" in rec else ""
    if rec.get("formation_m") is not None:
        extra += f" formation {rec['formation_m']} m held {rec['formation_held_s']} s"
    return (
        f"{rec['mission']} ({rec['condition']}) run {rec['run']}: {rec['state']}"
        f" sep {rec['min_separation_m']} m clr {rec['min_clearance_m']} m flown"
        f" {rec['mission_time_s']} s wall {rec['wall_s']} s{extra}"
        + (f"  VIOLATION {'; '.join(rec['violations'])}" if rec["violations"] else "")
    )


def _stats(values: list[float]) -> tuple[float | None, float | None]:
    return (min(values), statistics.median(values)) if values else (None, None)


def summarize(
    results: Sequence[dict[str, Any]], conditions: Mapping[str, Labelled]
) -> dict[str, Any]:
    """Per condition, per mission and all missions: runs, violations, runs ending as
    expected, separation, clearance and formation (min, median), flown and wall time
    (median)."""
    out: dict[str, Any] = {}
    for key in dict.fromkeys(r["condition"] for r in results):
        rows = [r for r in results if r["condition"] == key]
        groups = {
            m: [r for r in rows if r["mission"] == m]
            for m in dict.fromkeys(r["mission"] for r in rows)
        }
        if len(groups) > 1:
            groups["all"] = rows
        out[key] = {
            "label": conditions[key].label,
            "expect": conditions[key].expect,
            "missions": {m: _group(g) for m, g in groups.items()},
        }
    return out


def _group(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    def vals(k: str) -> list[float]:
        return [float(r[k]) for r in rows if r.get(k) is not None]

    sep, clr = _stats(vals("min_separation_m")), _stats(vals("min_clearance_m"))
    form = _stats(vals("formation_m"))
    return {
        "runs": len(rows),
        "errors": sum(1 for r in rows if r.get("error")),
        "violations": sum(1 for r in rows if r["violations"]),
        "as_expected": sum(1 for r in rows if r["ok"]),
        "states": {s: sum(1 for r in rows if r["state"] == s) for s in {r["state"] for r in rows}},
        "separation_min_m": sep[0],
        "separation_median_m": sep[1],
        "clearance_min_m": clr[0],
        "clearance_median_m": clr[1],
        "formation_min_m": form[0],
        "formation_median_m": form[1],
        "formation_held_max_s": max(vals("formation_held_s"), default=None),
        "uncontrolled_clearance_min_m": _stats(vals("uncontrolled_clearance_m"))[0],
        "sank": sum(1 for r in rows if r.get("sank")),
        "handover_delay_max_s": max(vals("handover_delay_s"), default=None),
        "failsafe_max_s": max(
            (d for r in rows for d in (r.get("failsafe_after_s") or {}).values() if d is not None),
            default=None,
        ),
        "violations_down": sum(1 for r in rows if (r.get("down") or {}).get("violations")),
        "violations_commanded": sum(1 for r in rows if r.get("violations_commanded")),
        "events_lost": sum(1 for r in rows if (r.get("event") or {}).get("events_kept") is False),
        "flown_median_s": _stats(vals("mission_time_s"))[1],
        "wall_median_s": _stats(vals("wall_s"))[1],
    }


def format_tables(summary: dict[str, Any]) -> str:
    """One table per condition, a row per mission.  ``form`` is the worst wingman's
    distance from its slot at the run's best moment (min and median over the runs),
    ``held`` the longest any run kept every wingman within the target accuracy."""
    lines = []
    head = (
        f"{'mission':<18}{'runs':>5}{'viol':>5}{'ok':>4}{'sep min':>9}{'sep med':>9}"
        f"{'clr min':>9}{'clr med':>9}{'form min':>9}{'form med':>9}{'held':>6}"
        f"{'flown':>7}{'wall':>6}  note"
    )

    def f(x: float | None, w: int) -> str:
        return f"{'-' if x is None else f'{x:.1f}':>{w}}"

    for key, c in summary.items():
        lines += [
            "",
            f"({key}) {c['label']}: ok = ended {c['expect']}"
            + (" within the lost-vehicle timeout" if key == "e" else ""),
            head,
        ]
        for m, g in c["missions"].items():
            note = [f"{s} {k}" for s, k in sorted(g["states"].items()) if s != c["expect"]]
            if g["uncontrolled_clearance_min_m"] is not None:
                note.append(f"stuck wingman's clearance {g['uncontrolled_clearance_min_m']:.1f}")
            if g["handover_delay_max_s"] is not None:
                note.append(f"new leader <= {g['handover_delay_max_s']:.1f} s after silence")
            if g["failsafe_max_s"] is not None:
                note.append(
                    f"RTL <= {g['failsafe_max_s']:.1f} s after the kill; violations while "
                    f"down {g['violations_down']}, commanded {g['violations_commanded']}"
                    + (f"; events lost {g['events_lost']}" if g["events_lost"] else "")
                )
            if g["sank"]:
                note.append(f"{g['sank']} below the ground keep-out")
            lines.append(
                f"{m[:17]:<18}{g['runs']:>5}{g['violations']:>5}{g['as_expected']:>4}"
                f"{f(g['separation_min_m'], 9)}{f(g['separation_median_m'], 9)}"
                f"{f(g['clearance_min_m'], 9)}{f(g['clearance_median_m'], 9)}"
                f"{f(g['formation_min_m'], 9)}{f(g['formation_median_m'], 9)}"
                f"{f(g['formation_held_max_s'], 6)}"
                f"{f(g['flown_median_s'], 7)}{f(g['wall_median_s'], 6)}  {'; '.join(note)}"
            )
    return "\n".join(lines) + "\n"

"""`gcs-ppf plan MISSION.json --out DIR`: plan with both methods, write metrics, trajectory, plots.

Planning itself is ``gcs_ppf.offline.plan``; what is written is ``gcs_ppf.offline.output`` and
``gcs_ppf.offline.plots`` (CONVENTIONS §4); ``gcs_ppf.cli`` parses the arguments.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import Any

from tqdm import tqdm

from gcs_ppf.mission import Mission, MissionError, load_mission_file
from gcs_ppf.offline import output
from gcs_ppf.offline.plan import PlanRun, plan_mission
from gcs_ppf.planning.planner import Method

SWEEP_DTS = (0.1, 0.05, 0.02, 0.01, 0.005)  # Fig. 9 of the paper
EXIT_BAD_INPUT = 2
EXIT_PLOT_FAILED = 3  # metrics.json and trajectory.csv written, some figures not
log = logging.getLogger("gcs_ppf")


def _progress_plan(mission: Mission, method: Method, dt: float | None, what: str) -> PlanRun:
    total = mission.planner.max_time
    with tqdm(
        total=total,
        desc=what,
        unit="s",
        leave=False,
        bar_format="{desc}: {bar} {n:.1f}/{total:.0f} s flight",
    ) as bar:

        def progress(t: float) -> None:
            bar.update(t - bar.n)

        return plan_mission(mission, method=method, dt=dt, progress=progress)


def _comparison(run: PlanRun, baseline: PlanRun) -> dict[str, Any]:
    """The smoothness figures of both methods side by side."""

    def figures(r: PlanRun) -> dict[str, Any]:
        m = r.metrics
        return {
            **m["smoothness"],
            "heading_change_deg_per_km_per_vehicle": {
                vid: row["heading_change_deg_per_km"] for vid, row in m["per_vehicle"].items()
            },
            "max_yaw_rate_rad_s": m["max_yaw_rate_rad_s"],
            "max_pitch_rate_rad_s": m["max_pitch_rate_rad_s"],
            "collisions": m["collisions"],
            "reached": m["reached"],
            "flight_time_s": m["flight_time_s"],
        }

    ours, theirs = figures(run), figures(baseline)
    return {
        run.method: ours,
        baseline.method: theirs,
        "smoother": run.method
        if ours["heading_change_deg_per_km"] < theirs["heading_change_deg_per_km"]
        else baseline.method,
    }


def _sweep(mission: Mission, method: Method) -> list[dict[str, float]]:
    rows = []
    for dt in tqdm(SWEEP_DTS, desc="Δt sweep", leave=False):
        run = plan_mission(mission, method=method, dt=dt)
        m = run.metrics
        rows.append(
            {
                "dt_s": dt,
                "flight_time_s": m["simulated_time_s"],
                "planning_wall_time_s": run.wall_time_s,
                "real_time_factor": m["real_time_factor"],
                "reached": m["reached"],
            }
        )
    return rows


def _write_outputs(
    out_dir: Path,
    mission: Mission,
    run: PlanRun,
    baseline: PlanRun,
    sweep: list[dict[str, float]] | None,
    plots: bool,
) -> dict[str, str]:
    """Metrics and trajectory first, then the figures; returns the figures that failed."""
    metrics = dict(run.metrics)
    metrics["comparison"] = _comparison(run, baseline)
    if sweep is not None:
        metrics["dt_sweep"] = sweep
    if not plots:
        return output.write_plan(out_dir, metrics, run.trajectory)
    from gcs_ppf.offline import plots as fig  # matplotlib only when plotting

    figures = fig.plan_figures(mission, run, baseline, sweep)
    jobs = tqdm(figures, desc="plots", leave=False)
    return output.write_plan(out_dir, metrics, run.trajectory, jobs)


def plan_command(args: argparse.Namespace) -> int:
    try:
        mission = load_mission_file(args.mission)
    except MissionError as exc:
        print(f"gcs-ppf: error: invalid mission {args.mission}: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    method: Method = args.method or mission.planner.method
    other: Method = "apf" if method == "ppf" else "ppf"
    log.info(
        "planning %r with %s (Δt = %g s); the first run compiles the kernel",
        mission.name,
        method.upper(),
        args.dt or mission.planner.dt,
    )
    run = _progress_plan(mission, method, args.dt, method.upper())
    baseline = _progress_plan(mission, other, args.dt, f"{other.upper()} baseline")
    sweep = _sweep(mission, method) if args.sweep_dt else None
    plot_errors = _write_outputs(args.out, mission, run, baseline, sweep, plots=not args.no_plots)

    m = run.metrics

    def fmt(x: float | None, unit: str, none: str = "never") -> str:
        return none if x is None else f"{x:.2f} {unit}"

    log.info(
        "leader reached target: %s, flight time %s", m["reached"], fmt(m["flight_time_s"], "s")
    )
    log.info("all wingmen in formation at once: %s", fmt(m["formation_time_s"], "s"))
    log.info(
        "min vehicle separation %s (safe %g m), min obstacle clearance %s (safe %g m), "
        "collisions %d",
        fmt(m["min_separation_m"], "m", "n/a"),
        mission.limits.safe_distance_uav,
        fmt(m["min_obstacle_clearance_m"], "m", "n/a"),
        mission.limits.safe_distance_obstacle,
        m["collisions"],
    )
    nearest = [
        f"{vid} {row['nearest_keep_out']} ({fmt(row['min_obstacle_clearance_m'], 'm')})"
        for vid, row in m["per_vehicle"].items()
        if row.get("nearest_keep_out") is not None
    ]
    if nearest:
        log.info("each vehicle's nearest keep-out: %s", ", ".join(nearest))
    log.info(
        "planning took %.2f ms for %.1f s of flight: %.0f× real time",
        run.wall_time_s * 1e3,
        m["simulated_time_s"],
        m["real_time_factor"] or 0.0,
    )
    cmp = _comparison(run, baseline)
    log.info(
        "heading change per km: %s %.1f°/km, %s %.1f°/km",
        method.upper(),
        cmp[method]["heading_change_deg_per_km"],
        other.upper(),
        cmp[other]["heading_change_deg_per_km"],
    )
    if plot_errors:  # the data is written; say which figures are missing, exit 3
        for name, error in plot_errors.items():
            print(f"gcs-ppf: error: figure {name} not drawn: {error}", file=sys.stderr)
        log.info("metrics and trajectory are in %s/, without those figures", args.out)
        return EXIT_PLOT_FAILED
    log.info("metrics, trajectory and plots are in %s/", args.out)
    return 0

"""PNG figures that reproduce the paper's Figs. 5–13 from planned trajectories.

Any number of vehicles: up to five keep the paper's colours; up to
``LEGEND_MAX_WINGMEN`` wingmen get the 20 qualitative colours of ``tab20`` (dark ones
first, the light ones dashed) and a legend beside the axes; more wingmen are coloured
along a perceptual map (viridis, yellow end cut off) with cycling line styles, and the
legend summarises them in a colour bar of their ids.  The leader is always named in the
legend.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.cm import ScalarMappable
from matplotlib.colors import BoundaryNorm, ListedColormap, to_rgba
from matplotlib.figure import Figure

from gcs_ppf.mission import Mission
from gcs_ppf.offline.plan import PlanRun
from gcs_ppf.planning.metrics import local_target_points
from gcs_ppf.planning.scene import FloatArray
from gcs_ppf.planning.zones import INCLUSION, POLYGON, Zones, zone_clearances

RGBA = tuple[float, float, float, float]
Draw = Callable[[Path], None]

PAPER_COLOURS = ["tab:blue", "gold", "tab:red", "tab:green", "black"]
LEGEND_MAX_WINGMEN = 20
"""Up to this many wingmen each gets a legend entry; beyond, a colour bar of ids."""
LINE_STYLES = ("-", "--", "-.", ":")


@dataclass(frozen=True)
class FleetStyle:
    """How each vehicle (index 0 the leader) is drawn, and how the legend names them."""

    colours: list[RGBA]
    line_styles: list[str]
    summarised: bool
    """True when the wingmen are too many for a legend entry each (a colour bar instead)."""


def fleet_style(n: int) -> FleetStyle:
    """Colours and line styles for a fleet of ``n`` vehicles (the leader first)."""
    if n <= len(PAPER_COLOURS):
        return FleetStyle([to_rgba(c) for c in PAPER_COLOURS[:n]], ["-"] * n, summarised=False)
    wingmen = n - 1
    leader = [to_rgba("black")]
    if wingmen <= LEGEND_MAX_WINGMEN:
        tab20 = matplotlib.colormaps["tab20"]
        order = [*range(0, 20, 2), *range(1, 20, 2)]  # the ten dark colours, then the light
        colours = [to_rgba(tab20(order[k])) for k in range(wingmen)]
        styles = ["-" if k < 10 else "--" for k in range(wingmen)]
        return FleetStyle(leader + colours, ["-", *styles], summarised=False)
    viridis = matplotlib.colormaps["viridis"]
    colours = [to_rgba(viridis(x)) for x in np.linspace(0.0, 0.88, wingmen)]
    styles = [LINE_STYLES[k % len(LINE_STYLES)] for k in range(wingmen)]
    return FleetStyle(leader + colours, ["-", *styles], summarised=True)


def _label(run: PlanRun, i: int) -> str:
    vid = int(run.trajectory.ids[i])
    return f"leader (id {vid})" if i == 0 else f"wingman {i} (id {vid})"


def _plot_fleet(
    ax: Axes,
    run: PlanRun,
    x: FloatArray,
    ys: FloatArray,
    *,
    first: int = 0,
    lw: float = 1.0,
) -> FleetStyle:
    """One line per vehicle ``i >= first``: ``ys[:, i]`` against ``x``; labels for the
    legend (only the leader's when the fleet is summarised)."""
    style = fleet_style(run.trajectory.ids.shape[0])
    for i in range(first, ys.shape[1]):
        label = _label(run, i) if i == 0 or not style.summarised else None
        ax.plot(
            x,
            ys[:, i],
            color=style.colours[i],
            linestyle=style.line_styles[i],
            lw=lw * (1.4 if i == 0 and len(style.colours) > len(PAPER_COLOURS) else 1.0),
            label=label,
        )
    return style


def _legend(ax: Axes, run: PlanRun, style: FleetStyle) -> None:
    """The legend beside the axes (never over the data), in columns when long; with a
    summarised fleet, a colour bar of wingman ids beside it."""
    fig = ax.get_figure()
    assert isinstance(fig, Figure)
    if style.summarised:
        ids = run.trajectory.ids
        n = ids.shape[0]
        cmap = ListedColormap(style.colours[1:])
        norm = BoundaryNorm(np.arange(0.5, n), cmap.N)
        bar = fig.colorbar(
            ScalarMappable(norm=norm, cmap=cmap), ax=ax, pad=0.02, fraction=0.04, shrink=0.8
        )
        ticks = np.unique(np.linspace(1, n - 1, min(n - 1, 8)).round().astype(int))
        bar.set_ticks(ticks.tolist(), labels=[str(int(ids[k])) for k in ticks])
        bar.set_label(f"wingmen 1–{n - 1} (id)")
        bar.ax.tick_params(labelsize=7)
        ax.legend(loc="best", fontsize=7)
        return
    entries = len(ax.get_legend_handles_labels()[1])
    ax.legend(
        loc="upper left",
        bbox_to_anchor=(1.02, 1.0),
        borderaxespad=0.0,
        fontsize=7,
        ncol=1 if entries <= 12 else 2,
    )


def _nothing_to_draw(ax: Axes, t: FloatArray, why: str) -> None:
    """An empty panel over the flight's time span that says why it is empty."""
    ax.set_xlim(float(t[0]), float(max(t[-1], t[0] + 1.0)))
    ax.text(0.5, 0.7, why, transform=ax.transAxes, ha="center", va="center")


def _limit_line(ax: Axes, y: float, label: str | None = None) -> None:
    """A limit drawn as in the paper: a red dashed line."""
    ax.axhline(y, color="red", linestyle="--", linewidth=1.0, label=label)


def _save(fig: Figure, path: Path) -> None:
    """Write the figure (legends and colour bars beside the axes included) and close it."""
    try:
        fig.savefig(path, dpi=110, bbox_inches="tight")
    finally:
        plt.close(fig)


def _sphere(ax: object, centre: FloatArray, radius: float) -> None:
    u, v = np.mgrid[0 : 2 * np.pi : 24j, 0 : np.pi : 12j]
    x = centre[0] + radius * np.cos(u) * np.sin(v)
    y = centre[1] + radius * np.sin(u) * np.sin(v)
    z = centre[2] + radius * np.cos(v)
    ax.plot_wireframe(x, y, z, color="grey", alpha=0.25, linewidth=0.5)  # type: ignore[attr-defined]


def _zone_outline(zones: Zones, k: int) -> FloatArray:
    """Zone k's footprint as a closed ring [M, 2] (a circle as a 48-gon)."""
    if zones.kind[k] & POLYGON:
        ring = zones.verts[zones.vstart[k] : zones.vstart[k + 1]]
    else:
        a = np.linspace(0.0, 2.0 * np.pi, 48, endpoint=False)
        cx, cy, r = zones.geom[k, :3]
        ring = np.column_stack([cx + r * np.cos(a), cy + r * np.sin(a)])
    return np.vstack([ring, ring[:1]])


def _zone(ax: object, zones: Zones, k: int, z_span: tuple[float, float]) -> None:
    """Zone k as a wireframe prism: its footprint at the floor and the ceiling (an
    unbounded one drawn at the edge of the paths' heights) joined by vertical edges;
    an exclusion zone grey, an inclusion zone green and dashed."""
    ring = _zone_outline(zones, k)
    floor, ceiling = zones.geom[k, 3], zones.geom[k, 4]
    lo = floor if np.isfinite(floor) else z_span[0]
    hi = ceiling if np.isfinite(ceiling) else z_span[1]
    inclusion = bool(zones.kind[k] & INCLUSION)
    style = {"color": "green" if inclusion else "grey", "alpha": 0.5, "lw": 0.7}
    style["ls"] = "--" if inclusion else "-"
    for z in (lo, hi):
        ax.plot(ring[:, 0], ring[:, 1], np.full(len(ring), z), **style)  # type: ignore[attr-defined]
    step = max(1, (len(ring) - 1) // 12)
    for x, y in ring[:-1:step]:
        ax.plot([x, x], [y, y], [lo, hi], **style)  # type: ignore[attr-defined]


def paths_3d(run: PlanRun, path: Path) -> None:
    """Figs. 5a / 10: 3-D paths, start (circle) and target (triangle), obstacles."""
    tr = run.trajectory
    n = tr.ids.shape[0]
    style = fleet_style(n)
    fig = plt.figure(figsize=(9, 7), layout="constrained")
    ax = fig.add_subplot(projection="3d")
    for j in range(run.scene.obstacles.radius.shape[0]):
        _sphere(ax, run.scene.obstacles.center[j], float(run.scene.obstacles.radius[j]))
    z_span = (float(tr.pos[..., 2].min()), float(tr.pos[..., 2].max()))
    for k in range(len(run.scene.zones)):
        _zone(ax, run.scene.zones, k, z_span)
    for i in range(n):
        p = tr.pos[:, i]
        ax.plot(
            p[:, 0],
            p[:, 1],
            p[:, 2],
            color=style.colours[i],
            linestyle=style.line_styles[i],
            label=_label(run, i) if i == 0 or not style.summarised else None,
            lw=1.2,
        )
    starts = tr.pos[0]
    ax.scatter(starts[:, 0], starts[:, 1], starts[:, 2], color="red", marker="o", s=25)
    ax.scatter(*run.scene.target, color="red", marker="^", s=60, label="target")
    if len(run.waypoints):  # the leader's route, waypoint by waypoint to the target
        route = np.vstack([run.waypoints, run.scene.target])
        ax.plot(route[:, 0], route[:, 1], route[:, 2], color="red", ls=":", lw=1.0)
        w = run.waypoints
        ax.scatter(w[:, 0], w[:, 1], w[:, 2], color="red", marker="s", s=30, label="waypoints")
        a = np.linspace(0.0, 2.0 * np.pi, 121)
        for c, r in zip(w, run.loiter_radii_m, strict=False):
            if r > 0.0:  # the circle a loiter is flown on
                ax.plot(c[0] + r * np.cos(a), c[1] + r * np.sin(a), np.full_like(a, c[2]),
                        color="red", ls=":", lw=0.8)  # fmt: skip
    ax.set_xlabel("x east (m)")
    ax.set_ylabel("y north (m)")
    ax.set_zlabel("z up (m)")
    ax.set_title(f"Formation paths ({run.method.upper()}, Δt = {run.dt:g} s)")
    _legend(ax, run, style)
    _save(fig, path)


def leader_start(runs: Sequence[PlanRun], path: Path, seconds: float = 6.0) -> None:
    """Fig. 5b: the leader's path near its start, PPF against APF (plan view)."""
    fig, ax = plt.subplots(figsize=(6, 5), layout="constrained")
    styles = {"ppf": ("tab:blue", "-"), "apf": ("lightskyblue", "--")}
    for run in runs:
        tr = run.trajectory
        near = tr.t <= seconds
        colour, line = styles[run.method]
        ax.plot(
            tr.pos[near, 0, 0],
            tr.pos[near, 0, 1],
            line,
            color=colour,
            label=f"leader, {run.method.upper()}",
        )
    start = runs[0].trajectory.pos[0, 0]
    yaw = float(runs[0].trajectory.yaw[0, 0])
    ax.annotate(
        "",
        xy=(start[0] + 150 * math.cos(yaw), start[1] + 150 * math.sin(yaw)),
        xytext=(start[0], start[1]),
        arrowprops={"arrowstyle": "->", "color": "red"},
    )
    ax.scatter(
        start[0], start[1], color="red", marker="o", zorder=3, label="start, initial heading"
    )
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x east (m)")
    ax.set_ylabel("y north (m)")
    ax.set_title(f"Leader near the start (first {seconds:g} s)")
    ax.legend(fontsize=8)
    _save(fig, path)


def local_target_distance(runs: Sequence[PlanRun], path: Path, accuracy: float) -> None:
    """Figs. 6 / 11: each wingman's distance to its local target point (one panel a run)."""
    fig, axes = plt.subplots(
        len(runs), 1, figsize=(9, 3.4 * len(runs)), squeeze=False, layout="constrained"
    )
    for ax, run in zip(axes[:, 0], runs, strict=True):
        tr = run.trajectory
        gap = np.linalg.norm(local_target_points(tr, run.scene.fleet.slot) - tr.pos, axis=-1)
        style = _plot_fleet(ax, run, tr.t, gap, first=1)
        _limit_line(ax, accuracy, f"target accuracy {accuracy:g} m")
        if tr.ids.shape[0] == 1:
            _nothing_to_draw(ax, tr.t, "no wingmen")
        ax.set_yscale("log")
        ax.set_xlabel("t (s)")
        ax.set_ylabel("distance to local target (m)")
        ax.set_title(f"Wingmen following their local target points ({run.method.upper()})")
        _legend(ax, run, style)
    _save(fig, path)


def turn_per_step(
    run: PlanRun, path: Path, omega_pitch: float, omega_yaw: float, seconds: float = 25.0
) -> None:
    """Fig. 7: per-step pitch and yaw change against the ±ω·Δt limit (first 25 s)."""
    tr = run.trajectory
    near = tr.t[1:] <= seconds
    t = tr.t[1:][near]
    d_pitch = np.diff(tr.pitch, axis=0)[near]
    d_yaw = np.angle(np.exp(1j * np.diff(tr.yaw, axis=0)))[near]
    fig, axes = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True, layout="constrained")
    for ax, delta, omega, name in (
        (axes[0], d_pitch, omega_pitch, "pitch Δθ"),
        (axes[1], d_yaw, omega_yaw, "yaw Δψ"),
    ):
        style = _plot_fleet(ax, run, t, np.degrees(delta), lw=0.8)
        limit = math.degrees(omega * run.dt)
        _limit_line(ax, limit, f"±ω·Δt = ±{limit:.3f}°")
        _limit_line(ax, -limit)
        ax.set_ylabel(f"{name} per step (deg)")
        _legend(ax, run, style)
    axes[1].set_xlabel("t (s)")
    axes[0].set_title(f"Turn per step ({run.method.upper()}, Δt = {run.dt:g} s)")
    _save(fig, path)


def speeds(run: PlanRun, path: Path, v_min: float, v_max: float) -> None:
    """Fig. 8: speed of every vehicle."""
    tr = run.trajectory
    fig, ax = plt.subplots(figsize=(9, 4.5), layout="constrained")
    style = _plot_fleet(ax, run, tr.t, tr.speed)
    for v in (v_min, v_max):
        _limit_line(ax, v)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("speed (m/s)")
    ax.set_title(f"Speeds ({run.method.upper()})")
    _legend(ax, run, style)
    _save(fig, path)


def nearest_teammate_distance(pos: FloatArray) -> FloatArray:
    """[K, N] distance from each vehicle to its nearest teammate (inf alone); one vehicle
    at a time, so memory grows as K·N, not K·N²."""
    k, n, _ = pos.shape
    nearest = np.full((k, n), np.inf)
    for i in range(n):
        gap = np.linalg.norm(pos - pos[:, i : i + 1], axis=-1)
        gap[:, i] = np.inf
        nearest[:, i] = gap.min(axis=1)
    return nearest


def min_vehicle_distance(run: PlanRun, path: Path, safe: float) -> None:
    """Fig. 12: each vehicle's distance to its nearest teammate."""
    tr = run.trajectory
    fig, ax = plt.subplots(figsize=(9, 4.5), layout="constrained")
    if tr.ids.shape[0] > 1:
        style = _plot_fleet(ax, run, tr.t, nearest_teammate_distance(tr.pos))
    else:
        style = fleet_style(1)
        _nothing_to_draw(ax, tr.t, "one vehicle: no teammates")
    _limit_line(ax, safe, f"safe distance {safe:g} m")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("distance to nearest teammate (m)")
    ax.set_title(f"Minimum vehicle–vehicle distance ({run.method.upper()})")
    _legend(ax, run, style)
    _save(fig, path)


def obstacle_clearance(run: PlanRun) -> FloatArray:
    """[K, N]: each vehicle's distance to the nearest obstacle or zone surface (a zone's
    free side positive, as metrics' ``min_obstacle_clearance_m`` counts it)."""
    tr = run.trajectory
    obs = run.scene.obstacles
    clear = np.full(tr.speed.shape, np.inf)
    for j in range(obs.radius.shape[0]):  # one obstacle at a time: memory K·N
        centre = obs.center[j][None] + tr.t[:, None] * obs.velocity[j][None]
        gap = np.linalg.norm(tr.pos - centre[:, None], axis=-1) - obs.radius[j]
        clear = np.minimum(clear, gap)
    if len(run.scene.zones):
        k, n = tr.speed.shape
        to_zones = zone_clearances(tr.pos.reshape(k * n, 3), run.scene.zones)
        clear = np.minimum(clear, to_zones.min(axis=1).reshape(k, n))
    return clear


def min_obstacle_distance(run: PlanRun, path: Path, safe: float) -> None:
    """Fig. 13: each vehicle's distance to the nearest obstacle or zone surface."""
    fig, ax = plt.subplots(figsize=(9, 4.5), layout="constrained")
    style = _plot_fleet(ax, run, run.trajectory.t, obstacle_clearance(run))
    _limit_line(ax, safe, f"safe distance {safe:g} m")
    ax.set_yscale("log")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("distance to nearest obstacle surface (m)")
    ax.set_title(f"Minimum vehicle–obstacle distance ({run.method.upper()})")
    _legend(ax, run, style)
    _save(fig, path)


def dt_sweep(rows: Sequence[dict[str, float]], path: Path) -> None:
    """Fig. 9: planning wall time against the planned flight time for several Δt."""
    dts = [r["dt_s"] for r in rows]
    fig, ax = plt.subplots(figsize=(7, 4), layout="constrained")
    x = np.arange(len(rows))
    ax.bar(x - 0.2, [r["flight_time_s"] for r in rows], width=0.4, label="flight time (s)")
    ax.bar(
        x + 0.2,
        [r["planning_wall_time_s"] for r in rows],
        width=0.4,
        label="planning wall time (s)",
    )
    ax.set_yscale("log")
    ax.set_xticks(x, [f"{d:g}" for d in dts])
    ax.set_xlabel("Δt (s)")
    ax.set_ylabel("seconds")
    ax.set_title("Planning time against flight time")
    for xi, r in zip(x, rows, strict=True):
        ax.annotate(
            f"{r['real_time_factor']:.0f}×",
            (xi + 0.2, r["planning_wall_time_s"]),
            ha="center",
            va="bottom",
            fontsize=8,
        )
    ax.legend(fontsize=8)
    _save(fig, path)


def _closing(draw: Draw) -> Draw:
    """``draw``, closing the figures it leaves open when it fails."""

    def run(path: Path) -> None:
        before = set(plt.get_fignums())
        try:
            draw(path)
        except BaseException:
            for num in set(plt.get_fignums()) - before:
                plt.close(num)
            raise

    return run


def plan_figures(
    mission: Mission,
    run: PlanRun,
    baseline: PlanRun,
    sweep: Sequence[dict[str, float]] | None = None,
) -> list[tuple[str, Draw]]:
    """The figures of ``gcs-ppf plan``: (file name, drawing function taking the path)."""
    lim = mission.limits
    runs = [run, baseline] if run.method == "ppf" else [baseline, run]
    apf_first = sorted(runs, key=lambda r: r.method)  # Fig. 6: (a) APF, (b) PPF
    jobs: list[tuple[str, Draw]] = [
        ("fig05_10_paths.png", lambda p: paths_3d(run, p)),
        ("fig05b_leader_start.png", lambda p: leader_start(runs, p)),
        (
            "fig06_11_local_target_distance.png",
            lambda p: local_target_distance(apf_first, p, lim.target_accuracy),
        ),
        (
            "fig07_turn_per_step.png",
            lambda p: turn_per_step(run, p, lim.max_pitch_rate, lim.max_yaw_rate),
        ),
        ("fig08_speed.png", lambda p: speeds(run, p, lim.v_min, lim.v_max)),
        (
            "fig12_min_vehicle_distance.png",
            lambda p: min_vehicle_distance(run, p, lim.safe_distance_uav),
        ),
    ]
    if mission.obstacles or mission.zones:
        jobs.append(
            (
                "fig13_min_obstacle_distance.png",
                lambda p: min_obstacle_distance(run, p, lim.safe_distance_obstacle),
            )
        )
    if sweep is not None:
        rows = list(sweep)
        jobs.append(("fig09_dt_sweep.png", lambda p: dt_sweep(rows, p)))
    return [(name, _closing(draw)) for name, draw in jobs]

"""PNG figures that reproduce the paper's Figs. 5–13 from planned trajectories."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from gcs_ppf.offline.plan import PlanRun
from gcs_ppf.planning.metrics import local_target_points
from gcs_ppf.planning.scene import FloatArray

PAPER_COLOURS = ["tab:blue", "gold", "tab:red", "tab:green", "black"]


def _colour(i: int) -> str:
    if i < len(PAPER_COLOURS):
        return PAPER_COLOURS[i]
    return str(matplotlib.colormaps["tab20"](i % 20))


def _label(run: PlanRun, i: int) -> str:
    vid = int(run.trajectory.ids[i])
    return f"leader (id {vid})" if i == 0 else f"wingman {i} (id {vid})"


def _limit_line(ax: Axes, y: float, label: str | None = None) -> None:
    """A limit drawn as in the paper: a red dashed line."""
    ax.axhline(y, color="red", linestyle="--", linewidth=1.0, label=label)


def _save(fig: Figure, path: Path) -> None:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _sphere(ax: object, centre: FloatArray, radius: float) -> None:
    u, v = np.mgrid[0 : 2 * np.pi : 24j, 0 : np.pi : 12j]
    x = centre[0] + radius * np.cos(u) * np.sin(v)
    y = centre[1] + radius * np.sin(u) * np.sin(v)
    z = centre[2] + radius * np.cos(v)
    ax.plot_wireframe(x, y, z, color="grey", alpha=0.25, linewidth=0.5)  # type: ignore[attr-defined]


def paths_3d(run: PlanRun, path: Path) -> None:
    """Figs. 5a / 10: 3-D paths, start (circle) and target (triangle), obstacles."""
    tr = run.trajectory
    fig = plt.figure(figsize=(8, 7))
    ax = fig.add_subplot(projection="3d")
    for j in range(run.scene.obstacles.radius.shape[0]):
        _sphere(ax, run.scene.obstacles.center[j], float(run.scene.obstacles.radius[j]))
    for i in range(tr.ids.shape[0]):
        p = tr.pos[:, i]
        ax.plot(p[:, 0], p[:, 1], p[:, 2], color=_colour(i), label=_label(run, i), lw=1.2)
        ax.scatter(*p[0], color="red", marker="o", s=25)
    ax.scatter(*run.scene.target, color="red", marker="^", s=60, label="target")
    ax.set_xlabel("x east (m)")
    ax.set_ylabel("y north (m)")
    ax.set_zlabel("z up (m)")
    ax.set_title(f"Formation paths ({run.method.upper()}, Δt = {run.dt:g} s)")
    ax.legend(loc="upper left", fontsize=8)
    _save(fig, path)


def leader_start(runs: Sequence[PlanRun], path: Path, seconds: float = 6.0) -> None:
    """Fig. 5b: the leader's path near its start, PPF against APF (plan view)."""
    fig, ax = plt.subplots(figsize=(6, 5))
    styles = {"ppf": ("tab:blue", "-"), "apf": ("lightskyblue", "--")}
    for run in runs:
        tr = run.trajectory
        near = tr.t <= seconds
        colour, style = styles[run.method]
        ax.plot(
            tr.pos[near, 0, 0],
            tr.pos[near, 0, 1],
            style,
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
    fig, axes = plt.subplots(len(runs), 1, figsize=(8, 3.2 * len(runs)), squeeze=False)
    for ax, run in zip(axes[:, 0], runs, strict=True):
        tr = run.trajectory
        gap = np.linalg.norm(local_target_points(tr, run.scene.fleet.slot) - tr.pos, axis=-1)
        for i in range(1, tr.ids.shape[0]):
            ax.plot(tr.t, gap[:, i], color=_colour(i), label=_label(run, i), lw=1.0)
        _limit_line(ax, accuracy, f"target accuracy {accuracy:g} m")
        ax.set_yscale("log")
        ax.set_xlabel("t (s)")
        ax.set_ylabel("distance to local target (m)")
        ax.set_title(f"Wingmen following their local target points ({run.method.upper()})")
        ax.legend(fontsize=7, ncol=2)
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
    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for ax, delta, omega, name in (
        (axes[0], d_pitch, omega_pitch, "pitch Δθ"),
        (axes[1], d_yaw, omega_yaw, "yaw Δψ"),
    ):
        for i in range(tr.ids.shape[0]):
            ax.plot(t, np.degrees(delta[:, i]), color=_colour(i), lw=0.8, label=_label(run, i))
        limit = math.degrees(omega * run.dt)
        _limit_line(ax, limit, f"±ω·Δt = ±{limit:.3f}°")
        _limit_line(ax, -limit)
        ax.set_ylabel(f"{name} per step (deg)")
        ax.legend(fontsize=7, ncol=3)
    axes[1].set_xlabel("t (s)")
    axes[0].set_title(f"Turn per step ({run.method.upper()}, Δt = {run.dt:g} s)")
    _save(fig, path)


def speeds(run: PlanRun, path: Path, v_min: float, v_max: float) -> None:
    """Fig. 8: speed of every vehicle."""
    tr = run.trajectory
    fig, ax = plt.subplots(figsize=(8, 4))
    for i in range(tr.ids.shape[0]):
        ax.plot(tr.t, tr.speed[:, i], color=_colour(i), label=_label(run, i), lw=1.0)
    for v in (v_min, v_max):
        _limit_line(ax, v)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("speed (m/s)")
    ax.set_title(f"Speeds ({run.method.upper()})")
    ax.legend(fontsize=7, ncol=3)
    _save(fig, path)


def min_vehicle_distance(run: PlanRun, path: Path, safe: float) -> None:
    """Fig. 12: each vehicle's distance to its nearest teammate."""
    tr = run.trajectory
    n = tr.ids.shape[0]
    gaps = np.linalg.norm(tr.pos[:, :, None] - tr.pos[:, None], axis=-1)
    gaps[:, np.arange(n), np.arange(n)] = np.inf
    fig, ax = plt.subplots(figsize=(8, 4))
    for i in range(n):
        ax.plot(tr.t, gaps[:, i].min(axis=1), color=_colour(i), label=_label(run, i), lw=1.0)
    _limit_line(ax, safe, f"safe distance {safe:g} m")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("distance to nearest teammate (m)")
    ax.set_title(f"Minimum vehicle–vehicle distance ({run.method.upper()})")
    ax.legend(fontsize=7, ncol=3)
    _save(fig, path)


def min_obstacle_distance(run: PlanRun, path: Path, safe: float) -> None:
    """Fig. 13: each vehicle's distance to the nearest obstacle surface."""
    tr = run.trajectory
    obs = run.scene.obstacles
    centres = obs.center[None] + tr.t[:, None, None] * obs.velocity[None]
    clear = np.linalg.norm(tr.pos[:, :, None] - centres[:, None], axis=-1) - obs.radius
    fig, ax = plt.subplots(figsize=(8, 4))
    for i in range(tr.ids.shape[0]):
        ax.plot(tr.t, clear[:, i].min(axis=1), color=_colour(i), label=_label(run, i), lw=1.0)
    _limit_line(ax, safe, f"safe distance {safe:g} m")
    ax.set_yscale("log")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("distance to nearest obstacle surface (m)")
    ax.set_title(f"Minimum vehicle–obstacle distance ({run.method.upper()})")
    ax.legend(fontsize=7, ncol=3)
    _save(fig, path)


def dt_sweep(rows: Sequence[dict[str, float]], path: Path) -> None:
    """Fig. 9: planning wall time against the planned flight time for several Δt."""
    dts = [r["dt_s"] for r in rows]
    fig, ax = plt.subplots(figsize=(7, 4))
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

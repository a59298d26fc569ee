"""PNG figures of a sweep: outcomes per family, the distributions of separation and
clearance against the safe distances, flight time against the straight-line time.

Drawn as ``gcs_ppf.offline.plots`` draws a plan's (safe distances as red dashed lines,
figures written whole and closed); one colour per family.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.ticker import NullFormatter, StrMethodFormatter

from gcs_ppf.offline.plots import _save
from gcs_ppf.offline.sweep.rows import Outcome, SceneRow
from gcs_ppf.offline.sweep.spec import SceneSpec
from gcs_ppf.offline.sweep.summary import families, figures, straight_line_and_flight

Draw = Callable[[Path], None]
OUTCOME_COLOURS = {
    Outcome.REACHED: "tab:green",
    Outcome.NOT_REACHED: "tab:grey",
    Outcome.CLEARANCE: "tab:red",
    Outcome.GROUND: "tab:brown",
    Outcome.SEPARATION: "tab:orange",
    Outcome.ERROR: "black",
}


def _family_colour(k: int) -> str:
    return f"C{k % 10}"


def outcomes(rows: Sequence[SceneRow], path: Path) -> None:
    """Each family's scenes by outcome (a bar of shares), its failure rate beside it."""
    groups = families(rows)
    names = list(groups)
    fig, ax = plt.subplots(figsize=(9, 1.2 + 0.6 * len(names)), layout="constrained")
    left = np.zeros(len(names))
    for outcome in (Outcome.REACHED, *[o for o in Outcome if o != Outcome.REACHED]):
        share = np.array(
            [sum(r.outcome == outcome for r in groups[n]) / len(groups[n]) for n in names]
        )
        if share.any():
            ax.barh(names, share, left=left, color=OUTCOME_COLOURS[outcome], label=outcome.value)
        left += share
    for k, name in enumerate(names):
        failed = sum(r.outcome != Outcome.REACHED for r in groups[name])
        ax.annotate(
            f"failed {failed} of {len(groups[name])} ({100 * failed / len(groups[name]):.1f} %)",
            (1.01, k),
            va="center",
            fontsize=8,
            annotation_clip=False,
        )
    ax.set_xlim(0.0, 1.0)
    ax.invert_yaxis()
    ax.set_xlabel("share of the family's scenes")
    ax.set_title("Outcome of each scene, per family")
    ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.25 - 0.1 / len(names)), ncol=6, fontsize=8)
    _save(fig, path)


def _histograms(ax: Axes, rows: Sequence[SceneRow], field: str, safe: Sequence[float]) -> None:
    """One step histogram per family of ``field``, the safe distances as limit lines."""
    groups = families(rows)
    values = {name: figures(group, field) for name, group in groups.items()}
    every = [v for vs in values.values() for v in vs]
    if not every:
        ax.text(0.5, 0.5, "no scene has this figure", transform=ax.transAxes, ha="center")
        return
    bins = np.linspace(min([*every, *safe]), max(every), 80).tolist()
    for k, (name, vs) in enumerate(values.items()):
        if vs:
            ax.hist(
                vs, bins=bins, histtype="step", color=_family_colour(k), label=f"{name} ({len(vs)})"
            )
    for s in sorted(set(safe)):  # a limit as in the paper's figures: a red dashed line
        ax.axvline(s, color="red", linestyle="--", linewidth=1.0, label=f"safe distance {s:g} m")
    ax.set_yscale("log")  # the tail near the safe distance shows
    ax.yaxis.set_major_formatter(StrMethodFormatter("{x:.0f}"))
    ax.yaxis.set_minor_formatter(NullFormatter())
    ax.set_ylabel("scenes")
    ax.legend(fontsize=8)


def separation_and_clearance(
    rows: Sequence[SceneRow], path: Path, specs: Sequence[SceneSpec]
) -> None:
    """Histograms of each scene's minimum separation and minimum obstacle clearance."""
    fig, axes = plt.subplots(2, 1, figsize=(9, 7), layout="constrained")
    _histograms(axes[0], rows, "min_separation_m", [s.limits.safe_distance_uav for s in specs])
    axes[0].set_xlabel("smallest distance between two vehicles over the flight (m)")
    axes[0].set_title("Separation (each scene's minimum)")
    _histograms(
        axes[1], rows, "min_obstacle_clearance_m", [s.limits.safe_distance_obstacle for s in specs]
    )
    axes[1].set_xlabel("smallest distance from a vehicle to an obstacle surface (m)")
    axes[1].set_title("Obstacle clearance (each scene's minimum)")
    _save(fig, path)


def flight_against_straight_line(rows: Sequence[SceneRow], path: Path) -> None:
    """Each reached scene's flight time against its straight-line time at v_max."""
    fig, ax = plt.subplots(figsize=(7, 6), layout="constrained")
    top = 0.0
    for k, (name, group) in enumerate(families(rows).items()):
        done = straight_line_and_flight(group)
        x, y = [p[0] for p in done], [p[1] for p in done]
        ax.scatter(x, y, s=4, alpha=0.4, color=_family_colour(k), label=f"{name} ({len(done)})")
        top = max(top, *x, *y, 1.0)
    ax.plot(
        [0.0, top],
        [0.0, top],
        color="black",
        linestyle=":",
        linewidth=1.0,
        label="flight = straight line",
    )
    ax.set_xlim(0.0, top * 1.02)
    ax.set_ylim(0.0, top * 1.02)
    ax.set_xlabel("straight-line time of the leader at v_max (s)")
    ax.set_ylabel("flight time (s)")
    ax.set_title("Flight time against the straight-line time (reached scenes)")
    ax.legend(fontsize=8, markerscale=3)
    _save(fig, path)


def sweep_figures(rows: Sequence[SceneRow], specs: Sequence[SceneSpec]) -> list[tuple[str, Draw]]:
    """The figures of ``gcs-ppf sweep``: (file name, drawing function taking the path)."""
    return [
        ("sweep_outcomes.png", lambda p: outcomes(rows, p)),
        ("sweep_separation_clearance.png", lambda p: separation_and_clearance(rows, p, specs)),
        ("sweep_flight_time.png", lambda p: flight_against_straight_line(rows, p)),
    ]

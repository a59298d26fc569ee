"""Planner speed: real-time factor (flight seconds per wall second, one core).

``python -m gcs_ppf.offline.benchmark`` (or ``make bench``) prints a table for the paper's
Table 3 scene and for synthetic formations of N vehicles among M obstacles.  Timing
excludes the one-time compilation; each figure is the best of a few repeats.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from gcs_ppf.mission import Limits, PlannerSettings, load_mission_file
from gcs_ppf.offline.plan import plan_mission, warm_up
from gcs_ppf.planning.planner import advance
from gcs_ppf.planning.ppf.reference import reference_step
from gcs_ppf.planning.scene import Fleet, Obstacles, Scene, kernel_limits

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
SIZES = ((5, 4), (20, 20), (100, 100), (500, 200))


def synthetic_scene(n_vehicles: int, n_obstacles: int, seed: int = 7) -> Scene:
    """A leader and N−1 wingmen in rows of ten behind it (100 m apart), starting off
    their slots, flying east towards a target 40 km away through M spheres."""
    rng = np.random.default_rng(seed)
    k = np.arange(n_vehicles)
    row, col = (k - 1) // 10 + 1, (k - 1) % 10 - 4.5
    slot = np.stack([-100.0 * row, 100.0 * col, np.zeros(n_vehicles)], axis=1)
    slot[0] = 0.0
    pos = slot + rng.uniform(-30.0, 30.0, size=(n_vehicles, 3))
    pos[0] = 0.0
    centre = np.stack([
        rng.uniform(3000.0, 38000.0, n_obstacles),
        rng.uniform(-6000.0, 6000.0, n_obstacles),
        rng.uniform(-300.0, 300.0, n_obstacles),
    ], axis=1)  # fmt: skip
    fleet = Fleet(
        ids=k.astype(np.int64) + 1,
        pos=pos,
        pitch=np.zeros(n_vehicles),
        yaw=rng.uniform(-0.2, 0.2, n_vehicles),
        speed=np.full(n_vehicles, 100.0),
        slot=slot,
        rank=k.astype(np.int64),
        active=np.ones(n_vehicles, dtype=bool),
    )
    obstacles = Obstacles(
        center=centre,
        radius=rng.uniform(50.0, 300.0, n_obstacles),
        velocity=np.zeros((n_obstacles, 3)),
    )
    return Scene(fleet, obstacles, np.array([40_000.0, 0.0, 0.0]), kernel_limits(Limits()))


def time_scene(scene: Scene, dt: float, flight_s: float, repeats: int) -> tuple[float, float]:
    """Best wall time of ``repeats`` runs of ``flight_s`` seconds; returns (wall, flight)."""
    steps = round(flight_s / dt)
    warm_up(scene, dt, "ppf")
    best, flown = float("inf"), 0.0
    for _ in range(repeats):
        start = time.perf_counter()
        result = advance(scene, dt, steps, record_every=steps)
        best = min(best, time.perf_counter() - start)
        flown = result.elapsed_s
    return best, flown


def time_reference(scene: Scene, dt: float, steps: int) -> tuple[float, float]:
    """Wall time of ``steps`` steps of the plain-numpy reference (a Python loop)."""
    f, o = scene.fleet.copy(), scene.obstacles.copy()
    pos, pitch, yaw, speed = f.pos, f.pitch, f.yaw, f.speed
    start = time.perf_counter()
    for k in range(steps):
        centre = o.center + o.velocity * (k * dt)
        pos, pitch, yaw, speed, _ = reference_step(
            pos,
            pitch,
            yaw,
            speed,
            f.slot,
            f.rank,
            f.active,
            centre,
            o.radius,
            o.velocity,
            scene.target,
            scene.limits,
            dt,
        )
    return time.perf_counter() - start, steps * dt


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--dt", type=float, default=PlannerSettings().dt)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="skip the 500 × 200 scene")
    args = parser.parse_args(argv)

    rows: list[tuple[str, float, float, str]] = []
    mission = load_mission_file(EXAMPLES / "paper_table3.json")
    runs = [plan_mission(mission, dt=args.dt) for _ in range(args.repeats)]
    best = min(runs, key=lambda r: r.wall_time_s)
    flight = best.metrics["simulated_time_s"]
    rows.append(("paper Table 3 (5 × 4), whole plan", flight, best.wall_time_s, "≥ 5000×"))
    wall, flown = time_reference(best.scene, args.dt, 2000)
    rows.append(("Table 3, plain-numpy reference step", flown, wall, "(for comparison)"))
    for n, m in SIZES:
        if args.quick and n >= 500:
            continue
        flight_s = 20.0 if n <= 100 else 5.0
        wall, flown = time_scene(synthetic_scene(n, m), args.dt, flight_s, args.repeats)
        rows.append((f"{n} vehicles × {m} obstacles", flown, wall, "≥ 200×" if n == 100 else ""))

    print(f"PPF planner speed, Δt = {args.dt:g} s, one core (numba), best of {args.repeats}")
    print(f"{'scene':<36} {'flight s':>9} {'wall ms':>10} {'× real time':>12}  target")
    for name, flown, wall, target in rows:
        print(f"{name:<36} {flown:>9.2f} {wall * 1e3:>10.2f} {flown / wall:>12.0f}  {target}")


if __name__ == "__main__":
    main()

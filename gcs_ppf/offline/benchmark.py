"""Planner speed: real-time factor (flight seconds per wall second, one core).

``python -m gcs_ppf.offline.benchmark`` (or ``make bench``) prints a table for the paper's
Table 3 scene and for synthetic formations of N vehicles among M obstacles.  Timing
excludes the one-time compilation; each figure is the best of a few repeats.  The CPU
time of the process is printed beside the wall time: on a machine shared with other
work the wall time measures the load as much as the planner.  ``--mates`` chooses how
teammates are found (``gcs_ppf.planning.ppf.neighbours``; the plan is the same).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from gcs_ppf.mission import Limits, load_mission_file
from gcs_ppf.offline.plan import plan_mission, warm_up
from gcs_ppf.planning.planner import MateSearch, advance
from gcs_ppf.planning.ppf.reference import reference_step
from gcs_ppf.planning.scene import Fleet, Obstacles, Scene, kernel_limits

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
SIZES = ((5, 4), (20, 20), (100, 100), (500, 200), (1000, 1000))


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


def time_scene(
    scene: Scene, dt: float, flight_s: float, repeats: int, mates: MateSearch = "auto"
) -> tuple[float, float, float]:
    """Best wall and CPU time of ``repeats`` runs of ``flight_s`` seconds; returns
    (wall, CPU, flight)."""
    steps = round(flight_s / dt)
    warm_up(scene, dt, "ppf")
    best, best_cpu, flown = float("inf"), float("inf"), 0.0
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        result = advance(scene, dt, steps, record_every=steps, mates=mates)
        best = min(best, time.perf_counter() - start)
        best_cpu = min(best_cpu, time.process_time() - start_cpu)
        flown = result.elapsed_s
    return best, best_cpu, flown


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
    parser.add_argument("--dt", type=float, default=0.01)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="skip the scenes of 500 and more")
    parser.add_argument(
        "--mates", choices=("auto", "all-pairs", "grid"), default="auto", help="teammate search"
    )
    args = parser.parse_args(argv)

    rows: list[tuple[str, float, float, float | None, str]] = []
    mission = load_mission_file(EXAMPLES / "paper_table3.json")
    runs = [plan_mission(mission, dt=args.dt) for _ in range(args.repeats)]
    best = min(runs, key=lambda r: r.wall_time_s)
    flight = best.metrics["simulated_time_s"]
    rows.append(("paper Table 3 (5 × 4), whole plan", flight, best.wall_time_s, None, "≥ 10000×"))
    wall, flown = time_reference(best.scene, args.dt, 2000)
    rows.append(("Table 3, plain-numpy reference step", flown, wall, None, "(for comparison)"))
    targets = {100: "≥ 400×", 500: "≥ 50×"}
    for n, m in SIZES:
        if args.quick and n >= 500:
            continue
        flight_s = 20.0 if n <= 100 else 5.0
        scene = synthetic_scene(n, m)
        wall, cpu, flown = time_scene(scene, args.dt, flight_s, args.repeats, args.mates)
        rows.append((f"{n} vehicles × {m} obstacles", flown, wall, cpu, targets.get(n, "")))

    print(
        f"PPF planner speed, Δt = {args.dt:g} s, one core (numba), best of {args.repeats},"
        f" teammates: {args.mates}"
    )
    print(
        f"{'scene':<36} {'flight s':>9} {'wall ms':>10} {'× real time':>12}"
        f" {'CPU ms':>9} {'× (CPU)':>8}  target"
    )
    for name, flown, wall, cpu_s, target in rows:
        on_cpu = f"{cpu_s * 1e3:>9.2f} {flown / cpu_s:>8.0f}" if cpu_s else f"{'':>9} {'':>8}"
        print(
            f"{name:<36} {flown:>9.2f} {wall * 1e3:>10.2f} {flown / wall:>12.0f} {on_cpu}  {target}"
        )


if __name__ == "__main__":
    main()

"""`gcs-ppf sweep FAMILY ... --n N`: plan N random scenes of each family, write the table,
its summary and figures.

Scenes are planned in a process pool of ``--jobs`` workers (in this process with
``--jobs 1``), or on Ray with ``--ray ADDRESS``; a progress bar counts them. ``DIR`` gets
``sweep.csv`` (``table.py``), ``summary.json`` (the command, the families' specs, the wall
time, ``summary.py``'s figures per family) first, all or nothing, then the figures
(``plots.py``). ``gcs_ppf.cli`` parses the arguments.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from tqdm import tqdm

from gcs_ppf.offline import output
from gcs_ppf.offline.sweep.batches import (
    Batch,
    batch_size,
    in_order,
    make_batches,
    plan_here,
    plan_in_pool,
)
from gcs_ppf.offline.sweep.cluster import ClusterError, plan_on_ray
from gcs_ppf.offline.sweep.families import FAMILIES
from gcs_ppf.offline.sweep.rows import Outcome, SceneRow
from gcs_ppf.offline.sweep.scenes import SceneError, draw_scene
from gcs_ppf.offline.sweep.spec import SceneSpec, SpecError, load_spec_file
from gcs_ppf.offline.sweep.summary import describe, summarise
from gcs_ppf.offline.sweep.table import write_table

EXIT_BAD_INPUT = 2
EXIT_PLOT_FAILED = 3  # table and summary written, some figures not
TABLE = "sweep.csv"
SUMMARY = "summary.json"
log = logging.getLogger("gcs_ppf")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The arguments of ``gcs-ppf sweep``."""
    parser.add_argument(
        "families",
        nargs="+",
        metavar="FAMILY",
        help=f"a named family ({', '.join(FAMILIES)}) or a spec file (.toml or .json)",
    )
    parser.add_argument("--n", type=int, required=True, help="scenes of each family")
    parser.add_argument("--seed", type=int, default=0, help="the sweep's seed (default 0)")
    parser.add_argument(
        "--jobs",
        type=int,
        default=os.cpu_count() or 1,
        help="worker processes (default: one per CPU; 1: plan in this process); "
        "with --ray local, the CPUs of the local Ray",
    )
    parser.add_argument(
        "--ray",
        metavar="ADDRESS",
        help="plan on Ray: 'local' starts one here, else a cluster's address (ray.init)",
    )
    parser.add_argument("--batch", type=int, help="scenes per task (default: about 8 per worker)")
    parser.add_argument("--out", type=Path, default=Path("out/sweep"), help="output directory")
    parser.add_argument("--no-plots", action="store_true", help="write the table and summary only")


def resolve_family(name: str) -> SceneSpec:
    """A named family, or the spec in the file ``name``; ``SpecError`` naming the field."""
    if name in FAMILIES:
        return FAMILIES[name]
    path = Path(name)
    if not path.is_file():
        raise SpecError(
            "FAMILY", f"{name!r} is neither a family ({', '.join(FAMILIES)}) nor a file"
        )
    return load_spec_file(path)


def _check_inputs(args: argparse.Namespace) -> list[SceneSpec]:
    """The families to sweep; ``SpecError`` or ``SceneError`` on bad input."""
    for flag, value in (("--n", args.n), ("--jobs", args.jobs), ("--batch", args.batch or 1)):
        if value < 1:
            raise SpecError(flag, "must be at least 1")
    if args.seed < 0:
        raise SpecError("--seed", "must not be negative")
    specs = [resolve_family(name) for name in args.families]
    names = [s.name for s in specs]
    if len(set(names)) != len(names):
        raise SpecError("FAMILY", f"two families share a name: {names}")
    for spec in specs:  # a family that cannot make a scene fails now, not in every row
        draw_scene(spec, args.seed, 0)
    return specs


def _plan(args: argparse.Namespace, batches: Sequence[Batch], total: int) -> list[SceneRow]:
    """Plan every batch where ``args`` says, with a progress bar."""
    with tqdm(total=total, desc="sweep", unit="scene", smoothing=0.05) as bar:
        failed = 0

        def progress(rows: Sequence[SceneRow]) -> None:
            nonlocal failed
            failed += sum(r.outcome != Outcome.REACHED for r in rows)
            bar.update(len(rows))
            bar.set_postfix(failed=failed, refresh=False)

        if args.ray:
            return plan_on_ray(batches, args.ray, progress, num_cpus=args.jobs)
        if args.jobs == 1:
            return plan_here(batches, progress)
        return plan_in_pool(batches, args.jobs, progress)


def sweep_command(args: argparse.Namespace) -> int:
    try:
        specs = _check_inputs(args)
    except (SpecError, SceneError) as exc:
        print(f"gcs-ppf: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    total = args.n * len(specs)
    where = f"Ray at {args.ray}" if args.ray else f"{args.jobs} process(es)"
    log.info(
        "sweeping %d scenes of %s (seed %d) on %s",
        total,
        ", ".join(args.families),
        args.seed,
        where,
    )
    batches = make_batches(specs, args.n, args.seed, args.batch or batch_size(total, args.jobs))
    start = time.perf_counter()
    try:
        rows = in_order(_plan(args, batches, total), specs)
    except ClusterError as exc:
        print(f"gcs-ppf: error: --ray: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    wall = time.perf_counter() - start
    summary: dict[str, Any] = {
        "command": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
        "specs": {s.name: s.model_dump() for s in specs},
        "scenes": total,
        "wall_time_s": wall,
        "scenes_per_s": total / wall,
        "families": summarise(rows),
    }
    out_dir = args.out.resolve()

    def fill(d: Path) -> None:
        write_table(rows, d / TABLE)
        output.write_json(summary, d / SUMMARY)

    output.write_atomically(out_dir, fill)
    for line in describe(summary["families"]):
        log.info("%s", line)
    log.info("%d scenes in %.1f s (%.1f scenes/s)", total, wall, total / wall)
    if args.no_plots:
        log.info("table and summary are in %s/", args.out)
        return 0
    from gcs_ppf.offline.sweep.plots import sweep_figures  # matplotlib only when plotting

    errors = output.draw_figures(out_dir, sweep_figures(rows, specs))
    if errors:
        output.replace_json({**summary, "plot_errors": errors}, out_dir / SUMMARY)
        for name, error in errors.items():
            print(f"gcs-ppf: error: figure {name} not drawn: {error}", file=sys.stderr)
        return EXIT_PLOT_FAILED
    log.info("table, summary and plots are in %s/", args.out)
    return 0

"""The `gcs-ppf` command line: plan (``gcs_ppf.offline.command``), sweep
(``gcs_ppf.offline.sweep.command``), serve, demo, arduplane-sitl."""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Sequence
from pathlib import Path

from gcs_ppf.mission import MissionError, load_mission_file
from gcs_ppf.offline.command import EXIT_BAD_INPUT, plan_command
from gcs_ppf.offline.sweep.command import add_arguments as add_sweep_arguments
from gcs_ppf.offline.sweep.command import sweep_command

log = logging.getLogger("gcs_ppf")


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not 0.0 < value <= 1.0:
        raise argparse.ArgumentTypeError(f"must be in (0, 1] seconds: {text!r}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="gcs-ppf", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    plan = sub.add_parser("plan", help="plan a mission offline and write metrics and plots")
    plan.add_argument("mission", type=Path, help="mission document (JSON, CONVENTIONS §3)")
    plan.add_argument("--out", type=Path, required=True, help="output directory")
    plan.add_argument("--method", choices=["ppf", "apf"], help="override planner.method")
    plan.add_argument("--dt", type=_positive_float, help="override planner.dt (seconds)")
    plan.add_argument(
        "--sweep-dt", action="store_true", help="also time the plan for Δt = 0.1 … 0.005 s (Fig. 9)"
    )
    plan.add_argument("--no-plots", action="store_true", help="write metrics and CSV only")
    sweep = sub.add_parser(
        "sweep", help="plan many random scenes of a family (pool or Ray): table, summary, plots"
    )
    add_sweep_arguments(sweep)
    demo = sub.add_parser("demo", help="fly a mission live: built-in SITL + service (make run)")
    demo.add_argument("mission", type=Path, help="mission document (JSON)")
    demo.add_argument("--speedup", type=float, default=1.0, help="SITL time factor")
    demo.add_argument("--port", type=int, default=8000, help="port of the service's API")
    demo.add_argument("--base-port", type=int, default=5760, help="TCP port of vehicle 0")
    demo.add_argument(
        "--workdir", type=Path, default=Path("out/demo"), help="logs, tlogs and database"
    )
    serve = sub.add_parser("serve", help="run the ground-station service (REST API, MAVLink)")
    serve.add_argument(
        "--link",
        action="append",
        metavar="URL",
        help="MAVLink connection, pymavlink syntax (tcp:127.0.0.1:5760); repeat",
    )
    serve.add_argument("--host", help="address to serve the API on (default 127.0.0.1)")
    serve.add_argument("--port", type=int, help="port of the API (default 8000)")
    serve.add_argument("--db", type=Path, help="SQLite file (default gcs_ppf.db)")
    serve.add_argument(
        "--signing-key-file",
        type=Path,
        metavar="PATH",
        help="MAVLink 2 signing key (64 hex digits or a passphrase) in a file; or set "
        "GCS_PPF_SIGNING_KEY (there is no option for the key itself: ps would show it)",
    )
    ap = sub.add_parser("arduplane-sitl", help="start real ArduPlane SITL, one per vehicle")
    ap.add_argument("mission", type=Path, help="mission document (JSON)")
    ap.add_argument("--binary", type=Path, required=True, help="build/sitl/bin/arduplane")
    ap.add_argument("--defaults", type=Path, help="parameter file (default: the tree's plane.parm)")
    ap.add_argument("--speedup", type=float, default=1.0, help="SITL time factor")
    ap.add_argument("--base-port", type=int, default=5760, help="serial0 TCP port of vehicle 0")
    ap.add_argument("--workdir", type=Path, help="instances' directories (default: a temp dir)")
    return parser


def serve_command(args: argparse.Namespace) -> int:
    import uvicorn
    from pydantic import ValidationError

    from api.app import create_app
    from gcs_ppf.service.settings import Settings

    given = {
        "links": args.link,
        "host": args.host,
        "port": args.port,
        "db": args.db,
        "signing_key_file": args.signing_key_file,
    }
    try:
        settings = Settings(**{k: v for k, v in given.items() if v is not None})
    except ValidationError as exc:
        first = exc.errors()[0]
        field = ".".join(str(p) for p in first["loc"])
        where = f"{field}: " if field else ""  # a check of several fields names them itself
        message = str(first["msg"]).removeprefix("Value error, ")
        print(f"gcs-ppf: error: settings: {where}{message}", file=sys.stderr)
        return EXIT_BAD_INPUT
    log.info("serving on http://%s:%d (docs at /docs)", settings.host, settings.port)
    uvicorn.run(create_app(settings), host=settings.host, port=settings.port, log_level="info")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    logging.basicConfig(
        level=logging.INFO,
        format="%(asctime)s %(name)s %(message)s"
        if argv is None and len(sys.argv) > 1 and sys.argv[1] == "serve"
        else "%(message)s",
    )
    args = build_parser().parse_args(argv)
    if args.command == "plan":
        return plan_command(args)
    if args.command == "sweep":
        return sweep_command(args)
    if args.command == "serve":
        return serve_command(args)
    if args.command == "arduplane-sitl":
        from gcs_ppf.tools.arduplane_sitl import arduplane_sitl_command

        return arduplane_sitl_command(
            args.mission,
            binary=args.binary,
            defaults=args.defaults,
            speedup=args.speedup,
            base_port=args.base_port,
            workdir=args.workdir,
        )
    if args.command == "demo":
        from gcs_ppf.tools.demo import run_demo

        try:
            mission = load_mission_file(args.mission)
        except MissionError as exc:
            print(f"gcs-ppf: error: invalid mission {args.mission}: {exc}", file=sys.stderr)
            return EXIT_BAD_INPUT
        return run_demo(
            args.mission,
            mission,
            speedup=args.speedup,
            port=args.port,
            base_port=args.base_port,
            workdir=args.workdir,
        )
    return EXIT_BAD_INPUT  # pragma: no cover - argparse rejects unknown commands


if __name__ == "__main__":
    sys.exit(main())

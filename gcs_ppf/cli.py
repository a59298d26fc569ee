"""The `gcs-ppf` command line: plan (``gcs_ppf.offline.command``), sweep
(``gcs_ppf.offline.sweep.command``), serve, token, zones import, demo, arduplane-sitl."""

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
from gcs_ppf.tokens import Scope

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
    serve.add_argument(
        "--forward",
        action="append",
        metavar="URL",
        help="relay every vehicle to another ground station and back, as mavlink-router "
        "does: udpout:127.0.0.1:14550 (QGroundControl), udpin:HOST:PORT, tcpin:HOST:PORT; "
        "repeat",
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
    serve.add_argument(
        "--token-file",
        type=Path,
        help="API tokens (`gcs-ppf token --file`); without any the API is open, on loopback only",
    )
    token = sub.add_parser(
        "token",
        help="make an API bearer token: prints it once; the service keeps only its hash",
    )
    token.add_argument("id", help="its name in the audit log (letters, digits, _ . -)")
    token.add_argument(
        "--scope",
        choices=["read", "command"],
        default="command",
        help="read: GETs and the live streams; command (default): those and every change",
    )
    token.add_argument(
        "--file",
        type=Path,
        help="add its entry to this token file (created, mode 0600) for --token-file; "
        "without it the entry is printed for GCS_PPF_TOKENS",
    )
    zones = sub.add_parser("zones", help="no-fly zones from operators' files")
    zones_sub = zones.add_subparsers(dest="zones_command", required=True)
    zimport = zones_sub.add_parser(
        "import",
        help="zones from GeoJSON or a QGroundControl .plan: printed as the mission's zones[], "
        "or added to --mission and written to --out",
    )
    zimport.add_argument("file", type=Path, help="GeoJSON (.geojson, .json) or .plan")
    zimport.add_argument("--mission", type=Path, help="a mission document to add them to")
    zimport.add_argument("--out", type=Path, help="where that mission goes (with --mission)")
    zimport.add_argument(
        "--route",
        action="store_true",
        help="a .plan's waypoints as the leader's route and target too (with --mission)",
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
    from api.auth import ExposureError
    from gcs_ppf.service.settings import Settings
    from gcs_ppf.tokens import TokenFileError

    given = {
        "links": args.link,
        "forward": args.forward,
        "host": args.host,
        "port": args.port,
        "db": args.db,
        "token_file": args.token_file,
        "signing_key_file": args.signing_key_file,
    }
    try:
        settings = Settings(**{k: v for k, v in given.items() if v is not None})
        app = create_app(settings)
    except ValidationError as exc:
        first = exc.errors()[0]
        field = ".".join(str(p) for p in first["loc"])
        where = f"{field}: " if field else ""  # a check of several fields names them itself
        message = str(first["msg"]).removeprefix("Value error, ")
        print(f"gcs-ppf: error: settings: {where}{message}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except (ExposureError, TokenFileError) as exc:
        print(f"gcs-ppf: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    tokens = len(app.state.keyring.by_hash)
    log.info(
        "serving on http://%s:%d (docs at /docs), %s",
        settings.host,
        settings.port,
        f"{tokens} API token(s)" if tokens else "no API token: open to loopback callers",
    )
    uvicorn.run(app, host=settings.host, port=settings.port, log_level="info")
    return 0


def token_command(args: argparse.Namespace) -> int:
    """``gcs-ppf token ID``: the token on stdout (nothing else there, for scripts), what to
    do with it on stderr."""
    from pydantic import ValidationError

    from gcs_ppf.tokens import TokenFileError, add_to_token_file, entries_json, new_token

    scopes: tuple[Scope, ...] = ("read", "command") if args.scope == "command" else ("read",)
    try:
        token, entry = new_token(args.id, scopes)
        if args.file is not None:
            add_to_token_file(args.file, entry)
    except ValidationError as exc:
        print(f"gcs-ppf: error: id {args.id!r}: {exc.errors()[0]['msg']}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except TokenFileError as exc:
        print(f"gcs-ppf: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    print(token)
    if args.file is not None:
        hint = f"added {entry.id!r} to {args.file}: gcs-ppf serve --token-file {args.file}"
    else:
        hint = f"GCS_PPF_TOKENS='{entries_json([entry])}' gcs-ppf serve"
    print(f"{hint}\nclients send: Authorization: Bearer <the token above>", file=sys.stderr)
    return 0


def zones_import_command(
    file: Path, mission_file: Path | None, out: Path | None, route: bool = False
) -> int:
    """``gcs-ppf zones import``: the file's zones as JSON on stdout, or added to a mission
    document written to ``out`` (validated whole: its zones must fit its scene); with
    ``route``, a ``.plan``'s waypoints become its route and target as well."""
    import json

    from gcs_ppf.mission import Mission
    from gcs_ppf.plan_route import RouteImportError, route_from_plan
    from gcs_ppf.zone_import import ZoneImportError, import_zones

    def refuse(message: str) -> int:
        print(f"gcs-ppf: error: {message}", file=sys.stderr)
        return EXIT_BAD_INPUT

    if (mission_file is None) != (out is None) or (route and mission_file is None):
        return refuse("--mission and --out go together (and --route needs them)")
    try:
        text = file.read_text()
        zones = import_zones(text, str(file), required=not route)
    except (OSError, UnicodeDecodeError) as exc:
        return refuse(f"cannot read {file}: {exc}")
    except ZoneImportError as exc:
        return refuse(f"{exc}; nothing imported")
    found = [z.model_dump(exclude_none=True) for z in zones]
    if mission_file is None or out is None:
        print(json.dumps(found, indent=2))
        return 0
    try:
        doc = json.loads(mission_file.read_text())
        doc["zones"] = [*doc.get("zones", []), *found]
        said = f"{len(found)} zones"
        if route:
            flown = route_from_plan(json.loads(text), Mission.model_validate(doc).origin)
            doc["route"] = [w.model_dump() for w in flown.route]
            doc["target"] = list(flown.target)
            left = ", ".join(f"items[{k}] (MAV_CMD {c})" for k, c in flown.left_out)
            said += f" and a route of {len(flown.route) + 1} waypoints"
            said += f" (left out: {left})" if left else ""
        mission = Mission.model_validate(doc)
    except RouteImportError as exc:
        return refuse(f"{file}: {exc}; nothing imported")
    except (OSError, ValueError, TypeError, AttributeError) as exc:
        return refuse(f"{mission_file} with what {file} holds: {exc}")
    out.write_text(mission.model_dump_json(indent=2, exclude_none=True) + "\n")
    print(f"{said} of {file} added to {mission_file}: {out}", file=sys.stderr)
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
    if args.command == "token":
        return token_command(args)
    if args.command == "zones":
        return zones_import_command(args.file, args.mission, args.out, args.route)
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

"""``python -m sitl MISSION.json``: fly a mission's vehicles as simulated ArduPlanes.

See sitl/README.md for connection strings, options and the deviations from ArduPlane.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import sys
import time
from pathlib import Path

from gcs_ppf.mission import MissionError, load_mission_file
from sitl.airframe import AIRFRAMES
from sitl.engine import Simulation, parse_param_override
from sitl.faults import parse_fault
from sitl.server import ServerConfig, check_speedup, parse_serial, serve, signing_key


def parse_udp(text: str) -> tuple[str, int]:
    """``udp:HOST:PORT`` (or ``HOST:PORT``) → (host, port)."""
    body = text.removeprefix("udp:")
    host, sep, port = body.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise argparse.ArgumentTypeError(f"--out: expected udp:HOST:PORT, got {text!r}")
    return host, int(port)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m sitl", description=__doc__)
    p.add_argument("mission", type=Path, help="mission document (JSON, CONVENTIONS §3)")
    p.add_argument("--speedup", type=float, default=1.0, help="simulated seconds per wall second")
    p.add_argument("--base-port", type=int, default=5760, help="TCP port of vehicle 0 (+10 each)")
    p.add_argument(
        "--host",
        default="127.0.0.1",
        help="address the vehicles' TCP servers listen on (0.0.0.0 in containers)",
    )
    p.add_argument("--out", type=parse_udp, default=None, help="also stream to udp:HOST:PORT")
    p.add_argument("--seed", type=int, default=0, help="seed of noise and packet loss")
    p.add_argument("--tlog", type=Path, default=None, help="write DIR/vehicle<ID>.tlog")
    p.add_argument(
        "--signing-key",
        default=None,
        help="MAVLink 2 signing key (64 hex) or passphrase; ps shows it: prefer "
        "--signing-key-file or the SITL_SIGNING_KEY environment variable",
    )
    p.add_argument(
        "--signing-key-file",
        type=Path,
        default=None,
        metavar="PATH",
        help="a file holding the signing key (64 hex or a passphrase)",
    )
    p.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="[ID:]NAME=VALUE",
        help="set a parameter at start, for vehicle ID or all (repeatable)",
    )
    p.add_argument(
        "--fault",
        action="append",
        default=[],
        metavar="[ID:]KEY=VAL,...",
        help="loss=%%, latency=ms, noise=m, cut=START+DUR, die=T, ignore=T (sim s; repeatable)",
    )
    p.add_argument(
        "--airframe",
        choices=AIRFRAMES,
        default="auto",
        help="parameter defaults: ArduPlane's plane.parm (arduplane), scaled to the mission's "
        "limits (mission), or arduplane when the mission's v_max is within it (auto)",
    )
    start = p.add_mutually_exclusive_group()
    start.add_argument(
        "--ground-start",
        dest="ground_start",
        action="store_const",
        const=True,
        help="every vehicle starts on the ground at its start position, disarmed (takes off "
        "in TAKEOFF mode); by default only the ArduPlane airframe's vehicles whose start is "
        "on the ground (z <= 0) do, as ArduPlane does, the others in the air",
    )
    start.add_argument(
        "--air-start",
        dest="ground_start",
        action="store_const",
        const=False,
        help="every vehicle starts in the air at its start state (position, attitude, "
        "v_init), armed, as in the paper",
    )
    p.add_argument(
        "--serial",
        action="append",
        default=[],
        metavar="DEVICE[:BAUD]",
        help="also serve on a serial device (57600 baud unless given): once per vehicle, in "
        "order, or once for every vehicle on one line (repeatable)",
    )
    p.add_argument(
        "--radio",
        action="store_true",
        help="each --serial line carries only what a telemetry radio at its baud rate does "
        "(BAUD/10 bytes a second each way, 8N1; the rest dropped), in simulated time",
    )
    p.add_argument("--duration", type=float, default=None, help="stop after this many sim seconds")
    return p


SIGNING_KEY_ENV = "SITL_SIGNING_KEY"


def _signing_key(args: argparse.Namespace) -> bytes | None:
    """The key of ``--signing-key``, ``--signing-key-file`` or ``SITL_SIGNING_KEY`` (one of
    them at most), or None.  Raises ValueError naming the source, never quoting the key."""
    given = [
        name
        for name, value in (
            ("--signing-key", args.signing_key),
            ("--signing-key-file", args.signing_key_file),
            (SIGNING_KEY_ENV, os.environ.get(SIGNING_KEY_ENV)),
        )
        if value
    ]
    if len(given) > 1:
        raise ValueError(f"signing key given twice ({' and '.join(given)}): give one")
    if not given:
        return None
    if args.signing_key_file:
        try:
            text = Path(args.signing_key_file).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            reason = getattr(exc, "strerror", None) or type(exc).__name__
            raise ValueError(
                f"--signing-key-file: cannot read {args.signing_key_file}: {reason}"
            ) from None
    else:
        text = args.signing_key or os.environ[SIGNING_KEY_ENV]
    try:
        return signing_key(text)
    except ValueError as exc:
        raise ValueError(f"{given[0]}: {exc}") from None


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        mission = load_mission_file(args.mission)
        speedup = check_speedup(args.speedup)
        params = [parse_param_override(t) for t in args.param]
        faults = [parse_fault(t) for t in args.fault]
        key = _signing_key(args)
        serial = tuple(parse_serial(t) for t in args.serial)
        if len(serial) > 1 and len(serial) != len(mission.vehicles):
            raise ValueError(
                f"--serial: {len(serial)} devices for {len(mission.vehicles)} vehicles; give "
                "one per vehicle, or one for all"
            )
        if not 1 <= args.base_port <= 65535 - 10 * (len(mission.vehicles) - 1):
            raise ValueError("--base-port: ports out of range for this many vehicles")
        sim = Simulation(
            mission,
            seed=args.seed,
            params=params,
            faults=faults,
            boot_unix_us=int(time.time() * 1e6),
            airframe=args.airframe,
            ground_start=args.ground_start,
        )
    except (MissionError, ValueError) as exc:
        print(f"sitl: {exc}", file=sys.stderr)
        return 2
    cfg = ServerConfig(
        base_port=args.base_port,
        host=args.host,
        speedup=speedup,
        out=args.out,
        seed=args.seed,
        signing_key=key,
        tlog_dir=args.tlog,
        duration_s=args.duration,
        serial=serial,
        radio=args.radio,
    )

    def ready(line: str) -> None:
        print(line, flush=True)

    try:
        asyncio.run(serve(sim, cfg, ready=ready))
    except OSError as exc:
        print(f"sitl: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

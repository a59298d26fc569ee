"""Launch one real ArduPlane SITL process per mission vehicle (``gcs-ppf arduplane-sitl``)."""

from __future__ import annotations

import math
import re
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO

from gcs_ppf.geodesy import enu_to_geodetic, yaw_to_heading_ned
from gcs_ppf.mission import Mission, MissionError, Origin, Vehicle, load_mission_file

DEFAULT_BASE_PORT = 5760  # ArduPilot SITL's own serial0 port of instance 0
PORT_STRIDE = 10  # ArduPilot SITL adds 10 per instance (-I) to its ports
SERVICE_OFFSET, OBSERVER_OFFSET, OBSERVER2_OFFSET = 0, 2, 3  # serial0, serial1, serial2
PLANE_PARM = Path("Tools/autotest/models/plane.parm")  # in an ArduPilot source tree
SYSID_PARM = "sysid.parm"
LOG_NAME = "sitl.log"
EXIT_BAD_INPUT = 2


# ---------------------------------------------------------------------------- pure helpers


@dataclass(frozen=True)
class Ports:
    """TCP ports of one instance: the service's link (serial0) and two observers' links."""

    service: int
    observer: int
    observer2: int

    def all(self) -> tuple[int, int, int]:
        return self.service, self.observer, self.observer2


def instance_ports(base_port: int, index: int) -> Ports:
    """Ports of instance ``index`` (0-based, document order) for a fleet based at ``base_port``."""
    first = base_port + PORT_STRIDE * index
    return Ports(first + SERVICE_OFFSET, first + OBSERVER_OFFSET, first + OBSERVER2_OFFSET)


def check_base_port(base_port: int, count: int) -> None:
    """Raise ValueError unless ``count`` instances based at ``base_port`` fit in 1001…65535
    (ArduPilot SITL reads a TCP port ≤ 1000 as an offset from its own base port)."""
    last = instance_ports(base_port, count - 1).observer2
    if base_port <= 1000 or last > 65535:
        raise ValueError(
            f"--base-port {base_port}: the ports of {count} instances must lie in 1001…65535 "
            f"(they would span {base_port}…{last})"
        )


@dataclass(frozen=True)
class Home:
    """ArduPilot SITL's start location: WGS-84 degrees, metres AMSL, compass degrees."""

    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    heading_deg: float

    def arg(self) -> str:
        """The ``--home LAT,LON,ALT,HDG`` value."""
        return f"{self.lat_deg:.8f},{self.lon_deg:.8f},{self.alt_amsl_m:.2f},{self.heading_deg:.2f}"


def vehicle_home(vehicle: Vehicle, origin: Origin) -> Home:
    """A vehicle's start position (ICS, ENU metres about ``origin``) as a home on the ground:
    the ground is at the start's altitude; the heading is the compass heading of its yaw."""
    x, y, z = vehicle.position
    lat, lon, alt = enu_to_geodetic(x, y, z, origin)
    heading = round(math.degrees(yaw_to_heading_ned(vehicle.yaw)), 6) % 360.0  # 359.9999… → 0
    return Home(lat, lon, alt, heading)


def sysid_parameter(firmware: bytes) -> str:
    """The name of the system-id parameter in this firmware image: ``MAV_SYSID`` since
    ArduPilot 4.7, ``SYSID_THISMAV`` before."""
    return "MAV_SYSID" if b"MAV_SYSID" in firmware else "SYSID_THISMAV"


def serial_options(firmware: bytes) -> tuple[str, str, str]:
    """Command-line options that set SERIAL0…2: ``--serialN`` where the binary knows them,
    the older ``--uartA`` (SERIAL0), ``--uartC`` (SERIAL1), ``--uartD`` (SERIAL2) otherwise."""
    if b"--serial0" in firmware:
        return "--serial0", "--serial1", "--serial2"
    return "--uartA", "--uartC", "--uartD"


def sysid_parm_text(parameter: str, sysid: int) -> str:
    """A defaults file (``NAME VALUE`` lines) that gives an instance its system id."""
    return f"{parameter} {sysid}\n"


def find_plane_parm(binary: Path) -> Path | None:
    """``Tools/autotest/models/plane.parm`` of the ArduPilot tree the binary was built in
    (``<tree>/build/sitl/bin/arduplane``), or None."""
    for parent in binary.resolve().parents:
        candidate = parent / PLANE_PARM
        if candidate.is_file():
            return candidate
    return None


@dataclass(frozen=True)
class Instance:
    """One SITL process of the fleet: vehicle ``sysid`` as ArduPilot instance ``index``."""

    index: int
    sysid: int
    role: str
    ports: Ports
    home: Home
    workdir: Path


def plan_fleet(mission: Mission, base_port: int, workdir: Path) -> list[Instance]:
    """One instance per mission vehicle, in document order, each in its own directory."""
    check_base_port(base_port, len(mission.vehicles))
    return [
        Instance(
            index=i,
            sysid=v.id,
            role=v.role,
            ports=instance_ports(base_port, i),
            home=vehicle_home(v, mission.origin),
            workdir=workdir / f"vehicle-{v.id}",
        )
        for i, v in enumerate(mission.vehicles)
    ]


def instance_command(
    binary: Path,
    instance: Instance,
    *,
    speedup: float,
    defaults: Sequence[Path],
    serial: tuple[str, str, str] = ("--serial0", "--serial1", "--serial2"),
) -> list[str]:
    """The command line of one instance.  ``defaults`` are the airframe's parameter files;
    the instance's own ``sysid.parm`` (in its directory) is appended.  Serial ports listen
    on fixed TCP ports without waiting for a connection, so the instance boots on its own."""
    files = [*defaults, instance.workdir / SYSID_PARM]
    if any("," in str(f) for f in files):
        raise ValueError(f"ArduPilot splits --defaults at commas: {files}")
    ports = instance.ports.all()
    return [
        str(binary),
        "--model",
        "plane",
        "--speedup",
        f"{speedup:g}",
        "-I",
        str(instance.index),
        "--home",
        instance.home.arg(),
        "--defaults",
        ",".join(str(f) for f in files),
        "-w",
        *(
            arg
            for option, port in zip(serial, ports, strict=True)
            for arg in (option, f"tcp:{port}")
        ),
    ]


def listening(log_text: str, ports: Ports) -> bool:
    """Whether an instance's output says all three of its TCP ports are listening
    ("SERIAL1 on TCP port 5762", older firmware "Serial port 1 on TCP port 5762")."""
    return all(re.search(rf"on TCP port {p}\b", log_text) for p in ports.all())


def describe(instance: Instance) -> str:
    """The line printed for one instance."""
    p, h = instance.ports, instance.home
    return (
        f"vehicle {instance.sysid} ({instance.role}): sysid {instance.sysid}, instance "
        f"{instance.index}, service tcp:127.0.0.1:{p.service}, observers "
        f"tcp:127.0.0.1:{p.observer} tcp:127.0.0.1:{p.observer2}, home {h.arg()}, "
        f"log {instance.workdir / LOG_NAME}"
    )


# ---------------------------------------------------------------------------- the shell


def _stop(procs: Sequence[subprocess.Popen[bytes]], timeout_s: float = 5.0) -> None:
    """Terminate every process, wait for them (shared deadline), kill what is left."""
    for p in procs:
        if p.poll() is None:
            p.terminate()
    deadline = time.monotonic() + timeout_s
    for p in procs:
        try:
            p.wait(timeout=max(deadline - time.monotonic(), 0.1))
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def _tail(path: Path, lines: int = 5) -> str:
    try:
        return "\n".join(path.read_text(errors="replace").splitlines()[-lines:])
    except OSError:
        return ""


def run_fleet(
    mission: Mission,
    *,
    binary: Path,
    defaults: Sequence[Path],
    speedup: float,
    base_port: int,
    workdir: Path,
    ready_timeout_s: float = 60.0,
) -> int:
    """Start the fleet, print its ports and a ready line, and run until Ctrl-C or SIGTERM
    (exit 0) or until an instance dies (exit 1); every instance is stopped on the way out."""
    firmware = binary.read_bytes()
    parameter = sysid_parameter(firmware)
    serial = serial_options(firmware)
    instances = plan_fleet(mission, base_port, workdir)

    def stop_signal(_signum: int, _frame: object) -> None:
        raise KeyboardInterrupt  # SIGTERM stops the fleet like Ctrl-C

    previous = signal.signal(signal.SIGTERM, stop_signal)
    procs: list[subprocess.Popen[bytes]] = []
    logs: list[IO[bytes]] = []
    try:
        for inst in instances:
            inst.workdir.mkdir(parents=True, exist_ok=True)
            (inst.workdir / SYSID_PARM).write_text(sysid_parm_text(parameter, inst.sysid))
            cmd = instance_command(binary, inst, speedup=speedup, defaults=defaults, serial=serial)
            logs.append((inst.workdir / LOG_NAME).open("wb"))
            procs.append(
                subprocess.Popen(
                    cmd,
                    cwd=inst.workdir,
                    stdin=subprocess.DEVNULL,
                    stdout=logs[-1],
                    stderr=subprocess.STDOUT,
                )
            )
            print(describe(inst), flush=True)
        deadline = time.monotonic() + ready_timeout_s
        waiting = list(zip(instances, procs, strict=True))
        while waiting:
            for inst, p in waiting:
                if p.poll() is not None:
                    log = inst.workdir / LOG_NAME
                    print(
                        f"vehicle {inst.sysid}: ArduPlane SITL exited ({p.returncode}) before "
                        f"its ports were up; {log}:\n{_tail(log)}",
                        file=sys.stderr,
                    )
                    return 1
            waiting = [
                (inst, p)
                for inst, p in waiting
                if not listening((inst.workdir / LOG_NAME).read_text(errors="replace"), inst.ports)
            ]
            if waiting and time.monotonic() > deadline:
                print(
                    f"gcs-ppf: error: ArduPlane SITL ports not up after {ready_timeout_s:g} s:"
                    f" vehicles {[i.sysid for i, _ in waiting]}",
                    file=sys.stderr,
                )
                return 1
            time.sleep(0.1)
        links = " ".join(f"--link tcp:127.0.0.1:{i.ports.service}" for i in instances)
        print(
            f"ready: {len(instances)} ArduPlane SITL instances ({parameter}, speedup "
            f"{speedup:g}) in {workdir}; serve them with: gcs-ppf serve {links}; "
            "Ctrl-C stops them",
            flush=True,
        )
        while True:
            for inst, p in zip(instances, procs, strict=True):
                if p.poll() is not None:
                    print(
                        f"vehicle {inst.sysid}: ArduPlane SITL exited ({p.returncode}); "
                        f"stopping the fleet",
                        file=sys.stderr,
                    )
                    return 1
            time.sleep(0.5)
    except KeyboardInterrupt:
        print("stopping the ArduPlane SITL instances", flush=True)
        return 0
    finally:
        _stop(procs)
        for f in logs:
            f.close()
        signal.signal(signal.SIGTERM, previous)


def arduplane_sitl_command(
    mission_path: Path,
    *,
    binary: Path,
    defaults: Path | None,
    speedup: float,
    base_port: int,
    workdir: Path | None,
) -> int:
    """``gcs-ppf arduplane-sitl``: check the inputs (exit 2 with one line if bad), then run."""

    def bad(message: str) -> int:
        print(f"gcs-ppf: error: {message}", file=sys.stderr)
        return EXIT_BAD_INPUT

    try:
        mission = load_mission_file(mission_path)
    except MissionError as exc:
        return bad(f"invalid mission {mission_path}: {exc}")
    if not binary.is_file():
        return bad(f"--binary {binary}: no such file (build/sitl/bin/arduplane)")
    if not speedup > 0.0:
        return bad(f"--speedup {speedup:g}: must be positive")
    parm = defaults or find_plane_parm(binary)
    if parm is None:
        return bad(f"--defaults: no {PLANE_PARM} found above {binary}; name a defaults file")
    if not parm.is_file():
        return bad(f"--defaults {parm}: no such file")
    try:
        check_base_port(base_port, len(mission.vehicles))
    except ValueError as exc:
        return bad(str(exc))
    root = workdir or Path(tempfile.mkdtemp(prefix="arduplane-sitl-"))
    return run_fleet(
        mission,
        binary=binary.resolve(),
        defaults=[parm.resolve()],
        speedup=speedup,
        base_port=base_port,
        workdir=root.resolve(),
    )

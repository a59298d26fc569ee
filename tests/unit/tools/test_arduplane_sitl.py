"""``gcs-ppf arduplane-sitl``: ports, homes, command lines and the launcher shell, without
ArduPilot (a stand-in script plays the binary)."""

from __future__ import annotations

import itertools
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gcs_ppf.cli import build_parser
from gcs_ppf.geodesy import geodetic_to_enu
from gcs_ppf.mission import Origin, Vehicle, load_mission_file
from gcs_ppf.tools.arduplane_sitl import (
    EXIT_BAD_INPUT,
    Home,
    Ports,
    arduplane_sitl_command,
    check_base_port,
    find_plane_parm,
    instance_command,
    instance_ports,
    listening,
    plan_fleet,
    serial_options,
    sysid_parameter,
    sysid_parm_text,
    vehicle_home,
)
from tests.conftest import EXAMPLES, ROOT

ORIGIN = Origin(lat=-35.363261, lon=149.16523, alt=584.0)


def _vehicle(position: tuple[float, float, float], yaw: float) -> Vehicle:
    return Vehicle(id=1, role="leader", position=position, yaw=yaw)


def test_ports_follow_ardupilot_layout_from_the_base_port() -> None:
    assert instance_ports(5760, 0) == Ports(5760, 5762, 5763)  # ArduPilot's own defaults
    assert instance_ports(5760, 2) == Ports(5780, 5782, 5783)  # as -I 2 would give
    assert instance_ports(7000, 4) == Ports(7040, 7042, 7043)


@pytest.mark.parametrize(("base", "count"), [(1000, 1), (65500, 5), (65533, 1)])
def test_a_base_port_whose_block_does_not_fit_is_refused(base: int, count: int) -> None:
    with pytest.raises(ValueError, match="--base-port"):
        check_base_port(base, count)
    check_base_port(5760, 5)


@pytest.mark.parametrize(
    ("yaw", "heading"),
    [(math.pi / 2, 0.0), (1.5707963268, 0.0), (0.0, 90.0), (math.pi, 270.0),
     (-math.pi / 2, 180.0), (math.pi / 4, 45.0)],
)  # fmt: skip
def test_home_heading_is_the_compass_heading_of_the_yaw(yaw: float, heading: float) -> None:
    home = vehicle_home(_vehicle((0.0, 0.0, 0.0), yaw), ORIGIN)
    assert home.heading_deg == pytest.approx(heading, abs=1e-6)
    assert 0.0 <= home.heading_deg < 360.0


def test_home_is_the_start_position_on_the_ground() -> None:
    home = vehicle_home(_vehicle((272.0, -150.0, 30.0), math.pi / 2), ORIGIN)
    e, n, u = geodetic_to_enu(home.lat_deg, home.lon_deg, home.alt_amsl_m, ORIGIN)
    assert (e, n, u) == pytest.approx((272.0, -150.0, 30.0), abs=1e-3)
    assert home.alt_amsl_m == pytest.approx(ORIGIN.alt + 30.0, abs=0.1)
    at_origin = vehicle_home(_vehicle((0.0, 0.0, 0.0), 0.0), ORIGIN)
    assert (at_origin.lat_deg, at_origin.lon_deg) == pytest.approx((ORIGIN.lat, ORIGIN.lon))


def test_home_argument_is_lat_lon_alt_heading() -> None:
    fields = Home(-35.36326101, 149.165230004, 584.0, 0.0).arg().split(",")
    assert len(fields) == 4
    assert [float(f) for f in fields] == pytest.approx([-35.36326101, 149.16523, 584.0, 0.0])


def test_sysid_parameter_name_follows_the_firmware() -> None:
    assert sysid_parameter(b"\0SYSID_THISMAV\0MAV_SYSID\0Setting MAV_SYSID=%d") == "MAV_SYSID"
    assert sysid_parameter(b"\0SYSID_THISMAV\0SYSID_MYGCS\0") == "SYSID_THISMAV"
    assert sysid_parm_text("MAV_SYSID", 3) == "MAV_SYSID 3\n"


def test_serial_options_follow_the_firmware() -> None:
    assert serial_options(b"\t--serial0 device   set device") == (
        "--serial0",
        "--serial1",
        "--serial2",
    )
    assert serial_options(b"\t--uartA device   set device") == ("--uartA", "--uartC", "--uartD")


def test_plane_parm_is_found_in_the_binary_source_tree(tmp_path: Path) -> None:
    binary = tmp_path / "ardupilot/build/sitl/bin/arduplane"
    binary.parent.mkdir(parents=True)
    binary.write_bytes(b"")
    assert find_plane_parm(binary) is None
    parm = tmp_path / "ardupilot/Tools/autotest/models/plane.parm"
    parm.parent.mkdir(parents=True)
    parm.write_text("AIRSPEED_CRUISE 22\n")
    assert find_plane_parm(binary) == parm.resolve()


@pytest.mark.parametrize("n", [3, 5])
def test_fleet_of_the_example_missions(n: int, tmp_path: Path) -> None:
    mission = load_mission_file(EXAMPLES / f"arduplane_{n}.json")
    fleet = plan_fleet(mission, 7000, tmp_path)
    assert [i.sysid for i in fleet] == [v.id for v in mission.vehicles] == list(range(1, n + 1))
    assert [i.index for i in fleet] == list(range(n))
    assert [i.ports for i in fleet] == [instance_ports(7000, k) for k in range(n)]
    assert len({i.workdir for i in fleet}) == n
    assert all(i.workdir.parent == tmp_path for i in fleet)
    east = sorted(geodetic_to_enu(i.home.lat_deg, i.home.lon_deg, i.home.alt_amsl_m,
                                  mission.origin)[0] for i in fleet)  # fmt: skip
    assert _gaps(east) == pytest.approx([272.0] * (n - 1), abs=0.01)
    assert all(i.home.heading_deg == pytest.approx(0.0, abs=1e-6) for i in fleet)
    assert all(i.home.alt_amsl_m == pytest.approx(mission.origin.alt, abs=0.1) for i in fleet)
    assert fleet[0].role == "leader"


def _gaps(values: list[float]) -> list[float]:
    """Differences of consecutive values."""
    return [b - a for a, b in itertools.pairwise(values)]


def test_instance_command_line(tmp_path: Path) -> None:
    mission = load_mission_file(EXAMPLES / "arduplane_3.json")
    inst = plan_fleet(mission, 7000, tmp_path)[1]
    cmd = instance_command(Path("/ap/arduplane"), inst, speedup=5.0,
                           defaults=[Path("/ap/plane.parm")])  # fmt: skip
    assert cmd[0] == "/ap/arduplane"

    def value(option: str) -> str:
        return cmd[cmd.index(option) + 1]

    assert value("--model") == "plane"
    assert value("--speedup") == "5"
    assert value("-I") == "1"
    assert value("--home") == inst.home.arg()
    assert value("--defaults") == f"/ap/plane.parm,{inst.workdir / 'sysid.parm'}"
    assert "-w" in cmd
    assert (value("--serial0"), value("--serial1"), value("--serial2")) == (
        "tcp:7010", "tcp:7012", "tcp:7013")  # fmt: skip
    old = instance_command(Path("/ap/arduplane"), inst, speedup=0.5, defaults=[],
                           serial=("--uartA", "--uartC", "--uartD"))  # fmt: skip
    assert old[old.index("--uartC") + 1] == "tcp:7012"
    assert old[old.index("--speedup") + 1] == "0.5"
    with pytest.raises(ValueError, match="commas"):
        instance_command(Path("/ap/arduplane"), inst, speedup=1.0, defaults=[Path("/a,b")])


def test_ports_up_is_read_from_the_instance_output() -> None:
    ports = Ports(7010, 7012, 7013)
    new = "bind port 7010 for SERIAL0\nSERIAL0 on TCP port 7010\nSERIAL1 on TCP port 7012\n"
    assert not listening(new, ports)
    assert listening(new + "SERIAL2 on TCP port 7013\n", ports)
    old = "".join(f"Serial port {k} on TCP port {p}\n" for k, p in enumerate(ports.all()))
    assert listening(old, ports)
    assert not listening("SERIAL0 on TCP port 70100\n", Ports(7010, 7010, 7010))


def test_cli_registers_the_sub_command() -> None:
    args = build_parser().parse_args(["arduplane-sitl", "m.json", "--binary", "ap"])
    assert (args.command, args.mission, args.binary) == (
        "arduplane-sitl",
        Path("m.json"),
        Path("ap"),
    )
    assert (args.speedup, args.base_port, args.defaults, args.workdir) == (1.0, 5760, None, None)


def test_bad_inputs_exit_2_before_anything_starts(tmp_path: Path) -> None:
    mission = EXAMPLES / "arduplane_3.json"
    binary = tmp_path / "arduplane"
    binary.write_bytes(b"")
    kw: dict[str, object] = {"defaults": None, "speedup": 1.0, "base_port": 7000,
                             "workdir": tmp_path / "w"}  # fmt: skip

    def run(path: Path = mission, **over: object) -> int:
        a = {"binary": binary, **kw, **over}
        return arduplane_sitl_command(path, **a)  # type: ignore[arg-type]

    assert run(binary=tmp_path / "missing") == EXIT_BAD_INPUT
    assert run() == EXIT_BAD_INPUT  # no plane.parm above the binary, no --defaults
    parm = tmp_path / "plane.parm"
    parm.write_text("")
    assert run(defaults=tmp_path / "nope.parm") == EXIT_BAD_INPUT
    assert run(defaults=parm, base_port=80) == EXIT_BAD_INPUT
    assert run(defaults=parm, speedup=0.0) == EXIT_BAD_INPUT
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    assert run(bad, defaults=parm) == EXIT_BAD_INPUT
    assert not (tmp_path / "w").exists()


FAKE_SITL = """\
import json, os, sys, time
args = sys.argv[1:]
with open("argv.json", "w") as f:
    json.dump({"argv": args, "pid": os.getpid()}, f)
for k, opt in enumerate(("--serial0", "--serial1", "--serial2")):
    port = args[args.index(opt) + 1].split(":")[1]
    print(f"SERIAL{k} on TCP port {port}", file=sys.stderr, flush=True)
while True:
    time.sleep(0.1)
"""


@pytest.mark.realtime  # its processes, ready within 30 s of wall time
def test_the_launcher_starts_one_process_per_vehicle_and_stops_them_all(tmp_path: Path) -> None:
    """A stand-in binary (it writes its argv and pid, prints the port lines, sleeps): the
    launcher prints a line per vehicle and a ready line; SIGTERM stops every instance."""
    tree = tmp_path / "ardupilot"
    binary = tree / "build/sitl/bin/arduplane"
    binary.parent.mkdir(parents=True)
    binary.write_text(f"#!{sys.executable}\n# MAV_SYSID --serial0\n{FAKE_SITL}")
    binary.chmod(0o755)
    parm = tree / "Tools/autotest/models/plane.parm"
    parm.parent.mkdir(parents=True)
    parm.write_text("AIRSPEED_CRUISE 22\n")
    work = tmp_path / "fleet"
    mission = str(EXAMPLES / "arduplane_3.json")
    cmd = [sys.executable, "-m", "gcs_ppf.cli", "arduplane-sitl", mission, "--binary", str(binary),
           "--speedup", "5", "--base-port", "7100", "--workdir", str(work)]  # fmt: skip
    out = tmp_path / "launcher.log"
    with out.open("w") as log:
        p = subprocess.Popen(cmd, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 30
        while "ready" not in out.read_text() and time.monotonic() < deadline:
            assert p.poll() is None, out.read_text()
            time.sleep(0.1)
        text = out.read_text()
        assert "ready: 3 ArduPlane SITL instances (MAV_SYSID" in text, text
        runs = {
            vid: json.loads((work / f"vehicle-{vid}/argv.json").read_text()) for vid in (1, 2, 3)
        }
        for k, vid in enumerate((1, 2, 3)):
            assert f"vehicle {vid} (" in text
            assert f"service tcp:127.0.0.1:{7100 + 10 * k}" in text
            argv = runs[vid]["argv"]
            assert argv[argv.index("-I") + 1] == str(k)
            assert argv[argv.index("--defaults") + 1].startswith(str(parm.resolve()) + ",")
            assert (work / f"vehicle-{vid}/sysid.parm").read_text() == f"MAV_SYSID {vid}\n"
        p.send_signal(signal.SIGTERM)
        assert p.wait(timeout=20) == 0
    finally:
        if p.poll() is None:
            p.kill()
    for run in runs.values():
        with pytest.raises(ProcessLookupError):
            os.kill(run["pid"], 0)
    assert "stopping" in out.read_text()

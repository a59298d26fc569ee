"""Record a flown run's ticks (``tests.ticks``) for the equivalence test of the tick's pure parts.

``python -m tests.record_ticks MISSION.json OUT.json.gz [--ticks 12] [--every 5] [--skip 10]
[--speedup 1]`` flies the mission on the built-in SITL with the service in this process's
child (``serve`` below, the service's own ``gcs-ppf serve`` with two functions wrapped), and
writes, of every ``--every``-th tick after the first ``--skip``, what the tick handed
``tick_plan.plan`` and ``commanding.command_fleet`` and what they gave back: the plan, the
verdicts, every message sent, every event, and the dictionaries the commanding updates as
they were after it.  The service flies exactly as it does unwrapped (only slower by the
recording).  Recorded once with the code of the time, kept under ``tests/data/ticks``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from gcs_ppf.mission import Mission
from tests import ticks


def serve(out: Path, count: int, every: int, skip: int, argv: list[str]) -> int:
    """``gcs-ppf serve argv`` with the tick's plan and commanding recorded into ``out``."""
    from gcs_ppf import cli
    from gcs_ppf.guidance import tick_plan
    from gcs_ppf.service import commanding

    recorded: list[dict[str, Any]] = []
    seen = {"plans": 0, "judged": 0}
    pending: dict[str, Any] = {}
    plan, command_fleet = tick_plan.plan, commanding.command_fleet

    def scheduled() -> bool:
        k = seen["plans"] - 1
        return k >= skip and (k - skip) % every == 0

    def recorded_plan(*args: Any) -> Any:
        seen["plans"] += 1
        pending.clear()
        inputs = ticks.encode(list(args), args[0])
        result = plan(*args)
        pending["plan"] = {"args": inputs, "result": ticks.encode(result, args[0])}
        return result

    async def recorded_command_fleet(fleet: Any, *args: Any, **kwargs: Any) -> Any:
        if "plan" not in pending or len(recorded) >= count:
            return await command_fleet(fleet, *args, **kwargs)
        m = args[4].mission  # orders
        sender = _Recording(fleet, m)
        given = list(args)
        given[8] = None  # the event sink: its calls are recorded instead
        inputs = ticks.encode(given, m)
        event_calls: list[Any] = []

        def event(*a: Any, **kw: Any) -> None:
            event_calls.append(ticks.encode([list(a), kw], m))
            args[8](*a, **kw)

        call = list(args)
        call[8] = event
        result = await command_fleet(sender, *call, **kwargs)  # ``phases``: not recorded
        after = ticks.encode({"commanded_speed": args[7], "escaping": args[9],
                              "trims": args[11]}, m)  # fmt: skip
        judged = any(v.reason is not None for v in result.values())
        if not (scheduled() or (judged and seen["judged"] < count // 2)):
            return result
        seen["judged"] += judged
        recorded.append({
            "plan": pending.pop("plan"),
            "command_fleet": {"args": inputs, "telemetry": sender.telemetry_calls,
                              "sent": sender.sent, "events": event_calls,
                              "result": ticks.encode(result, m), "after": after},
        })  # fmt: skip
        ticks.write(out, m, recorded)  # each time: a run may end before ``count``
        return result

    tick_plan.plan = recorded_plan  # type: ignore[assignment]
    commanding.command_fleet = recorded_command_fleet
    return cli.main(["serve", *argv])


class _Recording:
    """The fleet as ``command_fleet`` uses it, every call recorded."""

    def __init__(self, fleet: Any, mission: Mission) -> None:
        self._fleet, self._mission = fleet, mission
        self.telemetry_calls: list[Any] = []
        self.sent: list[Any] = []

    def telemetry(self, system_id: int) -> Any:
        t = self._fleet.telemetry(system_id)
        self.telemetry_calls.append([system_id, ticks.encode(t, self._mission)])
        return t

    async def send(self, system_id: int, msg: Any) -> None:
        self.sent.append(ticks.encode([system_id, message(msg)]))
        await self._fleet.send(system_id, msg)


def message(msg: Any) -> dict[str, Any]:
    """A pymavlink message as its fields (before the codec packs them)."""
    return {k: (list(v) if isinstance(v, bytes | bytearray) else v)
            for k, v in msg.to_dict().items()}  # fmt: skip


def fly(mission_path: Path, out: Path, count: int, every: int, skip: int, speedup: float,
        seconds: float, port: int, base_port: int) -> None:  # fmt: skip
    """SITL and the recording service as processes, the mission flown until recorded."""
    from gcs_ppf.tools.demo import FINISHED, _wait_vehicles, http_json

    doc = json.loads(mission_path.read_text())
    n = len(doc["vehicles"])
    with tempfile.TemporaryDirectory() as tmp:
        links = [a for k in range(n) for a in ("--link", f"tcp:127.0.0.1:{base_port + 10 * k}")]
        procs = [
            subprocess.Popen([sys.executable, "-m", "sitl", str(mission_path), "--base-port",
                              str(base_port), "--speedup", str(speedup)],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL),
            subprocess.Popen([sys.executable, "-m", "tests.record_ticks", "--serve", str(out),
                              str(count), str(every), str(skip), "--",
                              "--port", str(port), "--db", str(Path(tmp) / "db.sqlite"),
                              *links]),
        ]  # fmt: skip
        api = f"http://127.0.0.1:{port}"
        try:
            if not _wait_vehicles(api, n, 90.0):
                raise RuntimeError("vehicles not discovered")
            _, created = http_json("POST", f"{api}/missions", doc)
            http_json("POST", f"{api}/missions/{created['id']}/start")
            deadline = time.monotonic() + seconds
            status: dict[str, Any] = {}
            while time.monotonic() < deadline:
                time.sleep(1.0)
                _, status = http_json("GET", f"{api}/missions/{created['id']}/status")
                if status["state"] in FINISHED or (
                    out.exists() and len(ticks.read(out)[1]) >= count
                ):
                    break
            print(f"state {status.get('state')}, mission time {status.get('mission_time_s')} s")
            http_json("POST", f"{api}/missions/{created['id']}/abort")
        finally:
            for p in procs:
                p.terminate()
                p.wait(timeout=10)
    if not out.exists():
        raise SystemExit(f"no tick recorded in {seconds} s")
    print(f"{len(ticks.read(out)[1])} ticks recorded into {out}")


def main(argv: Sequence[str] | None = None) -> None:
    args = list(sys.argv[1:] if argv is None else argv)
    if args and args[0] == "--serve":
        out, count, every, skip, sep, *rest = args[1:]
        assert sep == "--"
        sys.exit(serve(Path(out), int(count), int(every), int(skip), rest))
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("mission", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--ticks", type=int, default=12)
    parser.add_argument("--every", type=int, default=5)
    parser.add_argument("--skip", type=int, default=10)
    parser.add_argument("--speedup", type=float, default=1.0)
    parser.add_argument("--seconds", type=float, default=300.0)
    parser.add_argument("--port", type=int, default=18530)
    parser.add_argument("--base-port", type=int, default=37760)
    a = parser.parse_args(args)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    fly(a.mission, a.out, a.ticks, a.every, a.skip, a.speedup, a.seconds, a.port, a.base_port)


if __name__ == "__main__":
    main()

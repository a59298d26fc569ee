"""The tick's plans and the run-time assurance's verdicts are those of the code they were
recorded with (``tests.record_ticks``, ``tests/data/ticks``): every tick replayed through
``tick_plan.plan`` and ``commanding.command_fleet`` gives the same plan, the same verdicts,
the same events and the same state after, to the bit, and the same messages in the same
order, byte for byte as sent (``on_wire``).

Recorded before the tick was made to scale (issue 29), so that making it faster cannot
change what it decides; ``formation_100_bench`` (the service benchmark's 100 vehicles, two
ticks of them with 30 commands replaced) was recorded after the assurance's first speed-ups
and replayed identical by the code before them.  A change of the planner itself re-plans
the recorded results from the recorded inputs (crossing_point's guard on a teammate moved 5
of them by at most 1.1e-13 m, rounding; the verdicts and commands replayed unchanged), and
a change of what the tick decides re-derives them all so (the assurance's climbing escapes
and the teammates' margin in a dense formation: of the 100-vehicle benchmark's first tick,
31 commands replaced before, none after)."""

from __future__ import annotations

import asyncio
import json
from functools import partial
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_ppf.guidance import tick_plan
from gcs_ppf.mission import load_mission_file
from gcs_ppf.planning.route import legs
from gcs_ppf.service import commanding
from tests import ticks
from tests.record_ticks import message

RECORDINGS = sorted(ticks.TICKS_DIR.glob("*.json.gz"))


def on_wire(sent: list[Any]) -> list[tuple[int, str]]:
    """Each message sent as the codec packs it, the bytes the vehicle receives (hex): its
    fields before packing are doubles that the WGS-84 conversion's numpy trigonometry
    rounds differently on another CPU (an altitude 7e-10 m apart), which MAVLink's float32
    fields do not carry."""
    packed = []
    for system_id, fields in sent:
        cls = getattr(mavlink2, f"MAVLink_{fields['mavpackettype'].lower()}_message")
        msg = cls(**{k: v for k, v in fields.items() if k != "mavpackettype"})
        packed.append((system_id, msg.pack(mavlink2.MAVLink(None)).hex()))
    return packed


def same(obj: Any, mission: Any) -> str:
    """A canonical text of ``obj`` (NaN equal to NaN, every float exact)."""
    return json.dumps(ticks.encode(obj, mission), sort_keys=True)


class Replay:
    """The fleet as ``command_fleet`` saw it: the telemetry it was given, call by call."""

    def __init__(self, calls: list[Any]) -> None:
        self._calls = list(calls)
        self.sent: list[Any] = []

    def telemetry(self, system_id: int) -> Any:
        vid, t = self._calls.pop(0)
        assert vid == system_id, "the telemetry asked for in another order"
        return t

    async def send(self, system_id: int, msg: Any) -> None:
        self.sent.append([system_id, message(msg)])


def _record(events: list[Any], *a: Any, **kw: Any) -> None:
    events.append([list(a), kw])


def test_the_recordings_are_there_and_exercise_the_assurance() -> None:
    assert len(RECORDINGS) >= 2
    replaced = yielded = 0
    for path in RECORDINGS:
        _, recorded = ticks.read(path)
        assert recorded
        for tick in recorded:
            verdicts = tick["command_fleet"]["result"].values()
            replaced += sum(v.replaced for v in verdicts)
            yielded += sum(v.reason == "teammate" for v in verdicts)
    assert replaced > 0, "no recorded tick replaced a command"
    assert yielded > 0, "no recorded tick judged a teammate"


@pytest.mark.parametrize("path", RECORDINGS, ids=lambda p: Path(p).name)
def test_recorded_plans_are_planned_again(path: Path) -> None:
    mission, recorded = ticks.read(path)
    for k, tick in enumerate(recorded):
        result = tick_plan.plan(*tick["plan"]["args"])
        assert same(result, mission) == same(tick["plan"]["result"], mission), f"tick {k}"


@pytest.mark.parametrize("path", RECORDINGS, ids=lambda p: Path(p).name)
def test_recorded_verdicts_and_commands_are_given_again(path: Path) -> None:
    mission, recorded = ticks.read(path)
    for k, tick in enumerate(recorded):
        rec = tick["command_fleet"]
        args = list(rec["args"])
        events: list[Any] = []
        args[8] = partial(_record, events)
        fleet = Replay(rec["telemetry"])
        verdicts = asyncio.run(commanding.command_fleet(fleet, *args))
        assert same(verdicts, mission) == same(rec["result"], mission), f"tick {k}: verdicts"
        assert on_wire(fleet.sent) == on_wire(rec["sent"]), f"tick {k}: messages"
        assert same(events, mission) == same(rec["events"], mission), f"tick {k}: events"
        after = {"commanded_speed": args[7], "escaping": args[9], "trims": args[11]}
        assert same(after, mission) == same(rec["after"], mission), f"tick {k}: state after"


def test_a_route_leg_with_its_loiter_is_recorded_and_read_back() -> None:
    """A loiter route's tick passes its leg, which holds a pydantic ``Loiter``: recording it
    failed ('cannot record a Loiter'); the mission itself stays a reference."""
    mission = load_mission_file(
        ticks.TICKS_DIR.parents[2] / "examples/arduplane_route_loiter_3.json"
    )
    leg = legs(mission)[0]
    assert leg.loiter is not None
    data = ticks.encode([mission, leg], mission)
    assert data[0] == {"__mission__": None}
    back_mission, back_leg = ticks.decode(json.loads(json.dumps(data)), mission)
    assert back_mission is mission
    assert back_leg.loiter == leg.loiter
    assert same(back_leg, mission) == same(leg, mission)

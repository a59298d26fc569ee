"""Where vehicles hold after a run: the stack keeps the order of their heights, so that no
two climbs or descents to the holding circles cross."""

from __future__ import annotations

import asyncio
import math
import time
from dataclasses import replace
from functools import partial
from typing import Any

import numpy as np
import pytest

from gcs_ppf.guidance import assurance, vehicle_motion
from gcs_ppf.guidance.airframe import Airframe
from gcs_ppf.guidance.online import Guidance, VehicleState, guidance, scene_now
from gcs_ppf.guidance.slew import course_command_rad, course_lead_rad
from gcs_ppf.mavlink import commands, enums
from gcs_ppf.mavlink.telemetry import CommandAck, VehicleTelemetry
from gcs_ppf.mission import Mission
from gcs_ppf.planning.scene import Obstacles, scene_from_mission
from gcs_ppf.service.commanding import (
    SIDE_MEMORY_S,
    STATION_KEEPING_REACH,
    Orders,
    _send_speed,
    command_fleet,
    hold_plan,
    motion,
    override_event,
    planned_commands,
    remember,
    stack_level,
)
from tests.conftest import EXAMPLES


def state(z: float) -> VehicleState:
    return VehicleState((0.0, 0.0, z), 0.0, 0.0, 100.0)


def test_the_lowest_vehicle_now_holds_lowest_and_the_order_of_heights_is_kept() -> None:
    # the mission's order (1…4) is not the order of heights: 2 is highest, 4 lowest
    states = {1: state(300.0), 2: state(474.0), 3: state(350.0), 4: state(299.0)}
    heights = {vid: s.pos_m[2] for vid, s in states.items()}
    levels = {vid: stack_level(vid, heights) for vid in states}
    assert levels == {4: 0, 1: 1, 3: 2, 2: 3}
    order_now = sorted(states, key=lambda v: states[v].pos_m[2])
    assert sorted(states, key=levels.__getitem__) == order_now


def test_vehicles_at_one_height_get_distinct_levels_by_id() -> None:
    heights = {5: 300.0, 2: 300.0, 7: 300.0}
    assert sorted(stack_level(v, heights) for v in heights) == [0, 1, 2]
    assert stack_level(2, heights) == 0
    assert stack_level(7, heights) == 2


def test_a_vehicle_diving_fast_is_stacked_below_one_it_will_level_off_under() -> None:
    """At a run's end wingman 3 is 20 m above wingman 4 but diving at 40 m/s, wingman 4
    climbing at 20 m/s (the paper's airframe, TECS_TIME_CONST 1 s): wingman 3 levels off
    below wingman 4 and is given the lower level, so neither climbs through the other."""
    from gcs_ppf.service.commanding import levelling_height

    mission = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())
    airframe = Airframe(tecs_time_constant_s=1.0, climb_max_m_s=100.0, sink_max_m_s=100.0)
    diving = VehicleState((0.0, 0.0, 794.0), 0.0, 0.0, 150.0, climb_rate_m_s=-40.0)
    climbing = VehicleState((300.0, 0.0, 774.0), 0.0, 0.0, 150.0, climb_rate_m_s=20.0)
    heights = {3: levelling_height(diving, airframe, mission),
               4: levelling_height(climbing, airframe, mission)}  # fmt: skip
    assert heights[3] < 794.0 - 30.0  # 794 − 40 × (1 / 1.75 + 0.4) = 755.1
    assert heights[4] > 774.0 + 15.0
    assert stack_level(3, heights) == 0
    assert stack_level(4, heights) == 1
    assert stack_level(3, {3: 794.0, 4: 774.0}) == 1  # by the heights they had


def test_a_fleet_too_large_for_a_stack_holds_spread_apart_at_its_own_heights() -> None:
    """Ten vehicles stack; eleven hold at their own heights on circles that cross nowhere
    (``STACK_LEVELS_MAX``: climbing to 100 levels, neighbours climbed side by side on crossing
    circles, 47.9 m apart); a return home still flies from a stack."""
    from gcs_ppf.guidance.holding import flown_width_m
    from gcs_ppf.service.commanding import STACK_LEVELS_MAX, stack_spacing_m

    doc = {
        "target": [8000.0, 0.0, 500.0],
        "vehicles": [{"id": 1, "role": "leader", "position": [0.0, 0.0, 500.0],
                      "pitch": 0.0, "yaw": 0.0}]
        + [{"id": k, "role": "wingman", "position": [-150.0 * k, 0.0, 500.0], "pitch": 0.0,
            "yaw": 0.0, "slot": [-150.0 * k, 0.0, 0.0]} for k in range(2, 13)],
    }  # fmt: skip
    mission = Mission.model_validate(doc)

    def plan(n: int, at_end: str = "loiter", completed: bool = True) -> dict[int, Any]:
        states = {k: VehicleState((9000.0 - 150.0 * k, 150.0 * (k % 2), 500.0 + 3.0 * k), 0.0,
                                  0.0, 100.0) for k in range(1, n + 1)}  # fmt: skip
        airframes = {k: Airframe() for k in states}
        m = Mission.model_validate({**doc, "at_end": at_end})
        return hold_plan(Orders(m, "course", 1.0), states, airframes, 90.0, completed,
                         lambda *a, **k: None, set(states)).circles  # fmt: skip

    stacked = plan(STACK_LEVELS_MAX)
    assert len({round(h.z_m) for h in stacked.values()}) == STACK_LEVELS_MAX
    spread = plan(STACK_LEVELS_MAX + 1)
    assert {k: h.z_m for k, h in spread.items()} == {k: 500.0 + 3.0 * k for k in spread}
    wide = flown_width_m(spread[1].radius_m, None)
    for i, a in spread.items():
        for j, b in spread.items():
            if i < j:
                assert math.hypot(a.x_m - b.x_m, a.y_m - b.y_m) > 2.0 * wide
    levels = sorted(h.z_m for h in plan(STACK_LEVELS_MAX + 1, at_end="rtl").values())
    assert np.diff(levels).min() == pytest.approx(stack_spacing_m(mission))
    aborted = plan(STACK_LEVELS_MAX + 1, at_end="rtl", completed=False)  # no way home flown
    assert {k: h.z_m for k, h in aborted.items()} == {k: 500.0 + 3.0 * k for k in aborted}


def test_a_vehicle_whose_command_is_replaced_by_an_escape_is_told_to_fly_its_slowest() -> None:
    """The planner flies the leader straight at a sphere 650 m ahead at 200 m/s (its keep-out
    and the turn it needs are within the hold): the assurance replaces the course, and the
    speed sent is the mission's v_min (the tightest turn), not the plan's."""
    mission = Mission.model_validate({
        "target": [8000.0, 0.0, 300.0],
        "limits": {"v_init": 200.0, "v_min": 100.0, "v_max": 300.0},
        "vehicles": [{"id": 1, "role": "leader", "position": [0.0, 0.0, 300.0],
                      "pitch": 0.0, "yaw": 0.0}],
    })  # fmt: skip
    states = {1: VehicleState((0.0, 0.0, 300.0), 0.0, 0.0, 200.0)}
    scene = scene_now(mission, states, {1}, scene_from_mission(mission).obstacles)
    g = guidance(scene, lookahead_s=1.0, dt=0.1)
    sphere = Obstacles(np.array([[650.0, 0.0, 300.0]]), np.array([150.0]), np.zeros((1, 3)))
    keep = assurance.KeepOut(sphere, None, 25.0, 50.0)
    fleet = Recorder()
    verdicts = asyncio.run(command_fleet(
        fleet, g, {1}, states, [Airframe()], Orders(mission, "course", 1.0), keep, 1.0, {},
        lambda *a, **k: None, {}, 0.0,
    ))  # fmt: skip
    assert verdicts[1].replaced
    speeds = [m.param2 for m in fleet.sent if m.get_type() == "COMMAND_LONG"
              and m.command == commands.MAV_CMD_DO_CHANGE_SPEED]  # fmt: skip
    assert speeds == [pytest.approx(100.0)]
    assert g.speed_m_s[0] > 150.0  # the plan's own speed was not the one sent


class Recorder:
    """A fleet of one vehicle that reports no airspeed and records what it is sent."""

    def __init__(self) -> None:
        self.sent: list[Any] = []

    def telemetry(self, system_id: int) -> VehicleTelemetry | None:
        return VehicleTelemetry(system_id=system_id, component_id=1)

    async def send(self, system_id: int, msg: Any) -> None:
        self.sent.append(msg)


def test_the_assurance_counts_on_the_climb_the_pitch_limit_gives_at_the_speed_flown() -> None:
    """The paper's airframe (TECS_CLMB_MAX = v_max·sin 20° = 102.6 m/s, 20° of pitch) at
    100 m/s climbs 34 m/s, not 102.6; ArduPlane's (5 m/s, 25°) at 25 m/s climbs 5 m/s."""
    mission = Mission.model_validate({
        "target": [8000.0, 0.0, 300.0],
        "vehicles": [{"id": 1, "role": "leader", "position": [0.0, 0.0, 300.0],
                      "pitch": 0.0, "yaw": 0.0}],
    })  # fmt: skip
    paper = Airframe(climb_max_m_s=102.6, sink_max_m_s=126.8, pitch_max_deg=20.0,
                     pitch_min_deg=-25.0)  # fmt: skip
    m = motion(VehicleState((0.0, 0.0, 300.0), 0.0, 0.0, 100.0), paper, mission)
    assert m.climb_m_s == pytest.approx(100.0 * math.sin(math.radians(20.0)))
    assert m.sink_m_s == pytest.approx(100.0 * math.sin(math.radians(25.0)))
    plane = Airframe(climb_max_m_s=5.0, sink_max_m_s=5.0, pitch_max_deg=25.0, pitch_min_deg=-20.0)
    m = motion(VehicleState((0.0, 0.0, 300.0), 0.0, 0.0, 25.0), plane, mission)
    assert m.climb_m_s == pytest.approx(5.0)
    assert m.sink_m_s == pytest.approx(5.0)


def test_every_vehicle_holds_at_the_missions_slowest_speed() -> None:
    """GUIDED keeps the last DO_CHANGE_SPEED: a wingman left at 218 m/s on its way to a
    holding circle crossed the centre and swung 1.4 km out, into a sphere (Table 3, ×10, two
    CPU burners). Each hold is a loiter point, then v_min (within the airframe's
    AIRSPEED_MIN..MAX), then the altitude."""
    mission = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())
    states = {
        v.id: VehicleState(
            (6000.0 - 150.0 * i, 7000.0 - 120.0 * i, 300.0 + 50 * i), 0.0, 0.8, 218.0
        )
        for i, v in enumerate(mission.vehicles)
    }
    airframes = {vid: Airframe() for vid in states}
    airframes[3] = Airframe(airspeed_min_m_s=120.0)
    orders = hold_plan(Orders(mission, "course", 1.0), states, airframes, 100.0, True,
                       lambda *a, **k: None, set(states)).orders  # fmt: skip
    for vid in states:
        mine = [o for o in orders if o.vehicle_id == vid]
        assert [o.what for o in mine] == ["hold: guided loiter", "hold: speed", "hold: altitude"]
        speed = mine[1].make()
        assert speed.command == commands.MAV_CMD_DO_CHANGE_SPEED
        assert speed.param2 == pytest.approx(120.0 if vid == 3 else mission.limits.v_min)


def test_the_way_an_escape_turned_is_remembered_for_a_while_after_it() -> None:
    """While a vehicle escapes its escape is in force; back on its plan, the way it turned
    is remembered for ``SIDE_MEMORY_S`` of mission time, then forgotten."""
    escaping: dict[int, assurance.Escape] = {}
    escape = vehicle_motion.Command(0.5, 300.0)
    planned = vehicle_motion.Command(0.0, 300.0)
    replaced = assurance.Verdict(escape, True, "obstacle", -5.0, 40.0, side=1)
    kept = assurance.Verdict(planned, False, None, 60.0, 60.0)
    remember(escaping, 7, replaced, 10.0)
    assert escaping[7] == assurance.Escape(escape, 1)
    remember(escaping, 7, kept, 10.1)
    assert escaping[7] == assurance.Escape(None, 1, 10.1)
    remember(escaping, 7, kept, 10.1 + SIDE_MEMORY_S)
    assert escaping[7].side == 1
    remember(escaping, 7, kept, 10.2 + SIDE_MEMORY_S)
    assert 7 not in escaping
    remember(escaping, 8, kept, 11.0)
    assert escaping == {}


class Fleet:
    """Any number of vehicles that report no airspeed; records what each is sent."""

    def __init__(self) -> None:
        self.sent: list[tuple[int, Any]] = []

    def telemetry(self, system_id: int) -> VehicleTelemetry | None:
        return VehicleTelemetry(system_id=system_id, component_id=1)

    async def send(self, system_id: int, msg: Any) -> None:
        self.sent.append((system_id, msg))


def headings_sent(fleet: Fleet, vid: int) -> list[float]:
    """The courses (compass degrees) ``vid`` was sent by GUIDED_CHANGE_HEADING."""
    return [m.param2 for i, m in fleet.sent if i == vid and m.get_type() == "COMMAND_INT"
            and m.command == commands.MAV_CMD_GUIDED_CHANGE_HEADING]  # fmt: skip


def on_circle(hold: Any, angle: float, speed: float, z: float) -> VehicleState:
    """A vehicle on ``hold``'s ring as flown, at ``angle`` round its centre, flying it
    clockwise at ``speed``."""
    from gcs_ppf.guidance.holding import flown_radius_m

    r = flown_radius_m(hold.radius_m)
    pos = (hold.x_m + r * math.cos(angle), hold.y_m + r * math.sin(angle), z)
    return VehicleState(pos, 0.0, angle - math.pi / 2.0, speed)


def test_vehicles_circling_one_level_of_the_stack_apart_fly_their_circles_unreplaced() -> None:
    """Table 3 (v_min 100 m/s, safe distance 50 m): two vehicles on one circle one level
    apart, one right above the other, each as far off its level towards the other as a
    settled vehicle may be, are told the loiter course and their levels, none replaced
    (``stack_spacing_m``), with the slack to spare; 100 m apart, the lower one 5 m high, the
    lower one's margin is under the slack (an escape looked for every tick they cross)."""
    from gcs_ppf.guidance.holding import SETTLED_HEIGHT_M, Hold
    from gcs_ppf.service.commanding import command_holds, stack_spacing_m

    mission = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())
    none = Obstacles(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)))
    keep = assurance.KeepOut(none, None, 25.0, 50.0)
    airframes = {1: Airframe(), 2: Airframe()}
    spacing = stack_spacing_m(mission)
    assert spacing >= 2 * 50.0 + assurance.SLACK_S * 100.0

    def fly(levels_m: float, gap_m: float) -> dict[int, assurance.Verdict]:
        circles = {1: Hold(0.0, 0.0, 1000.0, 290.0, math.inf),
                   2: Hold(0.0, 0.0, 1000.0 - levels_m, 290.0, math.inf)}  # fmt: skip
        states = {1: on_circle(circles[1], 1.0, 100.0, 1000.0),
                  2: on_circle(circles[2], 1.0, 100.0, 1000.0 - gap_m)}  # fmt: skip
        motions = [motion(states[i], airframes[i], mission) for i in (1, 2)]
        return asyncio.run(command_holds(
            Fleet(), circles, [1, 2], motions, Orders(mission, "course", 1.0), keep, 1.0,
            lambda *a, **k: None, {}, 0.0,
        ))  # fmt: skip

    verdicts = fly(spacing, spacing - 2.0 * SETTLED_HEIGHT_M)
    assert not any(v.replaced for v in verdicts.values())
    assert [v.reason for v in verdicts.values()] == [None, None]
    assert [v.command.z_m for v in verdicts.values()] == [1000.0, 1000.0 - spacing]
    close = fly(100.0, 95.0)[2]
    assert close.reason == "teammate"
    assert close.margin_m < assurance.SLACK_S * 100.0


def test_a_vehicle_heard_at_rest_is_told_its_hold_at_the_hold_airspeed() -> None:
    """A vehicle in a launch's holds heard at 0 m/s (its takeoff just begun) is told the
    loiter course with the lateral acceleration of the airspeed it holds at: at the speed
    it reports, 0, the heading command raised and the holds failed."""
    from gcs_ppf.guidance.holding import Hold
    from gcs_ppf.service.commanding import command_holds, hold_motion, slowest_airspeed

    mission = Mission.model_validate_json((EXAMPLES / "arduplane_5.json").read_text())
    none = Obstacles(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)))
    keep = assurance.KeepOut(none, None, 25.0, 50.0)
    circles = {1: Hold(2000.0, 0.0, 100.0, 150.0, math.inf)}
    state = VehicleState((0.0, 0.0, 0.0), 0.0, 0.0, 0.0)
    m = hold_motion(state, Airframe(), mission)
    assert m.speed_m_s == slowest_airspeed(mission, Airframe()) > 0.0
    fleet = Fleet()
    verdicts = asyncio.run(command_holds(
        fleet, circles, [1], [m], Orders(mission, "course", 1.0), keep, 1.0,
        lambda *a, **k: None, {}, 0.0,
    ))  # fmt: skip
    assert list(verdicts) == [1]
    assert len(headings_sent(fleet, 1)) == 1


def test_a_loiter_course_that_would_cut_a_keep_out_is_replaced_by_an_escape() -> None:
    """A vehicle on its way to its circle whose loiter course runs it at a sphere 270 m
    ahead is sent an escape instead, with an ``assurance_override`` event of the holding
    phase; its teammate, whose course is clear, is sent the loiter course itself."""
    from gcs_ppf.guidance.holding import Hold, flown_radius_m, loiter_course
    from gcs_ppf.service.commanding import command_holds

    mission = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())
    sphere = Obstacles(np.array([[420.0, 0.0, 1000.0]]), np.array([150.0]), np.zeros((1, 3)))
    keep = assurance.KeepOut(sphere, None, 25.0, 50.0)
    circles = {1: Hold(5000.0, 0.0, 1000.0, 290.0, math.inf),
               2: Hold(0.0, 5000.0, 1500.0, 290.0, math.inf)}  # fmt: skip
    states = {1: VehicleState((0.0, 0.0, 1000.0), 0.0, 0.0, 100.0),
              2: VehicleState((-3000.0, 0.0, 1500.0), 0.0, 0.0, 100.0)}  # fmt: skip
    events: list[tuple[Any, ...]] = []
    fleet = Fleet()
    motions = [motion(states[i], Airframe(), mission) for i in (1, 2)]
    verdicts = asyncio.run(command_holds(
        fleet, circles, [1, 2], motions, Orders(mission, "course", 1.0), keep, 1.0,
        lambda *a, **k: events.append((a, k)), {}, 0.0,
    ))  # fmt: skip
    assert verdicts[1].replaced
    assert verdicts[1].reason == "obstacle"
    assert [(a, k["phase"]) for a, k in events] == [(("assurance_override", 1), "hold")]
    m = motion(states[2], Airframe(), mission)
    wanted = loiter_course(m.pos_m, 0.0, 5000.0, flown_radius_m(290.0), m.speed_m_s,
                           m.turn_rate_rad_s, m.heading_tau_s)  # fmt: skip
    assert not verdicts[2].replaced
    assert headings_sent(fleet, 2) == [pytest.approx(90.0 - math.degrees(wanted), abs=1e-3)]
    assert headings_sent(fleet, 1) == [
        pytest.approx(90.0 - math.degrees(verdicts[1].command.course_rad), abs=1e-3)
    ]


def test_an_override_event_names_the_teammate_given_way_to_by_its_id() -> None:
    """``Verdict.gives_way_to`` indexes the vehicles assured; the event names that vehicle's
    system id, and an override that gives way to no one carries no such field."""
    seen: list[tuple[str, int, dict[str, Any]]] = []

    def event(kind: str, vid: int, **detail: Any) -> None:
        seen.append((kind, vid, detail))

    sent = vehicle_motion.Command(0.5, 300.0)
    giving = assurance.Verdict(sent, True, "teammate", 80.0, 90.0, -1, gives_way_to=1)
    override_event(event, 7, giving, [7, 9], phase="hold")
    escaping = assurance.Verdict(sent, True, "obstacle", -5.0, 30.0, 1)
    override_event(event, 9, escaping, [7, 9])
    assert seen[0] == ("assurance_override", 7, {
        "keep_out": "teammate", "planned_margin_m": 80.0, "sent_margin_m": 90.0,
        "turn": "right", "phase": "hold", "gives_way_to": 9,
    })  # fmt: skip
    assert "gives_way_to" not in seen[1][2]
    assert seen[1][2]["turn"] == "left"


def test_wingmen_are_led_for_their_leaders_turn_and_an_avoiding_one_for_its_own() -> None:
    """At ArduPlane's scale a wingman keeping station (within ``STATION_KEEPING_REACH``
    target accuracies of its slot) is led for the turn its leader's plan makes (the
    formation's), its own correction sent as planned; one avoiding, or one still joining
    its slot from afar, is led for its own planned turn (cut against its correction), as is
    the leader.  At the paper's scale every vehicle is led for its own planned turn,
    uncut."""
    arduplane = Mission.model_validate_json(
        (EXAMPLES / "arduplane_route_loiter_3.json").read_text()
    )
    paper = Mission.model_validate_json((EXAMPLES / "paper_table2.json").read_text())
    g = Guidance(
        ids=[1, 2, 3],
        guided_point_m=np.zeros((3, 3)),
        speed_m_s=np.array([22.0, 22.0, 22.0]),
        course_rad=np.array([0.0, 0.05, -0.05]),
        turn_rate_rad_s=np.array([-0.03, 0.2, 0.25]),
        climb_rate_m_s=np.zeros(3),
        state=["s1", "s1", "s1"],
        avoiding=[False, False, True],
        formed=[True, False, False],
        local_target_distance_m=[None, 8.0, 12.0],
        leader_arrives_within_lookahead=False,
    )
    states = {vid: VehicleState((0.0, 0.0, 100.0), 0.0, 0.0, 22.0) for vid in (1, 2, 3)}
    airframes = [Airframe(guided_p=5000.0, roll_limit_deg=65.0)] * 3
    led = planned_commands(g, states, airframes, Orders(arduplane, "course", 3.0), 8.4, True)
    lead = partial(course_lead_rad, speed_m_s=22.0, guided_p=5000.0, roll_limit_deg=65.0)
    assert led[1].course_rad == pytest.approx(0.05 + lead(-0.03))  # the leader's turn
    assert led[2].course_rad == pytest.approx(
        course_command_rad(-0.05, 0.25, 22.0, 5000.0, 65.0, 0.0)
    )
    assert led[0].course_rad == pytest.approx(
        course_command_rad(0.0, -0.03, 22.0, 5000.0, 65.0, 0.0)
    )
    joining = replace(g, local_target_distance_m=[None, 30.1, 12.0])
    orders = Orders(arduplane, "course", 3.0)
    led = planned_commands(joining, states, airframes, orders, 8.4, True)
    assert STATION_KEEPING_REACH * arduplane.limits.target_accuracy == pytest.approx(30.0)
    assert led[1].course_rad == pytest.approx(
        course_command_rad(0.05, 0.2, 22.0, 5000.0, 65.0, 0.0)
    )
    own = planned_commands(g, states, airframes, Orders(paper, "course", 3.0), 8.4, False)
    for i in range(3):
        expected = float(g.course_rad[i]) + lead(float(g.turn_rate_rad_s[i]))
        assert own[i].course_rad == pytest.approx(expected)


def test_an_airspeed_not_acknowledged_is_sent_again_and_one_answered_is_not() -> None:
    """Sent only when it changes, a DO_CHANGE_SPEED lost on the link was never sent again
    while the plan's speed stayed within the deadband.  Unanswered past the wait, the same
    airspeed goes again; answered (accepted or refused), or within the wait, it does not."""
    g = Guidance(
        ids=[1],
        guided_point_m=np.zeros((1, 3)),
        speed_m_s=np.array([22.0]),
        course_rad=np.zeros(1),
        turn_rate_rad_s=np.zeros(1),
        climb_rate_m_s=np.zeros(1),
        state=["s1"],
        avoiding=[False],
        formed=[True],
        local_target_distance_m=[None],
        leader_arrives_within_lookahead=False,
    )

    class Acking(Recorder):
        def __init__(self) -> None:
            super().__init__()
            self.acks: tuple[CommandAck, ...] = ()

        def telemetry(self, system_id: int) -> VehicleTelemetry | None:
            return VehicleTelemetry(system_id=system_id, component_id=1, command_acks=self.acks)

    def speeds(fleet: Recorder) -> list[float]:
        return [m.param2 for m in fleet.sent if m.command == commands.MAV_CMD_DO_CHANGE_SPEED]

    fleet, commanded, sent = Acking(), {}, {}  # type: ignore[var-annotated]
    send = partial(_send_speed, fleet, 1, g, 0, Airframe(), commanded, True, None, sent)
    asyncio.run(send(ack_wait_s=1e6))
    asyncio.run(send(ack_wait_s=1e6))  # not answered yet, but within the wait
    assert speeds(fleet) == [pytest.approx(22.0)]
    asyncio.run(send(ack_wait_s=0.0))  # past it, unanswered: again
    assert speeds(fleet) == [pytest.approx(22.0)] * 2
    for result in (enums.MAV_RESULT_ACCEPTED, enums.MAV_RESULT_DENIED):
        fleet.acks = (CommandAck(commands.MAV_CMD_DO_CHANGE_SPEED, result, time.monotonic()),)
        asyncio.run(send(ack_wait_s=0.0))
        assert len(speeds(fleet)) == 2
    without, once = Recorder(), {}  # type: ignore[var-annotated]
    for _ in range(3):  # no record of the sends: sent on a change only, as before
        asyncio.run(_send_speed(without, 1, g, 0, Airframe(), once, True, None, None, 0.0))
    assert speeds(without) == [pytest.approx(22.0)]

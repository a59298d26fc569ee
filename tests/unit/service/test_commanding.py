"""Where vehicles hold after a run: the stack keeps the order of their heights, so that no
two climbs or descents to the holding circles cross."""

from __future__ import annotations

from gcs_ppf.guidance.online import VehicleState
from gcs_ppf.service.commanding import stack_level


def state(z: float) -> VehicleState:
    return VehicleState((0.0, 0.0, z), 0.0, 0.0, 100.0)


def test_the_lowest_vehicle_now_holds_lowest_and_the_order_of_heights_is_kept() -> None:
    # the mission's order (1…4) is not the order of heights: 2 is highest, 4 lowest
    states = {1: state(300.0), 2: state(474.0), 3: state(350.0), 4: state(299.0)}
    levels = {vid: stack_level(vid, states) for vid in states}
    assert levels == {4: 0, 1: 1, 3: 2, 2: 3}
    order_now = sorted(states, key=lambda v: states[v].pos_m[2])
    assert sorted(states, key=levels.__getitem__) == order_now


def test_vehicles_at_one_height_get_distinct_levels_by_id() -> None:
    states = {5: state(300.0), 2: state(300.0), 7: state(300.0)}
    assert sorted(stack_level(v, states) for v in states) == [0, 1, 2]
    assert stack_level(2, states) == 0
    assert stack_level(7, states) == 2

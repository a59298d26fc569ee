"""Leader succession (``gcs_ppf.planning.succession``): the wingman of highest priority
leads, and every vehicle keeps its place in the formation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from gcs_ppf.mission import Mission
from gcs_ppf.planning.succession import succeed, successors
from tests.conftest import EXAMPLES

TABLE3 = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())


def _places(mission: Mission) -> dict[int, np.ndarray]:
    """Each vehicle's offset from the leader, in the leader's frame."""
    return {v.id: np.zeros(3) if v.slot is None else np.array(v.slot) for v in mission.vehicles}


def test_the_first_wingman_by_priority_leads_and_every_place_is_kept() -> None:
    led = succeed(TABLE3, {1})
    assert led is not None
    assert led.leader.id == 2
    before, after = _places(TABLE3), _places(led)
    for a in before:
        for b in before:  # every vehicle where it was relative to every other
            assert np.allclose(before[a] - before[b], after[a] - after[b])
    assert [v.id for v in led.vehicles] == [v.id for v in TABLE3.vehicles]
    assert {v.id: v.position for v in led.vehicles} == {v.id: v.position for v in TABLE3.vehicles}


def test_priority_then_id_chooses_and_lost_wingmen_are_passed_over() -> None:
    doc = TABLE3.model_dump()
    doc["vehicles"][4]["priority"] = -1  # wingman 5 first
    chosen = Mission.model_validate(doc)
    assert [v.id for v in successors(chosen, {1})] == [5, 2, 3, 4]
    assert [v.id for v in successors(TABLE3, {1, 2})] == [3, 4, 5]
    assert successors(TABLE3, {1, 2, 3, 4, 5}) == []
    assert succeed(TABLE3, {1, 2, 3, 4, 5}) is None


def test_a_second_succession_keeps_the_places_too() -> None:
    once = succeed(TABLE3, {1})
    assert once is not None
    twice = succeed(once, {1, 2})
    assert twice is not None
    assert twice.leader.id == 3
    before, after = _places(TABLE3), _places(twice)
    assert all(np.allclose(before[v] - before[3], after[v]) for v in before)


@given(st.lists(st.tuples(*[st.floats(-500, 500)] * 3), min_size=1, max_size=6, unique=True))
def test_any_formation_keeps_its_geometry(slots: list[tuple[float, float, float]]) -> None:
    doc = TABLE3.model_dump()
    leader = doc["vehicles"][0]
    wingmen = [
        {**doc["vehicles"][1], "id": 2 + k, "slot": s, "position": [1000.0 * k, 0.0, 500.0]}
        for k, s in enumerate(slots)
    ]
    try:
        mission = Mission.model_validate({**doc, "vehicles": [leader, *wingmen]})
    except ValueError:
        assume(False)  # slots the mission refuses (within the safe distance of the leader)
    led = succeed(mission, {1})
    assert led is not None
    assert led.leader.id == 2

    before, after = _places(mission), _places(led)
    for vid in before:
        assert after[vid] == pytest.approx(before[vid] - before[2], abs=1e-9)

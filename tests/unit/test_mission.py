"""The mission document (CONVENTIONS §3): examples load, bad input names its field."""

from __future__ import annotations

import copy
import json
import math
from collections.abc import Callable
from typing import Any

import pytest

from gcs_ppf.mission import MissionError, load_mission
from tests.conftest import EXAMPLES

Doc = dict[str, Any]


def table3_doc() -> Doc:
    doc: Doc = json.loads((EXAMPLES / "paper_table3.json").read_text())
    return doc


def test_examples_transcribe_the_paper(table2: Any, table3: Any) -> None:
    assert table2.target == (6000.0, 7000.0, 4800.0)
    assert table3.target == (6000.0, 7000.0, 300.0)
    assert [v.id for v in table3.vehicles] == [1, 2, 3, 4, 5]
    assert table3.leader.id == 1
    assert next(w.slot for w in table2.wingmen) == (-300.0, 300.0, 0.0)
    assert [w.slot for w in table3.wingmen][3] == (-200.0, -200.0, 0.0)
    assert [o.radius for o in table3.obstacles] == [350.0, 650.0, 650.0, 850.0]
    assert table3.limits.max_yaw_rate == pytest.approx(math.pi / 6)


def _set(path: list[Any], value: Any) -> Callable[[Doc], None]:
    def edit(doc: Doc) -> None:
        node = doc
        for key in path[:-1]:
            node = node[key]
        node[path[-1]] = value

    return edit


def _two_leaders(doc: Doc) -> None:
    doc["vehicles"][1]["role"] = "leader"
    del doc["vehicles"][1]["slot"]


def _no_leader(doc: Doc) -> None:
    doc["vehicles"][0]["role"] = "wingman"
    doc["vehicles"][0]["slot"] = [-400.0, 0.0, 0.0]


BAD: dict[str, tuple[Callable[[Doc], None], str]] = {
    "nan": (_set(["target", 2], math.nan), "target[2]"),
    "infinite speed": (_set(["limits", "v_max"], math.inf), "limits.v_max"),
    "zero radius": (_set(["obstacles", 0, "radius"], 0.0), "obstacles[0].radius"),
    "negative radius": (_set(["obstacles", 1, "radius"], -5.0), "obstacles[1].radius"),
    "zero dt": (_set(["planner", "dt"], 0.0), "planner.dt"),
    "negative dt": (_set(["planner", "dt"], -0.01), "planner.dt"),
    "duplicate id": (_set(["vehicles", 3, "id"], 2), "vehicles[3].id"),
    "two leaders": (_two_leaders, "vehicles"),
    "no leader": (_no_leader, "vehicles"),
    "wingman without slot": (lambda d: d["vehicles"][2].pop("slot"), "vehicles[2].slot"),
    "vehicle in obstacle": (
        _set(["vehicles", 2, "position"], [3000.0, 3100.0, 100.0]),
        "vehicles[2].position",
    ),
    "target in obstacle": (_set(["target"], [4500.0, 6000.0, 200.0]), "target"),
    "slots too close": (_set(["vehicles", 2, "slot"], [-110.0, 120.0, 0.0]), "vehicles[2].slot"),
    "unknown key": (_set(["vehicles", 0, "colour"], "blue"), "vehicles[0].colour"),
    "unknown top-level key": (_set(["obstacle"], []), "obstacle"),
    "bad method": (_set(["planner", "method"], "rrt"), "planner.method"),
    "string for number": (_set(["limits", "accel"], "fast"), "limits.accel"),
    "v_min above v_max": (_set(["limits", "v_min"], 400.0), "limits.v_min"),
    "vehicle under the ground": (_set(["ground"], 10.0), "vehicles[1].position"),
    "leader too near the ground": (_set(["ground"], 290.0), "vehicles[0].position"),
    "infinite ground": (_set(["ground"], -math.inf), "ground"),
    "unknown formation frame": (_set(["formation_frame"], "wind"), "formation_frame"),
}


def test_target_closer_to_the_ground_than_the_safe_distance() -> None:
    doc = copy.deepcopy(table3_doc())
    doc["ground"] = -200.0
    doc["target"] = [6000.0, 7000.0, -180.0]
    with pytest.raises(MissionError) as err:
        load_mission(json.dumps(doc))
    assert err.value.field == "target"
    doc["target"] = [6000.0, 7000.0, -175.0]  # exactly the safe distance up: fine
    assert load_mission(json.dumps(doc)).ground == -200.0


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_mission_names_the_field(case: str) -> None:
    edit, field = BAD[case]
    doc = copy.deepcopy(table3_doc())
    edit(doc)
    with pytest.raises(MissionError) as err:
        load_mission(json.dumps(doc))
    assert err.value.field == field
    assert str(err.value).startswith(field)


def test_nan_literal_in_json_text_is_rejected() -> None:
    text = json.dumps(table3_doc()).replace("6000.0, 7000.0, 300.0", "6000.0, NaN, 300.0")
    with pytest.raises(MissionError, match=r"target\[1\]"):
        load_mission(text)


@pytest.mark.parametrize("text", ["", "[1, 2]", "{not json", "null"])
def test_not_a_mission_document(text: str) -> None:
    with pytest.raises(MissionError, match="mission"):
        load_mission(text)


def test_defaults_are_table1() -> None:
    doc = {
        "target": [0.0, 0.0, 0.0],
        "vehicles": [{"id": 1, "role": "leader", "position": [-5000.0, 0.0, 0.0]}],
    }
    m = load_mission(json.dumps(doc))
    assert (m.limits.v_min, m.limits.v_max, m.limits.accel, m.limits.decel) == (100, 300, 10, 40)
    assert m.limits.target_accuracy == 10.0
    assert m.planner.dt == 0.01

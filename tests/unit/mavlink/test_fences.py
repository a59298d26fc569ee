"""Zones as ArduPlane fence items."""

from __future__ import annotations

from gcs_ppf.mavlink import fences
from gcs_ppf.mission import Mission
from tests.conftest import EXAMPLES


def doc_with(zones: list[dict[str, object]]) -> Mission:
    doc = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text()).model_dump()
    doc["zones"] = zones
    return Mission.model_validate(doc)


def test_inclusion_always_and_exclusion_only_unbounded_unless_footprints() -> None:
    mission = doc_with(
        [
            {"kind": "polygon", "inclusion": True, "ceiling": 900.0,
             "vertices": [[0, 0], [9000, 0], [9000, 9000], [0, 9000]]},
            {"kind": "cylinder", "center_latlon": [47.40, 8.55], "radius": 200.0},
            {"kind": "cylinder", "center": [3000, 3000], "radius": 300.0, "ceiling": 450.0},
        ]
    )  # fmt: skip
    items, left_out = fences.fence_items(mission)
    assert [i.command for i in items] == [fences.POLYGON_INCLUSION] * 4 + [fences.CIRCLE_EXCLUSION]
    assert all(i.param1 == 4.0 for i in items[:4])
    assert (items[4].lat_e7, items[4].lon_e7, items[4].param1) == (474000000, 85500000, 200.0)
    assert len(left_out) == 1
    assert left_out[0].startswith("zones[2]: an exclusion zone with a floor or a ceiling")
    both, none_left = fences.fence_items(mission, footprints=True)
    assert len(both) == 6
    assert none_left == []
    assert fences.same(items, list(items))
    assert not fences.same(items, items[:-1])
    moved = [*items[:-1], fences.FenceItem(items[-1].command, items[-1].lat_e7 + 1,
                                           items[-1].lon_e7, 200.0)]  # fmt: skip
    assert not fences.same(items, moved)

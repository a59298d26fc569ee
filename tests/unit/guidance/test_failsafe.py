"""The failsafe's RTL altitudes: over every keep-out, one holding level apart."""

from __future__ import annotations

import itertools
import math

import pytest

from gcs_ppf.guidance import failsafe
from gcs_ppf.mission import Mission
from tests.conftest import EXAMPLES

TABLE3 = Mission.model_validate_json((EXAMPLES / "paper_table3.json").read_text())


def test_table3_comes_home_over_its_highest_sphere_one_level_apart() -> None:
    # the highest sphere: centre z 100, radius 850; safe distance 25
    assert failsafe.keep_outs_top_m(TABLE3, 0.0) == pytest.approx(975.0)
    homes = {1: 0.0, 2: 0.0, 3: 10.0, 4: 0.0, 5: -5.0}
    alt = failsafe.rtl_altitudes_m(TABLE3, homes, 0.0, 150.0)
    assert alt == {1: 975.0, 2: 1125.0, 3: 1265.0, 4: 1425.0, 5: 1580.0}
    levels = sorted(alt[v] + homes[v] for v in homes)
    assert min(b - a for a, b in itertools.pairwise(levels)) == pytest.approx(150.0)


def test_without_keep_outs_over_the_homes_and_zones_by_their_ceilings() -> None:
    doc = TABLE3.model_dump()
    doc["obstacles"] = []
    bare = Mission.model_validate(doc)
    assert failsafe.keep_outs_top_m(bare, 0.0) == -math.inf
    assert failsafe.rtl_altitudes_m(bare, {1: 50.0, 2: 0.0}, 0.0, 100.0) == {1: 25.0, 2: 175.0}
    doc["zones"] = [
        {"kind": "cylinder", "center": [0, 0], "radius": 100, "floor": 0, "ceiling": 400},
        {"kind": "cylinder", "center": [9000, 0], "radius": 100},  # no ceiling: not overflown
    ]
    zoned = Mission.model_validate(doc)
    assert failsafe.keep_outs_top_m(zoned, 0.0) == pytest.approx(425.0)
    assert failsafe.rtl_altitudes_m(zoned, {}, 0.0, 100.0) == {}

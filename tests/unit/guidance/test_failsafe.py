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


def test_a_way_home_over_every_sphere_is_clear_and_one_into_a_zone_is_not() -> None:
    """From circles above Table 3's target at the return floor (twice the safe distance over
    the highest sphere, 1,000 m) and a level above it, straight home to two starts: clear,
    the RTL altitude the level over the home.  A no-fly cylinder without a ceiling across
    the way, a level too low over the home: not clear."""
    floor = failsafe.return_floor_m(TABLE3, {1: 300.0, 2: 0.0}, 0.0)
    assert floor == pytest.approx(1000.0)
    circles = {1: ((6000.0, 7000.0, floor), 300.0), 2: ((6000.0, 7000.0, floor + 150.0), 300.0)}
    homes = {1: (1500.0, 2000.0, 300.0), 2: (2000.0, 1500.0, 0.0)}
    ways = failsafe.ways_home(TABLE3, circles, homes, 0.0)
    assert ways[1].clear
    assert ways[2].clear
    assert (ways[1].rtl_altitude_m, ways[2].rtl_altitude_m) == (700.0, 1150.0)
    assert ways[1].clearance_m == pytest.approx(77.3, abs=0.1)  # over the 850 m sphere
    doc = TABLE3.model_dump()
    doc["zones"] = [{"kind": "cylinder", "center": [3750.0, 4500.0], "radius": 200.0}]
    walled = Mission.model_validate(doc)
    assert not failsafe.ways_home(walled, circles, homes, 0.0)[1].clear
    under = {1: (3000.0, 3000.0, 400.0)}  # under the first sphere's top: home at the level
    assert failsafe.ways_home(TABLE3, {1: circles[1]}, under, 0.0)[1].clear
    low = {1: (1500.0, 2000.0, 990.0)}
    assert not failsafe.ways_home(TABLE3, {1: circles[1]}, low, 0.0)[1].clear
    assert failsafe.ways_home(TABLE3, circles, {}, 0.0) == {}

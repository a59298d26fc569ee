"""Run-time assurance among zones: a command into a cylinder, a polygon (concave too) or
out of an inclusion zone, too close to escape, is replaced with the reason ``zone``; one
with room, or over a zone's ceiling, is kept; the margin is the zone surface's distance."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_ppf.guidance.assurance import SLACK_S, KeepOut, assure, score
from gcs_ppf.guidance.vehicle_motion import Command, Motion, escape_s, hold_path
from gcs_ppf.mission import CylinderZone, Mission, PolygonZone
from gcs_ppf.planning.scene import Obstacles
from gcs_ppf.planning.zones import Zones, zone_clearances, zones_of

SPEED, OMEGA, SAFE = 25.0, 0.3, 25.0
NO_SPHERES = Obstacles(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)))
ORIGIN_MISSION = Mission.model_validate(
    {"target": [0.0, 0.0, 300.0], "vehicles": [{"id": 1, "role": "leader", "position": [0, 0, 0]}]}
)


def zones(*zs: CylinderZone | PolygonZone) -> Zones:
    return zones_of(list(zs), ORIGIN_MISSION.origin)


def keep(z: Zones) -> KeepOut:
    return KeepOut(NO_SPHERES, 0.0, SAFE, 50.0, zones=z)


def plane(x: float, y: float, z: float, yaw: float) -> Motion:
    return Motion((x, y, z), yaw, SPEED, OMEGA, climb_m_s=5.0, sink_m_s=5.0, heading_tau_s=1.5)


CYLINDER = CylinderZone(kind="cylinder", center=(200.0, 0.0), radius=100.0)
SQUARE = PolygonZone(kind="polygon", vertices=[(125, -100), (325, -100), (325, 100), (125, 100)])
U_OPEN_WEST = PolygonZone(  # a U opening west, the vehicle in its pocket flying to its end
    kind="polygon",
    vertices=[(-100, -400), (600, -400), (600, 400), (-100, 400), (-100, 200), (200, 200),
              (200, -200), (-100, -200)],
)  # fmt: skip


@pytest.mark.parametrize("zone", [CYLINDER, SQUARE, U_OPEN_WEST], ids=["cylinder", "square", "U"])
def test_a_course_into_a_zone_close_ahead_is_replaced_by_one_that_escapes(
    zone: CylinderZone | PolygonZone,
) -> None:
    m = plane(0.0, 0.0, 150.0, 0.0)
    [alone] = assure([m], [Command(0.0, 150.0)], 1.0, keep(zones()))
    assert not alone.replaced  # nothing but the zone makes the difference
    [v] = assure([m], [Command(0.0, 150.0)], 1.0, keep(zones(zone)))
    assert v.replaced
    assert v.reason == "zone"
    assert v.margin_m < SLACK_S * SPEED
    assert v.margin_m < v.chosen_margin_m
    assert v.chosen_margin_m >= 0.0
    s, _ = score(m, v.command, 1.0, keep(zones(zone)), [])
    assert s == pytest.approx(v.chosen_margin_m)


def test_a_zone_whose_ceiling_is_well_below_the_vehicle_is_flown_over() -> None:
    low = CylinderZone(kind="cylinder", center=(200.0, 0.0), radius=100.0, ceiling=100.0)
    m = plane(0.0, 0.0, 150.0, 0.0)
    [v] = assure([m], [Command(0.0, 150.0)], 1.0, keep(zones(low)))
    assert not v.replaced
    s, reason = score(m, Command(0.0, 150.0), 1.0, keep(zones(low)), [])
    assert reason == "zone"
    # at least level over its top, at most as much higher as an escape climbs
    level = 150.0 - 100.0 - SAFE
    assert level - 1.0 <= s <= level + m.climb_m_s * escape_s(m)


def test_heading_out_of_an_inclusion_zone_close_to_its_edge_is_replaced_heading_in_is_kept() -> (
    None
):
    box = PolygonZone(
        kind="polygon",
        vertices=[(-2000, -2000), (125, -2000), (125, 2000), (-2000, 2000)],
        inclusion=True,
    )
    m = plane(0.0, 0.0, 150.0, 0.0)  # its edge 125 m ahead
    [out] = assure([m], [Command(0.0, 150.0)], 1.0, keep(zones(box)))
    assert out.replaced
    assert out.reason == "zone"
    [back] = assure(
        [plane(0.0, 0.0, 150.0, math.pi)], [Command(math.pi, 150.0)], 1.0, keep(zones(box))
    )
    assert not back.replaced


def test_the_margin_is_the_zone_surfaces_least_distance_less_the_safe_distance() -> None:
    """Flying west, away from the square 125 m east of it: the hold's first instant is the
    nearest the vehicle comes (its escapes turn back on its own side), so the margin is
    the square's distance there less the safe distance."""
    z = zones(SQUARE)
    m = plane(0.0, 0.0, 150.0, math.pi)
    s, reason = score(m, Command(math.pi, 150.0), 1.0, keep(z), [])
    path, _ = hold_path(m, Command(math.pi, 150.0), 1.0)
    assert reason == "zone"
    assert float(zone_clearances(path, z).min()) == pytest.approx(125.0)
    assert s == pytest.approx(125.0 - SAFE, abs=1e-6)

"""The named scene families: those of the property tests and the explorer (docs/sweeps.md,
"where the method fails"), as specs.

* ``feasible``: the guarantees can hold: obstacle influence spheres at v_max do not overlap,
  starts and target lie outside them, vehicles start ≥ 300 m apart, obstacles static;
* ``dense``: 2–8 obstacles (100–700 m) whose influence spheres may overlap;
* ``moving``: feasible scenes whose obstacles move at up to 300 m/s;
* ``close``: vehicles start only 80 m apart, no obstacles;
* ``zones``: feasible scenes whose spheres are vertical cylinders and polygons, convex or
  not (``ZoneSpec``);
* ``pockets``: feasible scenes whose spheres are U-shaped polygons opening towards the
  leader's start (a concave pocket on the way).
"""

from __future__ import annotations

from gcs_ppf.offline.sweep.spec import Box, FleetSpec, ObstacleSpec, SceneSpec, ZoneSpec

FEASIBLE = SceneSpec(name="feasible")
DENSE = SceneSpec(
    name="dense",
    obstacles=ObstacleSpec(
        count=(2, 8),
        placement="overlapping",
        box=Box(center_m=(0.0, 0.0, 0.0), half_size_m=(3000.0, 1500.0, 300.0)),
        radius_m=(100.0, 700.0),
    ),
)
MOVING = SceneSpec(name="moving", obstacles=ObstacleSpec(speed_m_s=(0.0, 300.0)))
CLOSE = SceneSpec(
    name="close", fleet=FleetSpec(start_gap_m=80.0), obstacles=ObstacleSpec(count=(0, 0))
)

ZONES = SceneSpec(name="zones", zones=ZoneSpec())
POCKETS = SceneSpec(name="pockets", zones=ZoneSpec(shape="pocket"))

FAMILIES: dict[str, SceneSpec] = {
    f.name: f for f in (FEASIBLE, DENSE, MOVING, CLOSE, ZONES, POCKETS)
}

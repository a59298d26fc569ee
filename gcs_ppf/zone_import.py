"""Zones from the files operators have: GeoJSON and QGroundControl ``.plan`` (CONVENTIONS §3's
``zones``, kept in lat/lon: the mission converts them about its origin).

* **GeoJSON** (RFC 7946; a FeatureCollection, a Feature or a bare geometry): a ``Polygon``
  is a polygon zone (its outer ring; holes are refused), a ``MultiPolygon`` one zone per
  polygon, a ``Point`` with a ``radius`` property (m) a cylinder.  Properties: ``name``,
  ``floor`` and ``ceiling`` (ICS z, m; default: none, from the ground to the sky),
  ``inclusion`` (default false: a no-fly zone).  GeoJSON's positions are (lon, lat).
* **QGroundControl .plan** (``fileType`` "Plan"): its ``geoFence`` polygons and circles,
  inclusion or exclusion as the file says, with no height band (QGroundControl's fences
  have none; ArduPlane's FENCE_ALT_MAX is a separate limit).

Every error names the feature (``features[k]`` or ``geoFence.polygons[k]``) and the field;
an import either yields every zone of the file or raises: nothing is half imported.
"""

from __future__ import annotations

import json
from typing import Any

from geojson_pydantic import Feature, FeatureCollection, MultiPolygon, Point, Polygon
from pydantic import ValidationError

from gcs_ppf.mission import CylinderZone, PolygonZone

Zone = CylinderZone | PolygonZone


class ZoneImportError(ValueError):
    """A file whose zones cannot be read; the message names the feature and the field."""


def _first_error(exc: ValidationError) -> str:
    e = exc.errors()[0]
    where = ".".join(str(p) for p in e["loc"])
    msg = str(e["msg"]).removeprefix("Value error, ")
    return f"{where}: {msg}" if where else msg


def _zone(where: str, doc: dict[str, Any]) -> Zone:
    """One zone from its mission-document form, or the error that names ``where``."""
    try:
        if doc["kind"] == "cylinder":
            return CylinderZone.model_validate(doc)
        return PolygonZone.model_validate(doc)
    except ValidationError as exc:
        raise ZoneImportError(f"{where}: {_first_error(exc)}") from None


def _band(where: str, properties: dict[str, Any]) -> dict[str, Any]:
    """name, floor, ceiling and inclusion from a feature's properties."""
    band: dict[str, Any] = {}
    for key in ("floor", "ceiling"):
        value = properties.get(key)
        if value is not None:
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ZoneImportError(
                    f"{where}.properties.{key}: a number of metres, got {value!r}"
                )
            band[key] = float(value)
    inclusion = properties.get("inclusion", False)
    if not isinstance(inclusion, bool):
        raise ZoneImportError(f"{where}.properties.inclusion: true or false, got {inclusion!r}")
    band["inclusion"] = inclusion
    name = properties.get("name")
    if name is not None:
        band["name"] = str(name)
    return band


def _ring(where: str, polygon: Polygon) -> list[list[float]]:
    """A GeoJSON polygon's outer ring as (lat, lon) corners, not closed."""
    if len(polygon.coordinates) > 1:
        raise ZoneImportError(f"{where}.coordinates: holes are not supported (one ring only)")
    ring = [[p[1], p[0]] for p in polygon.coordinates[0]]
    return ring[:-1] if ring[0] == ring[-1] else ring


def _feature_zones(where: str, feature: Feature[Any, Any]) -> list[Zone]:
    geometry = feature.geometry
    band = _band(where, feature.properties or {})
    if isinstance(geometry, Polygon):
        ring = _ring(f"{where}.geometry", geometry)
        return [_zone(where, {"kind": "polygon", "vertices_latlon": ring, **band})]
    if isinstance(geometry, MultiPolygon):
        out = []
        for k, coords in enumerate(geometry.coordinates):
            part = Polygon(type="Polygon", coordinates=coords)
            ring = _ring(f"{where}.geometry.coordinates[{k}]", part)
            out.append(
                _zone(f"{where} polygon {k}", {"kind": "polygon", "vertices_latlon": ring, **band})
            )
        return out
    if isinstance(geometry, Point):
        radius = (feature.properties or {}).get("radius")
        if radius is None:
            raise ZoneImportError(f"{where}.properties.radius: a Point needs a radius (m)")
        centre = [geometry.coordinates[1], geometry.coordinates[0]]
        return [
            _zone(where, {"kind": "cylinder", "center_latlon": centre, "radius": radius, **band})
        ]
    kind = None if geometry is None else geometry.type
    raise ZoneImportError(
        f"{where}.geometry: {kind} is not a zone (Polygon, MultiPolygon, or Point with a radius)"
    )


def zones_from_geojson(doc: Any) -> list[Zone]:
    """The zones of a GeoJSON FeatureCollection, Feature or geometry (module docstring)."""
    if not isinstance(doc, dict):
        raise ZoneImportError("GeoJSON: an object expected")
    kind = doc.get("type")
    if kind in ("Polygon", "MultiPolygon", "Point"):
        doc = {"type": "Feature", "geometry": doc, "properties": {}}
        kind = "Feature"
    features: list[Feature[Any, Any]]
    try:
        if kind == "FeatureCollection":
            features = list(FeatureCollection.model_validate(doc).features)
        elif kind == "Feature":
            features = [Feature.model_validate(doc)]
        else:
            raise ZoneImportError(
                f"type: {kind!r} is not GeoJSON zones come from (FeatureCollection, Feature, "
                "Polygon, MultiPolygon, Point)"
            )
    except ValidationError as exc:
        raise ZoneImportError(f"GeoJSON {_first_error(exc)}") from None
    zones: list[Zone] = []
    for k, feature in enumerate(features):
        zones.extend(_feature_zones(f"features[{k}]", feature))
    return zones


def zones_from_plan(doc: Any) -> list[Zone]:
    """The ``geoFence`` polygons and circles of a QGroundControl ``.plan`` document."""
    if not isinstance(doc, dict) or doc.get("fileType") != "Plan":
        raise ZoneImportError('fileType: not a QGroundControl plan (fileType "Plan")')
    fence = doc.get("geoFence") or {}
    if not isinstance(fence, dict):
        raise ZoneImportError("geoFence: an object expected")
    zones: list[Zone] = []
    for k, item in enumerate(fence.get("polygons") or []):
        where = f"geoFence.polygons[{k}]"
        if not isinstance(item, dict) or not isinstance(item.get("polygon"), list):
            raise ZoneImportError(f"{where}.polygon: a list of [lat, lon] corners expected")
        inclusion = item.get("inclusion", True)
        doc = {"kind": "polygon", "vertices_latlon": item["polygon"], "inclusion": inclusion}
        zones.append(_zone(where, doc))
    for k, item in enumerate(fence.get("circles") or []):
        where = f"geoFence.circles[{k}]"
        circle = item.get("circle") if isinstance(item, dict) else None
        if not isinstance(circle, dict):
            raise ZoneImportError(f"{where}.circle: an object with center and radius expected")
        inclusion = item.get("inclusion", True)
        centre, radius = circle.get("center"), circle.get("radius")
        doc = {
            "kind": "cylinder",
            "center_latlon": centre,
            "radius": radius,
            "inclusion": inclusion,
        }
        zones.append(_zone(where, doc))
    return zones


def zones_from_mission_form(doc: dict[str, Any]) -> list[Zone]:
    """``{"zones": [...]}``: zones as the mission document writes them (CONVENTIONS §3, in
    ICS metres or lat/lon), as the operator's page sends one drawn on its map."""
    items = doc["zones"]
    if not isinstance(items, list):
        raise ZoneImportError("zones: a list of zones expected")
    out = []
    for k, item in enumerate(items):
        if not isinstance(item, dict) or item.get("kind") not in ("cylinder", "polygon"):
            raise ZoneImportError(f'zones[{k}].kind: "cylinder" or "polygon" expected')
        out.append(_zone(f"zones[{k}]", item))
    return out


def zones_from_document(doc: Any, required: bool = True) -> list[Zone]:
    """The zones of a parsed GeoJSON or QGroundControl ``.plan`` document (told apart by
    its ``fileType``), or of ``{"zones": [...]}`` in the mission document's own form: at
    least one when ``required``, or a ``ZoneImportError``."""
    if isinstance(doc, dict) and doc.get("fileType") == "Plan":
        zones = zones_from_plan(doc)
    elif isinstance(doc, dict) and "zones" in doc and "type" not in doc:
        zones = zones_from_mission_form(doc)
    else:
        zones = zones_from_geojson(doc)
    if not zones and required:
        raise ZoneImportError("no zones in it")
    return zones


def import_zones(text: str, source: str = "the file", required: bool = True) -> list[Zone]:
    """The zones of a GeoJSON or ``.plan`` text, or a ``ZoneImportError`` naming
    ``source``, the feature and the field."""
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ZoneImportError(
            f"{source} is not JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})"
        ) from None
    try:
        return zones_from_document(doc, required)
    except ZoneImportError as exc:
        raise ZoneImportError(f"{source}: {exc}") from None

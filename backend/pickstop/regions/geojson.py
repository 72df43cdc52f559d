"""Regions as GeoJSON: one Feature per (tray, yaw), polygons in world metres."""

from __future__ import annotations

from typing import Any

import shapely
from shapely.geometry import mapping, shape

from pickstop.regions.cells import TrayRegion


def region_feature(region: TrayRegion, name: str = "") -> dict[str, Any]:
    return {
        "type": "Feature",
        "geometry": mapping(region.polygon) if not region.polygon.is_empty else None,
        "properties": {
            "tray_id": region.tray_id,
            "name": name,
            "yaw": region.yaw,
            "area_m2": round(region.area, 6),
            "cells": len(region.cells),
            "resolution_m": region.grid.res,
            "counts": {k: int(v) for k, v in region.counts.items()},
            "reason": region.reason,
            "seconds": round(region.seconds, 4),
        },
    }


def regions_geojson(
    regions: list[TrayRegion], names: dict[str, str] | None = None
) -> dict[str, Any]:
    names = names or {}
    return {
        "type": "FeatureCollection",
        "features": [region_feature(r, names.get(r.tray_id, "")) for r in regions],
    }


def read_polygons(doc: dict[str, Any]) -> dict[tuple[str, float], shapely.Geometry]:
    """Polygons of a regions GeoJSON document keyed by (tray id, yaw)."""
    out = {}
    for f in doc["features"]:
        p = f["properties"]
        geom = shape(f["geometry"]) if f["geometry"] else shapely.Polygon()
        out[(p["tray_id"], p["yaw"])] = geom
    return out

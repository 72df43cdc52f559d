"""Region polygons as GeoJSON (regions/geojson.py)."""

from __future__ import annotations

import json

import pytest

from pickstop.regions.geojson import read_polygons, regions_geojson
from pickstop.scene.load import parse_scene


def test_region_polygon_matches_cells_and_geojson_round_trip(planner, paper_doc):
    scene = parse_scene(paper_doc)
    region = planner.tray_region(scene, "tray_1")
    assert region.polygon.area == pytest.approx(region.area, rel=1e-9)
    assert region.mask.sum() == len(region.cells)
    doc = json.loads(json.dumps(regions_geojson([region])))
    polys = read_polygons(doc)
    assert polys[("tray_1", region.yaw)].symmetric_difference(region.polygon).area < 1e-9
    props = doc["features"][0]["properties"]
    assert props["cells"] == len(region.cells) and props["area_m2"] == pytest.approx(region.area)

"""The guidance document -> meshes and legend: every zone's area is covered at the support's
height, kinds keep their own mesh, ``unknown`` zones are counted and not drawn."""

from __future__ import annotations

import numpy as np
import pytest
from shapely.geometry import Polygon, mapping

from pickstop_ui.guidance_view import KINDS, LIFT, guidance_drawing, legend


def _feature(kind, geom, trays=()):
    return {"type": "Feature", "geometry": mapping(geom),
            "properties": {"kind": kind, "support": "table_b", "trays": list(trays)}}  # fmt: skip


def _doc():
    holed = Polygon([(3.4, 1.4), (3.8, 1.4), (3.8, 1.6), (3.4, 1.6)],
                    [[(3.5, 1.45), (3.6, 1.45), (3.6, 1.55), (3.5, 1.55)]])  # fmt: skip
    return {
        "type": "FeatureCollection",
        "properties": {
            "tray": "tray_4",
            "sigma": 0.05,
            "groups": [["tray_3", "tray_4"]],
            "here": "shares",
            "seconds": 0.1,
        },
        "features": [
            _feature("shares", holed, ["tray_3"]),
            _feature("own", Polygon([(3.0, 1.0), (3.2, 1.0), (3.2, 1.1)])),
            _feature("unknown", Polygon([(0, 0), (1, 0), (1, 1)])),
        ],
    }


def _area(v, f):
    a, b, c = (v[f[:, k]][:, :2].astype(float) for k in range(3))
    (ux, uy), (wx, wy) = (b - a).T, (c - a).T
    return float(np.sum(np.abs(ux * wy - uy * wx)) / 2)


def test_each_kind_is_one_mesh_covering_its_zones_at_the_support_height():
    d = guidance_drawing(_doc(), 0.75)
    assert set(d.meshes) == set(KINDS) and d.tray == "tray_4" and d.here == "shares"
    v, f = d.meshes["shares"]
    assert _area(v, f) == pytest.approx(0.4 * 0.2 - 0.1 * 0.1, abs=1e-6)  # the hole stays open
    assert np.allclose(v[:, 2], 0.75 + LIFT)
    assert _area(*d.meshes["own"]) == pytest.approx(0.01, abs=1e-6)
    assert len(d.meshes["unreachable"][1]) == 0
    assert d.unknown == 1


def test_multipolygons_and_empty_geometries():
    doc = _doc()
    doc["features"] = [
        {"type": "Feature", "properties": {"kind": "unreachable"},
         "geometry": {"type": "MultiPolygon", "coordinates": [
             [[[0, 0], [1, 0], [1, 1], [0, 0]]], [[[2, 0], [3, 0], [3, 1], [2, 0]]]]}},
        {"type": "Feature", "properties": {"kind": "own"},
         "geometry": {"type": "GeometryCollection", "geometries": []}},
    ]  # fmt: skip
    d = guidance_drawing(doc, 0.0)
    assert _area(*d.meshes["unreachable"]) == pytest.approx(1.0)
    assert len(d.meshes["own"][1]) == 0


def test_legend_names_the_colours_partners_and_where_the_tray_stands():
    text = legend(_doc())
    assert "Guidance for tray_4" in text and "tray_3" in text
    for word in ("shares a stop", "own", "cannot be reached", "now: *shares*", "1 zone(s)"):
        assert word in text

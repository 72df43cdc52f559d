"""Floor drawings: region patches cover their polygons exactly, holes left open."""

from __future__ import annotations

import numpy as np
from shapely.geometry import Point, Polygon

from pickstop_ui.geometry import patch_mesh


def test_a_patch_covers_its_polygons_and_leaves_their_holes():
    ring = Point(0, 0).buffer(1.0, 64).difference(Point(0.2, 0).buffer(0.3, 16))
    polys = [ring, Point(3, 0).buffer(0.5, 32), Polygon()]
    v, f = patch_mesh(polys, 0.01)
    assert v.dtype == np.float32 and f.dtype == np.uint32 and f.shape[1] == 3
    assert np.all(v[:, 2] == np.float32(0.01)) and f.max() == len(v) - 1
    a, b, c = v[f[:, 0], :2], v[f[:, 1], :2], v[f[:, 2], :2]
    area = 0.5 * np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    assert np.isclose(area.sum(), sum(p.area for p in polys), rtol=1e-5)
    centroids = (a + b + c) / 3
    assert not any(Point(x, y).distance(Point(0.2, 0)) < 0.29 for x, y in centroids)  # the hole


def test_nothing_to_cover():
    v, f = patch_mesh([Polygon()], 0.0)
    assert v.shape == (0, 3) and f.shape == (0, 3)

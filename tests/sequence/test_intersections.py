"""Intersections and inscribed circles on hand-made polygons with known answers."""

from __future__ import annotations

import math

import pytest
import shapely
from shapely.geometry import Polygon, box

from pickstop.sequence.intersections import (
    inscribed_circle,
    intersections,
    polygon_parts,
)


def _by_trays(cands):
    out = {}
    for c in cands:
        out.setdefault(tuple(sorted(c.trays)), []).append(c)
    return out


def test_square_inscribed_circle():
    (cx, cy), r = inscribed_circle(box(0, 0, 2, 1))
    assert r == pytest.approx(0.5, abs=2e-3)
    assert cy == pytest.approx(0.5, abs=2e-3) and 0.5 <= cx <= 1.5


def test_hole_pushes_the_centre_away():
    ring = box(0, 0, 4, 4).difference(box(1, 1, 3, 3))  # a 1 m wide frame
    (cx, cy), r = inscribed_circle(ring)
    # In a corner the circle touches both outer walls and the hole's corner: r = 2 - sqrt(2).
    assert r == pytest.approx(2 - math.sqrt(2), abs=2e-3)
    assert not box(1, 1, 3, 3).contains(shapely.Point(cx, cy))


def test_three_overlapping_squares_known_orders():
    regions = {"a": box(0, 0, 2, 2), "b": box(1, 0, 3, 2), "c": box(1.5, 0, 4, 2)}
    got = _by_trays(intersections(regions))
    assert set(got) == {("a",), ("b",), ("c",), ("a", "b"), ("a", "c"), ("b", "c"), ("a", "b", "c")}
    abc = got[("a", "b", "c")][0]
    assert abc.polygon.area == pytest.approx(1.0)  # x in [1.5, 2]
    assert abc.radius == pytest.approx(0.25, abs=2e-3)
    assert abc.centre[0] == pytest.approx(1.75, abs=2e-3)
    assert got[("a", "b")][0].radius == pytest.approx(0.5, abs=2e-3)


def test_components_are_separate_candidates():
    a = box(0, 0, 5, 1)
    b = shapely.union_all([box(0, 0, 1, 1), box(4, 0, 5, 1)])  # two islands
    got = _by_trays(intersections({"a": a, "b": b}))
    assert len(got[("a", "b")]) == 2
    assert len(got[("b",)]) == 2


def test_touching_regions_leave_no_candidate():
    # Sharing only an edge or a corner: lines and points are not places to stop.
    got = _by_trays(
        intersections({"a": box(0, 0, 1, 1), "b": box(1, 0, 2, 1), "c": box(2, 1, 3, 2)})
    )
    assert ("a", "b") not in got and ("b", "c") not in got


def test_empty_and_degenerate_inputs():
    assert intersections({}) == []
    assert intersections({"a": Polygon()}) == []
    line_and_square = shapely.GeometryCollection(
        [shapely.LineString([(0, 0), (5, 5)]), box(0, 0, 1, 1)]
    )
    assert len(polygon_parts(line_and_square)) == 1
    got = intersections({"a": line_and_square, "b": box(0.5, 0, 2, 1)})
    assert {tuple(sorted(c.trays)) for c in got} == {("a",), ("b",), ("a", "b")}


def test_many_trays_only_nonempty_subsets_explored():
    # 12 disjoint pairs: 24 regions, 12 second-order intersections, nothing higher.
    regions = {}
    for i in range(12):
        regions[f"t{i}a"] = box(10 * i, 0, 10 * i + 2, 2)
        regions[f"t{i}b"] = box(10 * i + 1, 0, 10 * i + 3, 2)
    cands = intersections(regions)
    assert max(c.order for c in cands) == 2
    assert len(cands) == 24 + 12
    assert all(math.isfinite(c.radius) for c in cands)

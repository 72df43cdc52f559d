"""Floor routing: shortest paths around inflated obstacles, never through them."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import Point, box

from pickstop.sequence.route import FloorMap, polyline_clear, shortest_paths


def test_straight_line_when_nothing_is_in_the_way():
    fmap = FloorMap.build((0, 0, 10, 10), [], 0.3)
    p = shortest_paths(fmap, np.array([[1, 1], [9, 1]]))
    assert p.dist[0, 1] == pytest.approx(8.0)
    assert len(p.polyline(0, 1)) == 2


def test_detour_around_a_wall_is_near_the_analytic_length():
    # A wall from y = 0 to 6 at x = 5 (0.2 thick); radius 0.3: go round its top end.
    fmap = FloorMap.build((0, 0, 10, 10), [box(4.9, 0, 5.1, 6)], 0.3)
    a, b = np.array([2.0, 1.0]), np.array([8.0, 1.0])
    p = shortest_paths(fmap, np.array([a, b]))
    top = np.array([5.0, 6.0])
    r = 0.3 + 0.1  # clearance from the wall's centre line at its end
    lower = np.linalg.norm(a - top) + np.linalg.norm(top - b)
    assert lower < p.dist[0, 1] < lower + 2 * r + 0.3
    line = p.polyline(0, 1)
    assert polyline_clear(fmap, line)
    assert line[:, 1].max() > 6.0


def test_unreachable_point_is_infinite():
    # The right half is closed off by a wall across the whole floor.
    fmap = FloorMap.build((0, 0, 10, 10), [box(4.9, -1, 5.1, 11)], 0.3)
    p = shortest_paths(fmap, np.array([[2, 5], [8, 5]]))
    assert math.isinf(p.dist[0, 1])
    assert not fmap.is_free((5.0, 5.0)) and fmap.is_free((2.0, 5.0))


@settings(max_examples=25, deadline=None)
@given(
    boxes=st.lists(
        st.tuples(st.floats(1, 8), st.floats(1, 8), st.floats(0.1, 1.5), st.floats(0.1, 1.5)),
        min_size=1,
        max_size=5,
    ),
    seed=st.integers(0, 1000),
)
def test_paths_never_cross_inflated_obstacles(boxes, seed):
    obstacles = [box(x, y, x + w, y + h) for x, y, w, h in boxes]
    radius = 0.25
    fmap = FloorMap.build((0, 0, 10, 10), obstacles, radius)
    rng = np.random.default_rng(seed)
    pts = rng.uniform(0.3, 9.7, (30, 2))
    pts = np.array([q for q in pts if fmap.is_free(tuple(q))])[:6]
    if len(pts) < 2:
        return
    p = shortest_paths(fmap, pts)
    for i, j in itertools.combinations(range(len(pts)), 2):
        if math.isinf(p.dist[i, j]):
            continue
        line = p.polyline(i, j)
        assert polyline_clear(fmap, line)
        # Every waypoint and the whole line keep the footprint off every real obstacle.
        from shapely.geometry import LineString

        for o in obstacles:
            assert LineString(line).distance(o) >= radius - 1e-3
        assert p.dist[i, j] >= np.linalg.norm(pts[i] - pts[j]) - 1e-9
        assert Point(line[0]).distance(Point(pts[i])) < 1e-9

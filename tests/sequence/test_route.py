"""Floor routing: shortest paths around inflated obstacles, never through them; docking legs
at a fixed yaw where the bounding circle does not fit, checked against the real outline."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import Point, box

from pickstop.regions.footprint import BodyPieces, FloorSolids, sweep_blocked
from pickstop.sequence.route import Docking, FloorMap, polyline_clear, shortest_paths

# Up to five boxes (x, y, width, depth) [m] on a 10 m floor.
BOXES = st.lists(
    st.tuples(st.floats(1, 8), st.floats(1, 8), st.floats(0.1, 1.5), st.floats(0.1, 1.5)),
    min_size=1,
    max_size=5,
)


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
@given(boxes=BOXES, seed=st.integers(0, 1000))
def test_distances_are_those_of_the_whole_visibility_graph(boxes, seed):
    # Reference: every leg between points and corners tested anew, Floyd-Warshall over them.
    fmap = FloorMap.build((0, 0, 10, 10), [box(x, y, x + w, y + h) for x, y, w, h in boxes], 0.25)
    rng = np.random.default_rng(seed)
    pts = rng.uniform(0.3, 9.7, (8, 2))
    pts = np.concatenate([pts, pts[:1], fmap.corners[:1]])  # a point twice, one on a corner
    nodes = np.concatenate([pts, fmap.corners])
    n = len(nodes)
    i, j = np.triu_indices(n, 1)
    ok = fmap.leg_ok(nodes[i], nodes[j])
    d = np.full((n, n), np.inf)
    np.fill_diagonal(d, 0.0)
    d[i[ok], j[ok]] = d[j[ok], i[ok]] = np.linalg.norm(nodes[i[ok]] - nodes[j[ok]], axis=1)
    for k in range(n):
        d = np.minimum(d, d[:, k : k + 1] + d[k : k + 1, :])
    p = shortest_paths(fmap, pts)
    Q = len(pts)
    assert np.array_equal(np.isinf(p.dist), np.isinf(d[:Q, :Q]))
    fin = np.isfinite(p.dist)
    assert np.allclose(p.dist[fin], d[:Q, :Q][fin], atol=1e-9)
    for a, b in itertools.combinations(range(Q), 2):
        if fin[a, b]:
            line = p.polyline(a, b)
            assert np.allclose(line[[0, -1]], pts[[a, b]])
            assert np.linalg.norm(np.diff(line, axis=0), axis=1).sum() == pytest.approx(
                p.dist[a, b]
            )


@settings(max_examples=25, deadline=None)
@given(boxes=BOXES, seed=st.integers(0, 1000))
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


# -- docking: a long base whose stop is closer to a table than its bounding radius ---------------

FLOOR = (0.0, 0.0, 6.0, 6.0)


def _body(outline, height=0.35):
    return BodyPieces((np.asarray(outline, float),), np.array([-np.inf]), np.array([height]))


def _rect(length, width):
    hx, hy = length / 2, width / 2
    return np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]])


def _world(obstacles, heights=None):
    heights = heights or [(0.0, 0.72)] * len(obstacles)
    return FloorSolids(
        list(obstacles),
        [f"ob{k}" for k in range(len(obstacles))],
        np.array([h[0] for h in heights]).reshape(-1),
        np.array([h[1] for h in heights]).reshape(-1),
        box(*FLOOR),
    )


def _setup(outline, obstacles, omni=True):
    body, world = _body(outline), _world(obstacles)
    radius = float(np.hypot(*np.asarray(outline).T).max())
    fmap = FloorMap.build(FLOOR, list(obstacles), radius)
    docking = Docking(lambda a, b, yaw: sweep_blocked(body, world, a, b, yaw), 3 * radius, omni)
    return fmap, docking, radius


def assert_path_clear(line, held, outline, radius, obstacles, end_yaw=None, step=0.005):
    """Exact check of a path: along a segment held at a yaw, the footprint polygon at that yaw
    sampled every ``step`` [m] (for a convex one also its sweep between samples, the hull of
    two); along a free segment and at every turn, the full bounding circle (the segment's
    distance to the obstacles); nothing meets an obstacle and everything stays on the floor."""
    from shapely.geometry import Polygon

    line = np.asarray(line, float)
    floor, union = box(*FLOOR).buffer(1e-6), shapely.union_all(obstacles)
    outline = np.asarray(outline, float)
    convex = Polygon(outline).equals(Polygon(outline).convex_hull)
    for k in range(len(line) - 1):
        a, b = line[k], line[k + 1]
        n = max(2, int(np.ceil(np.linalg.norm(b - a) / step)) + 1)
        pts = a + np.linspace(0, 1, n)[:, None] * (b - a)
        if held[k] is None:  # the whole circle swept along it (exact: the segment's distance)
            seg = shapely.LineString([a, b])
            assert seg.distance(union) > radius - 1e-4, (k, "circle meets an obstacle")
            inner = box(*FLOOR).buffer(-radius + 1e-4, join_style="mitre")
            assert inner.covers(seg), (k, "circle leaves the floor")
            continue
        c, s_ = math.cos(held[k]), math.sin(held[k])
        rot = outline @ np.array([[c, -s_], [s_, c]]).T
        placed = pts[:, None, :] + rot[None]
        shapes = list(shapely.polygons(placed))
        if convex:
            pairs = np.concatenate([placed[:-1], placed[1:]], axis=1)
            shapes += list(shapely.convex_hull(shapely.multipoints(pairs)))
        shapes = np.array(shapes)
        assert shapely.covers(floor, shapes).all(), (k, "leaves the floor")
        assert not shapely.intersects(shapes, union).any(), (k, held[k])
    if end_yaw is not None:
        c, s_ = math.cos(end_yaw), math.sin(end_yaw)
        end = Polygon(outline @ np.array([[c, -s_], [s_, c]]).T + line[-1])
        assert floor.covers(end) and not end.intersects(union)


def test_a_long_base_docks_closer_to_a_table_than_its_bounding_radius():
    outline = _rect(0.9, 0.3)  # bounding radius 0.474 m
    table = box(2.0, 2.0, 4.0, 2.6)
    fmap, docking, radius = _setup(outline, [table])
    stop = np.array([3.0, 2.0 - 0.2])  # 0.2 m off the table's edge, long side along it
    pts = np.array([[1.0, 0.5], [5.0, 0.5], stop])
    yaws = np.array([np.nan, np.nan, 0.0])
    assert not fmap.is_free(tuple(stop))
    # The bounding circle alone never gets there.
    assert math.isinf(shortest_paths(fmap, pts).dist[0, 2])
    p = shortest_paths(fmap, pts, yaws, docking)
    assert np.isfinite(p.dist[0, 2]) and np.isfinite(p.dist[2, 1]) and not p.undocked
    for i, j in [(0, 2), (2, 1)]:
        line, held = p.polyline(i, j), p.segment_yaws(i, j)
        assert any(h == 0.0 for h in held)
        assert_path_clear(line, held, outline, radius, [table], 0.0 if j == 2 else None)
    # One straight leg out to a staging point where the base may turn, then free travel.
    back, held = p.polyline(2, 1), p.segment_yaws(2, 1)
    assert held[0] == 0.0 and all(h is None for h in held[1:])
    assert fmap.is_free(tuple(back[1])) and np.linalg.norm(back[1] - stop) <= docking.reach
    assert p.dist[0, 2] >= np.linalg.norm(stop - pts[0])


def test_docked_stops_of_one_yaw_slide_along_the_table():
    outline = _rect(0.9, 0.3)
    table = box(2.0, 2.0, 4.0, 2.6)
    fmap, docking, radius = _setup(outline, [table])
    pts = np.array([[1.0, 0.5], [5.0, 0.5], [2.6, 1.8], [3.4, 1.8]])
    p = shortest_paths(fmap, pts, np.array([np.nan, np.nan, 0.0, 0.0]), docking)
    assert p.dist[2, 3] == pytest.approx(0.8)
    assert p.segment_yaws(2, 3) == [0.0]
    # Across yaws no slide: the half turn (same outline, other heading) needs the circle-free
    # floor, out and back in.
    p2 = shortest_paths(fmap, pts, np.array([np.nan, np.nan, 0.0, math.pi]), docking)
    held = p2.segment_yaws(2, 3)
    assert p2.dist[2, 3] > 0.8 + 0.2 and held[0] == 0.0 and held[-1] == math.pi
    assert None in held
    assert_path_clear(p2.polyline(2, 3), p2.segment_yaws(2, 3), outline, radius, [table])


def test_a_pose_that_cannot_dock_says_why():
    outline = _rect(0.9, 0.3)
    table = box(2.0, 2.0, 4.0, 2.6)
    # A pocket under the table whose mouth (0.25 m) is narrower than the base (0.3 m).
    walls = [box(2.4, 1.2, 2.5, 2.0), box(3.5, 1.2, 3.6, 2.0), box(2.4, 1.1, 2.9, 1.2),
             box(3.15, 1.1, 3.6, 1.2)]  # fmt: skip
    fmap, docking, _ = _setup(outline, [table, *walls])
    pts = np.array([[1.0, 0.5], [5.0, 0.5], [3.0, 1.8], [3.0, 1.95]])
    p = shortest_paths(fmap, pts, np.array([np.nan, np.nan, 0.0, 0.0]), docking)
    assert math.isinf(p.dist[0, 2]) and "every straight leg" in p.undocked[2]
    assert "ob0" in p.undocked[3] and "does not fit" in p.undocked[3]  # overlaps the table
    assert 0 not in p.undocked and 1 not in p.undocked


@settings(max_examples=20, deadline=None)
@given(
    boxes=st.lists(
        st.tuples(st.floats(0.5, 5), st.floats(0.5, 5), st.floats(0.2, 1.5), st.floats(0.2, 1.5)),
        min_size=1,
        max_size=4,
    ),
    shape=st.sampled_from(["rect", "ell"]),
    yaw=st.floats(-math.pi, math.pi),
    seed=st.integers(0, 1000),
)
def test_every_docked_path_is_clear_for_the_real_outline(boxes, shape, yaw, seed):
    """Random tables and a long (convex) or L-shaped (concave) base: points where the outline
    fits at its yaw but the bounding circle does not; every path found passes the exact
    sampled check."""
    from shapely import affinity
    from shapely.geometry import Polygon

    ell = [[0.45, 0.2], [-0.45, 0.2], [-0.45, -0.2], [0.0, -0.2], [0.0, 0.0], [0.45, 0.0]]
    outline = _rect(0.9, 0.35) if shape == "rect" else np.array(ell)
    obstacles = [box(x, y, x + w, y + h) for x, y, w, h in boxes]
    body, world = _body(outline), _world(obstacles)
    radius = float(np.hypot(*outline.T).max())
    fmap = FloorMap.build(FLOOR, obstacles, radius)
    if shape == "ell":  # concave: swept as its triangles, as body_pieces does
        tris = shapely.constrained_delaunay_triangles(Polygon(outline))
        body = BodyPieces(
            tuple(np.asarray(t.exterior.coords[:-1]) for t in tris.geoms),
            np.full(len(tris.geoms), -np.inf),
            np.full(len(tris.geoms), 0.35),
        )
    docking = Docking(lambda a, b, y: sweep_blocked(body, world, a, b, y), 3 * radius, True)
    rng = np.random.default_rng(seed)
    rot = affinity.rotate(Polygon(outline), yaw, origin=(0, 0), use_radians=True)
    floor, union = box(*FLOOR), shapely.union_all(obstacles)
    docked = []
    for q in rng.uniform(0.3, 5.7, (400, 2)):
        placed = affinity.translate(rot, *q)
        if not fmap.is_free(tuple(q)) and floor.covers(placed) and not placed.intersects(union):
            docked.append(q)
        if len(docked) == 3:
            break
    free = [q for q in rng.uniform(0.5, 5.5, (200, 2)) if fmap.is_free(tuple(q))][:2]
    if not docked or not free:
        return
    pts = np.array([*free, *docked])
    yaws = np.array([np.nan] * len(free) + [yaw] * len(docked))
    p = shortest_paths(fmap, pts, yaws, docking)
    for i, j in itertools.permutations(range(len(pts)), 2):
        if math.isinf(p.dist[i, j]):
            continue
        line, held = p.polyline(i, j), p.segment_yaws(i, j)
        end = yaw if j >= len(free) else None
        assert_path_clear(line, held, outline, radius, obstacles, end)
        if i < len(free) <= j:
            assert held[-1] is not None and held[-1] == pytest.approx(yaw)


def test_a_differential_base_docks_only_along_its_heading():
    """Beside a table, long side along it: a differential base backs out or drives on along
    its heading, never sideways; where neither way reaches floor it may turn on, it says so."""
    outline = _rect(0.9, 0.3)
    table = box(2.0, 2.0, 4.0, 2.6)
    fmap, docking, radius = _setup(outline, [table], omni=False)
    stop = np.array([3.5, 1.8])
    pts = np.array([[1.0, 0.5], [5.0, 0.5], stop])
    yaws = np.array([np.nan, np.nan, 0.0])
    p = shortest_paths(fmap, pts, yaws, docking)
    assert np.isfinite(p.dist[0, 2]) and not p.undocked
    for i, j in [(0, 2), (2, 1)]:
        line, held = p.polyline(i, j), p.segment_yaws(i, j)
        assert any(h is not None for h in held)
        for k, h in enumerate(held):
            if h is not None:  # straight along the heading: no sideways component
                d = line[k + 1] - line[k]
                assert abs(math.cos(h) * d[1] - math.sin(h) * d[0]) < 1e-6, (k, d)
        assert_path_clear(line, held, outline, radius, [table])
    # A wall ahead and the table's far end too far behind: no straight way out.
    wall = box(4.1, 1.0, 4.6, 2.6)
    fmap, docking, radius = _setup(outline, [table, wall], omni=False)
    p = shortest_paths(fmap, pts, yaws, docking)
    assert math.isinf(p.dist[0, 2])
    assert "along its heading" in p.undocked[2], p.undocked
    # The same stop with an omnidirectional base slides out sideways.
    fmap, docking, radius = _setup(outline, [table, wall], omni=True)
    assert np.isfinite(shortest_paths(fmap, pts, yaws, docking).dist[0, 2])


def test_route_joins_start_stops_goal_and_times_add_up(paper_plan):
    scene, plan = paper_plan
    assert plan.route[0] == pytest.approx((scene.start.x, scene.start.y))
    assert plan.route[-1] == pytest.approx((scene.goal.x, scene.goal.y))
    assert [leg.start for leg in plan.legs] == [
        "start",
        *(f"stop {k}" for k in range(len(plan.stops))),
    ]
    for leg, s in zip(plan.legs, plan.stops, strict=False):
        assert leg.polyline[-1] == pytest.approx((s.x, s.y))
    length = sum(math.dist(a, b) for a, b in zip(plan.route, plan.route[1:], strict=False))
    assert length == pytest.approx(plan.totals.route_length, rel=1e-9)
    t = plan.totals.time
    m = scene.motion
    n_parts = sum(len(scene.tray(x).parts) for x in scene.task_trays)
    assert t.stops == pytest.approx(len(plan.stops) * m.stop_time)
    assert t.picks == pytest.approx(n_parts * m.pick_time)
    assert t.total == pytest.approx(t.travel + t.stops + t.picks)
    assert plan.naive.saving_time == pytest.approx(plan.naive.time.total - t.total)
    assert plan.naive.saving_stops == len(plan.naive.stops) - len(plan.stops)

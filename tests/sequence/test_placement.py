"""Stops placed for success: the search against the estimate computed from scratch at every
point, and plans that place their stops (verified there, never worse than the centre)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from pickstop.regions.cells import CellGrid
from pickstop.scene.load import parse_scene
from pickstop.sequence.estimate import Q, estimate, feasible_subcells, kernel
from pickstop.sequence.intersections import inscribed_circle, polygon_parts
from pickstop.sequence.placement import MIN_GAIN, best_point, clearance
from pickstop.sequence.plan_model import PlanOptions
from pickstop.speedups.stop_planner import StopPlanner
from tests.utils import assert_stop_verified, discs, region_of

GRID = CellGrid(0.0, 0.0, 0.025, 48, 48)  # 1.2 m x 1.2 m
EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"


def _from_scratch(regions, kind, sigma, xy, dist=None):
    k = kernel(kind, sigma, GRID, xy, dist)
    return estimate(k, [feasible_subcells(r, k) for r in regions])


@settings(max_examples=25, deadline=None, derandomize=True)
@given(
    centres=st.lists(st.tuples(st.floats(0.4, 0.8), st.floats(0.4, 0.8)), min_size=1, max_size=3),
    radii=st.lists(st.floats(0.08, 0.3), min_size=3, max_size=3),
    other=st.tuples(st.floats(0.4, 0.8), st.floats(0.4, 0.8), st.floats(0.15, 0.4)),
    sigma=st.floats(0.02, 0.12),
    kind=st.sampled_from(["gaussian", "bounded"]),
)
def test_the_best_point_is_the_best_sub_cell_centre_by_the_estimate_from_scratch(
    centres, radii, other, sigma, kind
):
    """Two generated regions (a union of discs, and a disc): the search's score at its point
    equals the estimate computed there from scratch, and no sub-cell centre inside the
    intersection scores higher from scratch."""
    a = region_of(discs(centres, radii[: len(centres)]), GRID, "a")
    b = region_of(discs([other[:2]], [other[2]]), GRID, "b")
    parts = polygon_parts(a.polygon.intersection(b.polygon))
    if not parts:
        return
    poly = max(parts, key=lambda p: p.area)
    centre, _ = inscribed_circle(poly)
    found = best_point([a, b], poly, centre, lambda xy: kernel(kind, sigma, GRID, xy))
    assert found is not None
    xy, score = found
    assert shapely.contains_xy(poly, *xy)
    assert score == pytest.approx(_from_scratch([a, b], kind, sigma, xy), abs=1e-9)
    h = GRID.res / Q
    xs = GRID.x0 + (np.arange(GRID.nx * Q) + 0.5) * h
    X, Y = np.meshgrid(xs, xs)
    inside = shapely.contains_xy(poly, X, Y)
    pts = zip(X[inside], Y[inside], strict=True)
    every = [_from_scratch([a, b], kind, sigma, (x, y)) for x, y in pts]
    assert score >= max(every) - 1e-9


def test_a_long_intersection_under_a_biased_error_places_the_stop_against_the_bias():
    """A corridor 0.2 m across (x) and 0.6 m long, and an error that lands 5 cm off in +x on
    average: the best point sits about 5 cm in -x of the circle's centre, and succeeds more
    there."""
    from pickstop.scene.positioning import ErrorDist

    region = region_of(lambda p: (np.abs(p[:, 0] - 0.6) <= 0.1) & (np.abs(p[:, 1] - 0.6) <= 0.3),
                       GRID)  # fmt: skip
    dist = ErrorDist(kind="gaussian", sigma=0.05, mean=(0.05, 0.0), frame="map")
    centre, _ = inscribed_circle(region.polygon)
    xy, _ = best_point([region], region.polygon, centre,
                       lambda p: kernel("gaussian", 0.05, GRID, p, dist))  # fmt: skip
    assert xy[0] == pytest.approx(0.6 - 0.05, abs=0.013)
    assert (
        _from_scratch([region], "gaussian", 0.05, xy, dist)
        > _from_scratch([region], "gaussian", 0.05, centre, dist) + 0.05
    )


def test_clearance_is_the_distance_to_the_boundary_inside_and_zero_outside():
    square = shapely.box(0.0, 0.0, 1.0, 2.0)
    assert clearance(square, (0.5, 1.0)) == pytest.approx(0.5)
    assert clearance(square, (0.2, 1.9)) == pytest.approx(0.1)
    assert clearance(square, (1.5, 1.0)) == 0.0


@pytest.fixture(scope="module")
def stop_planner(planner):
    return StopPlanner(planner)


def test_placed_stops_are_verified_where_they_stand_and_never_worse_than_the_centre(
    stop_planner, planner
):
    """The rack cell, placed for success: each stop moved off its circle's centre lies in its
    intersection with its clearance, passes the exact check where it stands, reports the
    centre and both rates, and its estimate beats the centre's; the candidates keep their
    circles; placement 'centre' plans exactly today's stops."""
    scene = parse_scene(json.loads((EXAMPLES / "rack_cell.json").read_text()))
    plain = stop_planner.plan(scene, PlanOptions(samples=200))
    placed = stop_planner.plan(scene, PlanOptions(samples=200, placement="success"))
    assert placed.parameters.placement == "success"
    assert all(s.circle_centre is None and s.clearance == s.inscribed_radius for s in plain.stops)
    moved = [s for s in placed.stops if s.circle_centre is not None]
    assert moved, "nothing placed off its circle's centre in the rack cell"
    for s in placed.stops:
        cand = placed.candidates[s.candidate]
        poly = shapely.Polygon(cand.polygon[0], cand.polygon[1:])
        assert_stop_verified(planner, scene, s)
        if s.circle_centre is None:
            assert (s.x, s.y) == pytest.approx((cand.x, cand.y))
            continue
        assert s.circle_centre == pytest.approx((cand.x, cand.y))
        assert poly.buffer(1e-6).contains(shapely.Point(s.x, s.y))
        assert 0 < s.clearance <= s.inscribed_radius + 1e-9
        assert s.clearance == pytest.approx(poly.boundary.distance(shapely.Point(s.x, s.y)),
                                            abs=2e-4)  # fmt: skip
        assert s.estimated_success >= s.circle_estimated_success + MIN_GAIN - 1e-12
        assert s.success is not None and s.circle_success is not None
        assert s.circle_success.samples == s.success.samples == 200
    # The centre placement's stops are the circles' own, as they always were.
    for s in plain.stops:
        c = plain.candidates[s.candidate]
        assert (s.x, s.y) == (c.x, c.y)


def test_a_placed_point_that_fails_the_exact_check_goes_back_to_the_circle(
    stop_planner, monkeypatch
):
    """Were every placed point to fail its exact check, the plan stops at the circles'
    centres: the same stops as placement 'centre'."""
    scene = parse_scene(json.loads((EXAMPLES / "rack_cell.json").read_text()))
    plain = stop_planner.plan(scene, PlanOptions(samples=0))
    placed = stop_planner.plan(scene, PlanOptions(samples=0, placement="success"))
    circles = {(c.x, c.y) for c in placed.candidates}
    real = stop_planner.witnesses

    def only_at_circles(scene_, region, xy, world=None):
        if not any(math.dist(xy, c) < 1e-9 for c in circles):
            return None
        return real(scene_, region, xy, world)

    monkeypatch.setattr(stop_planner, "witnesses", only_at_circles)
    back = stop_planner.plan(scene, PlanOptions(samples=0, placement="success", seed=1))
    assert [(s.x, s.y, s.trays) for s in back.stops] == [(s.x, s.y, s.trays) for s in plain.stops]
    assert all(s.circle_centre is None for s in back.stops)


def test_a_placed_stop_tells_the_fleet_its_clearance_not_the_circles_radius(stop_planner):
    """The fleet's radius around a placed stop is the circle centred there (its clearance):
    the inscribed circle's radius around a point off its centre would reach outside."""
    from pickstop.fleet.route import guaranteed_radius, waypoints

    scene = parse_scene(json.loads((EXAMPLES / "rack_cell.json").read_text()))
    plan = stop_planner.plan(scene, PlanOptions(samples=0, placement="success"))
    moved = [s for s in plan.stops if s.circle_centre is not None]
    assert moved
    for s in moved:
        assert guaranteed_radius(s) == s.clearance < s.inscribed_radius
    at = {w.stop: w.tolerance_xy for w in waypoints(plan) if w.stop is not None}
    assert all(at[s.index] == guaranteed_radius(s) for s in plan.stops)

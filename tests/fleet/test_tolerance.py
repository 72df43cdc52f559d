"""Tolerance shapes against a known feasible set: what is exported lies inside it."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from pickstop.fleet.tolerance import (
    BOUNDARY_MAX,
    INTERIOR_MAX,
    ROUNDS,
    Ellipse,
    largest_inscribed,
    stop_shapes,
)

RES = 0.025


def _test_of(feasible):
    """The 'exact test' of a feasible set: a point passes when it lies in ``feasible``."""
    calls = []

    def test(tray, xy, yaw):
        calls.append(len(xy))
        return shapely.contains_xy(feasible, xy[:, 0], xy[:, 1])

    return test, calls


def _inside(e: Ellipse, n: int, rng, rim: float = 0.0) -> np.ndarray:
    """``n`` offsets uniform in ``e`` (``rim`` > 0: in its outer ring, ``rim`` wide)."""
    r = np.sqrt(rng.uniform((1 - rim) ** 2, 1, n))
    t = rng.random(n) * 2 * math.pi
    u, v = e.a * r * np.cos(t), e.b * r * np.sin(t)
    c, s = math.cos(e.theta), math.sin(e.theta)
    return np.stack([c * u - s * v, s * u + c * v], -1)


@settings(max_examples=25, deadline=None)
@given(
    w=st.floats(0.15, 0.6),
    h=st.floats(0.06, 0.3),
    turn=st.floats(-math.pi, math.pi),
    bite=st.floats(0.0, 0.5),
    seed=st.integers(0, 2**16),
)
def test_points_inside_the_exported_shapes_pass_the_test(w, h, turn, bite, seed):
    """The regions claim a rotated rectangle; the truly feasible set misses a disc bitten out
    of one side. Every point sampled inside the checked ellipse and circle passes."""
    claimed = shapely.affinity.rotate(
        shapely.box(-w / 2, -h / 2, w / 2, h / 2), turn, use_radians=True
    )
    side = np.array([math.cos(turn), math.sin(turn)]) * w / 2 * bite
    feasible = claimed.difference(shapely.Point(*side).buffer(0.6 * h))
    if not feasible.contains(shapely.Point(0, 0)):
        return
    test, _ = _test_of(feasible)
    r_in = float(shapely.distance(shapely.Point(0, 0), claimed.boundary))
    got = stop_shapes(test, ["t"], (0.0, 0.0), 0.0, claimed, r_in, RES)
    rng = np.random.default_rng(seed)
    circle = Ellipse(got.radius, got.radius, 0.0)
    for e in (got.ellipse, circle):
        pts = _inside(e, 400, rng)
        # the feasible set's boundary between samples may cut a sliver (the spacing's claim)
        assert shapely.contains_xy(feasible.buffer(RES / 8), pts[:, 0], pts[:, 1]).all()
    assert got.ellipse.area >= math.pi * got.radius**2 - 1e-12
    assert got.ellipse.a >= got.ellipse.b and -math.pi / 2 <= got.ellipse.theta <= math.pi / 2


def test_a_long_region_gets_an_ellipse_larger_than_its_circle_along_it():
    claimed = shapely.affinity.rotate(shapely.box(-0.4, -0.1, 0.4, 0.1), 30, origin=(0, 0))
    test, calls = _test_of(claimed)
    got = stop_shapes(test, ["a", "b"], (0.0, 0.0), 0.0, claimed, 0.1, RES)
    assert got.radius <= 0.1 and got.radius > 0.09
    assert got.ellipse.area > 2.5 * math.pi * got.radius**2
    assert abs(got.ellipse.theta - math.radians(30)) < math.radians(6)
    # bounded: every pose once per tray, at most the samples of a few rounds of three shapes
    assert got.tests == sum(calls) <= 2 * (3 * (INTERIOR_MAX + ROUNDS * BOUNDARY_MAX) + 1)
    assert (got.boundary_spacing, got.interior_spacing) == (RES / 4, RES / 2)


def test_a_failing_centre_proves_nothing():
    claimed = shapely.box(-0.2, -0.2, 0.2, 0.2)
    test, _ = _test_of(shapely.box(0.05, 0.05, 0.2, 0.2))
    got = stop_shapes(test, ["t"], (0.0, 0.0), 0.0, claimed, 0.2, RES)
    assert got.radius == 0 and got.ellipse.a == 0


def test_the_inscribed_candidate_stays_inside_the_region():
    region = shapely.Polygon([(-0.3, -0.1), (0.3, -0.1), (0.1, 0.2), (-0.2, 0.15)])
    e = largest_inscribed(region, (0.0, 0.0), 0.08, RES)
    pts = _inside(e, 2000, np.random.default_rng(0))
    # within a micrometre: the region's boundary is densified to points res/8 apart
    assert shapely.contains_xy(region.buffer(1e-6), pts[:, 0], pts[:, 1]).all()
    assert e.area > math.pi * 0.08**2


# -- the example plans, checked by the exact test --

SHAPED = ["paper_experiment", "rack_cell"]


@pytest.fixture(scope="module")
def shaped(example_plans, planner):
    """``name -> (checker, plan, shapes)`` of two example plans."""
    from pickstop.fleet.pickcheck import PickChecker

    out = {}
    for name in SHAPED:
        scene, plan = example_plans[name]
        check = PickChecker(planner, scene)
        out[name] = (check, plan, check.shapes(plan))
    return out


@pytest.mark.parametrize("name", SHAPED)
def test_orders_carry_the_checked_shapes_and_validate(shaped, name):
    """3.0: the checked ellipse on every stop node; 2.1 and 2.0: the checked circle."""
    import jsonschema

    from pickstop.fleet import order as orders
    from pickstop.fleet import published
    from pickstop.fleet import vda5050 as v

    _, plan, shapes = shaped[name]
    for version in ("3.0", "2.1", "2.0"):
        order = orders.build_order(plan, orders.OrderOptions(version=version, shapes=shapes))
        doc = v.dump(order)
        jsonschema.validate(doc, published.schema("order", v.VERSIONS[version]))
        assert orders.check_order(order) == []
        stops = [n for n in doc["nodes"] if n["nodeId"].startswith("stop")]
        assert len(stops) == len(plan.stops) == len(shapes)
        for n, sh in zip(stops, shapes, strict=True):
            dev = n["nodePosition"]["allowedDeviationXY"]
            if version == "3.0":
                e = sh.ellipse
                assert dev == {"a": e.a, "b": e.b, "theta": e.theta}
                assert e.a >= e.b >= 0 and e.area >= math.pi * sh.radius**2 - 1e-12
            else:
                assert dev == sh.radius


@pytest.mark.parametrize("name", SHAPED)
def test_poses_inside_the_exported_shapes_pass_the_exact_test(shaped, name):
    check, plan, shapes = shaped[name]
    rng = np.random.default_rng(7)
    for s, sh in zip(plan.stops, shapes, strict=True):
        assert sh.radius > 0 and sh.ellipse.area >= math.pi * sh.radius**2 - 1e-12
        assert sh.radius <= s.inscribed_radius + 1e-12
        for e in (sh.ellipse, Ellipse(sh.radius, sh.radius, 0.0)):
            # failures show first near the rim: half the poses there
            d = np.concatenate([_inside(e, 200, rng), _inside(e, 200, rng, rim=0.05)])
            xy = np.array([s.x, s.y]) + d
            for t in s.trays:
                ok = check.many(t, xy, s.yaw)
                assert ok.all(), (name, s.index, t, xy[~ok])

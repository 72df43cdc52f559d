"""The fast success estimate against analytic answers and against the Monte Carlo."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pickstop.regions.cells import CellGrid
from pickstop.sequence.estimate import Q, estimate, feasible_subcells, kernel
from pickstop.sequence.refine import Refinement
from pickstop.sequence.success import monte_carlo, rayleigh_scale
from tests.utils import discs, region_of

GRID = CellGrid(0.0, 0.0, 0.025, 80, 80)  # 2 m x 2 m at the examples' resolution


def refined(region, k, inside) -> np.ndarray:
    """The exact sub-cell outcomes the refinement finds for kernel ``k``."""
    ref = Refinement.of(region)
    ref.want(k)
    ref.run(lambda _, xy: inside(xy))
    return ref.exact


def test_a_half_plane_under_gaussian_error_matches_the_normal_cdf():
    """Feasible where x <= b, b half a millimetre short of a column of cell centres: those
    cells' verdict (their centre's: infeasible) is wrong on nearly half their area, their
    sub-cells' verdicts are right to 0.5 mm."""
    sigma, b, xy = 0.1, 1.0125 - 0.0005, (1.0, 1.0)

    def inside(p):
        return np.asarray(p, float).reshape(-1, 2)[:, 0] <= b

    region = region_of(inside, GRID)
    k = kernel("gaussian", sigma, GRID, xy)
    truth = 0.5 * (1 + math.erf((b - xy[0]) / (rayleigh_scale(sigma) * math.sqrt(2))))
    cells_only = estimate(k, [feasible_subcells(region, k)])
    exact = estimate(k, [feasible_subcells(region, k, refined(region, k, inside))])
    assert abs(exact - truth) < 0.005
    assert abs(cells_only - truth) > 0.03


@settings(max_examples=60, deadline=None, derandomize=True)
@given(
    centres=st.lists(st.tuples(st.floats(0.7, 1.3), st.floats(0.7, 1.3)), min_size=1, max_size=3),
    radii=st.lists(st.floats(0.1, 0.3), min_size=3, max_size=3),
    offset=st.tuples(st.floats(-0.15, 0.15), st.floats(-0.15, 0.15)),
    sigma=st.floats(0.05, 0.15),
    kind=st.sampled_from(["gaussian", "bounded"]),
    seed=st.integers(0, 2**32 - 1),
)
def test_the_refined_estimate_agrees_with_the_monte_carlo(
    centres, radii, offset, sigma, kind, seed
):
    """Generated regions (unions of discs of radius 0.1 m or more, their cells the discs'
    verdicts at the centres) and stops near them: the estimate lies within the 99.99%
    interval (z = 4) of a 4,000-sample Monte Carlo of the same exact test, widened by the
    landing mass on the half-cells the region's boundary crosses (each counts whole by the
    exact test at one point inside it: the lattice's resolution, and all it can be off by).
    That slack matters where the landing's edge runs along the boundary (a bounded error
    whose disc just fits: up to 2 points, always pessimistic); elsewhere it is a fraction of a
    point. On narrower regions (a disc of four cells across) the lattice errs by more."""
    inside = discs(centres, radii[: len(centres)])
    region = region_of(inside, GRID)
    xy = (centres[0][0] + offset[0], centres[0][1] + offset[1])
    k = kernel(kind, sigma, GRID, xy)
    est = estimate(k, [feasible_subcells(region, k, refined(region, k, inside))])
    rate = monte_carlo(
        lambda p, _: inside(p), xy, 0.0, kind, sigma, 0.0, 4000, np.random.default_rng(seed)
    )
    lo, hi = rate.wilson(4.0)
    edge = _crossed_mass(k, inside)
    assert lo - edge <= est <= hi + edge, (est, rate.rate, edge)


def _crossed_mass(k, inside) -> float:
    """The kernel's mass on the half-cells of its window that the region's boundary crosses
    (3 x 3 points of each half-cell, corners included, not all on one side)."""
    h = GRID.res / Q
    rows = np.arange(k.row0, k.row0 + k.shape[0])
    cols = np.arange(k.col0, k.col0 + k.shape[1])
    f = np.array([0.0, 0.5, 1.0])
    xs = GRID.x0 + (cols[:, None] + f) * h  # (cols, 3)
    ys = GRID.y0 + (rows[:, None] + f) * h  # (rows, 3)
    X = np.broadcast_to(xs[None, :, None, :], (len(rows), len(cols), 3, 3))
    Y = np.broadcast_to(ys[:, None, :, None], (len(rows), len(cols), 3, 3))
    ok = inside(np.stack([X.ravel(), Y.ravel()], axis=1)).reshape(len(rows), len(cols), 9)
    crossed = ok.any(axis=2) & ~ok.all(axis=2)
    return float(k.masses[crossed].sum())

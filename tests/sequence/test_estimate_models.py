"""The fast success estimate under biased and anisotropic error models, against sampling."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import Point

from pickstop.regions.cells import CellGrid, TrayRegion
from pickstop.scene.positioning import ErrorDist
from pickstop.sequence.estimate import estimate, feasible_subcells, kernel

GRID = CellGrid(0.0, 0.0, 0.05, 40, 40)


def _region(mask: np.ndarray) -> TrayRegion:
    cells = np.argwhere(mask)
    return TrayRegion(
        tray_id="t", yaw=0.0, grid=GRID, mask=mask, cells=cells, part_ids=(),
        thetas=np.zeros((len(cells), 0, 0)), grasp_index=np.zeros((len(cells), 0), int),
        polygon=Point(0, 0), counts={}, reason=None, seconds=0.0,
    )  # fmt: skip


def _sampled(region: TrayRegion, dist: ErrorDist, xy, yaw, n=200_000) -> float:
    dxy, _ = dist.sample(n, np.random.default_rng(7), yaw)
    ix, iy = GRID.cell_of(np.asarray(xy) + dxy)
    inside = (ix >= 0) & (ix < GRID.nx) & (iy >= 0) & (iy < GRID.ny)
    ok = np.zeros(n, bool)
    ok[inside] = region.mask[iy[inside], ix[inside]]
    return float(ok.mean())


def test_an_isotropic_model_gives_the_isotropic_kernel():
    d = ErrorDist("gaussian", 0.05)
    a = kernel("gaussian", 0.05, GRID, (1.0, 1.0))
    b = kernel("gaussian", 0.05, GRID, (1.0, 1.0), dist=d, yaw=0.7)
    assert (a.row0, a.col0) == (b.row0, b.col0) and np.array_equal(a.masses, b.masses)


def test_a_biased_model_moves_the_mass_by_its_mean_turned_with_the_stop():
    d = ErrorDist("gaussian", 0.03, mean=(0.2, 0.0), frame="base")
    k = kernel("gaussian", 0.03, GRID, (1.0, 1.0), dist=d, yaw=math.pi / 2)
    h = GRID.res / 2
    rows = np.arange(k.row0, k.row0 + k.shape[0]) * h + h / 2
    cols = np.arange(k.col0, k.col0 + k.shape[1]) * h + h / 2
    cy = float((k.masses.sum(1) * rows).sum())
    cx = float((k.masses.sum(0) * cols).sum())
    assert cx == pytest.approx(1.0, abs=0.01) and cy == pytest.approx(1.2, abs=0.01)


@settings(max_examples=15, deadline=None)
@given(
    sx=st.floats(0.01, 0.08), sy=st.floats(0.01, 0.08), rho=st.floats(-0.8, 0.8),
    mx=st.floats(-0.05, 0.05), my=st.floats(-0.05, 0.05), yaw=st.floats(-math.pi, math.pi),
    seed=st.integers(0, 1000),
)  # fmt: skip
def test_the_estimate_agrees_with_sampling_on_generated_regions(sx, sy, rho, mx, my, yaw, seed):
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:40, 0:40]
    cx, cy, r = rng.uniform(15, 25), rng.uniform(15, 25), rng.uniform(3, 8)
    mask = ((xx - cx) / r) ** 2 + ((yy - cy) / (r * rng.uniform(0.5, 1.5))) ** 2 <= 1.0
    region = _region(mask)
    cov = ((sx * sx, rho * sx * sy), (rho * sx * sy, sy * sy))
    d = ErrorDist("gaussian", 0.05, mean=(mx, my), covariance=cov)
    xy = ((cx + 0.5) * GRID.res, (cy + 0.5) * GRID.res)
    k = kernel("gaussian", 0.05, GRID, xy, dist=d, yaw=yaw)
    est = estimate(k, [feasible_subcells(region, k)])
    # the estimate integrates over sub-cells by midpoints: a few percent at a cell's scale
    assert est == pytest.approx(_sampled(region, d, xy, yaw), abs=0.03)

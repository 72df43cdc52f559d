"""Exact outcomes near a region's boundary, for the fast success estimate.

A region's verdict on a cell is its centre's; on the cells along the boundary (those with a
neighbour of the other verdict, on either side) part of the cell may go the other way. Those
cells, where a stop's landing distribution puts enough mass, get the exact off-grid test
(:func:`~pickstop.regions.offgrid.feasible_near`) at one point of each of their ``Q x Q``
sub-cells (:func:`probe_points`), and the estimate (:mod:`~pickstop.sequence.estimate`) counts
those outcomes instead of the cell's. What was checked is kept per region
(:class:`Refinement`), for every later estimate.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from pickstop.regions.cells import CellGrid, TrayRegion
from pickstop.sequence.estimate import MIN_MASS, Kernel, Q, cell_masses

#: The exact test of one region at base positions ``xy: (M, 2)`` [m]: ``ok (M,)``.
Evaluate = Callable[[TrayRegion, np.ndarray], np.ndarray]


#: Steps of the R2 low-discrepancy sequence that places each sub-cell's test point.
R2 = (0.7548776662466927, 0.5698402909980532)


def probe_points(grid: CellGrid, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``(n, 2)`` [m]: where sub-cells ``(rows, cols)`` (each ``(n,)``) are tested, one point
    inside each at an offset set by its index (the R2 sequence): a stratified sample of the
    boundary. Points on a fixed lattice would share the offsets of the cells' own verdicts and
    the database's voxels, and there the exact test passes less often than at the poses the
    base lands on (by up to a point of a stop's success in a hundred, on the examples)."""
    n = rows.astype(np.float64) * (grid.nx * Q) + cols
    u, v = (0.5 + n * R2[0]) % 1.0, (0.5 + n * R2[1]) % 1.0
    h = grid.res / Q
    return np.stack([grid.x0 + (cols + u) * h, grid.y0 + (rows + v) * h], axis=1)


def boundary(mask: np.ndarray) -> np.ndarray:
    """``(ny, nx)`` bool: cells with a neighbour (of 8) of the other verdict."""
    grown = ndimage.binary_dilation(mask, np.ones((3, 3), bool))
    shrunk = ndimage.binary_erosion(mask, np.ones((3, 3), bool), border_value=1)
    return grown & ~shrunk


@dataclass
class Refinement:
    """A region's exact sub-cell outcomes so far: ``exact (ny Q, nx Q)`` int8, 1 or 0 where
    the sub-cell's test point was checked, -1 elsewhere (a memo: it only grows)."""

    region: TrayRegion
    exact: np.ndarray
    edge: np.ndarray  # (ny, nx) bool: the boundary cells
    done: np.ndarray  # (ny, nx) bool: cells checked
    checks: int = 0  # exact tests run
    pending: set[tuple[int, int]] = field(default_factory=set)

    @classmethod
    def of(cls, region: TrayRegion) -> Refinement:
        g = region.grid
        return cls(
            region,
            np.full((g.ny * Q, g.nx * Q), -1, np.int8),
            boundary(region.mask),
            np.zeros((g.ny, g.nx), bool),
        )

    def want(self, k: Kernel) -> int:
        """Mark the boundary cells where ``k`` puts :data:`MIN_MASS` or more for checking;
        returns how many are new."""
        g = self.region.grid
        iy, ix, mass = cell_masses(k)
        ry, rx = np.nonzero(mass >= MIN_MASS)
        cy, cx = iy[ry], ix[rx]
        inside = (cy >= 0) & (cy < g.ny) & (cx >= 0) & (cx < g.nx)
        cy, cx = cy[inside], cx[inside]
        keep = self.edge[cy, cx] & ~self.done[cy, cx]
        before = len(self.pending)
        self.pending.update(zip(cy[keep].tolist(), cx[keep].tolist(), strict=True))
        return len(self.pending) - before

    def run(self, evaluate: Evaluate) -> int:
        """Check every pending cell's sub-cells exactly at their :func:`probe_points`; returns
        the tests run."""
        if not self.pending:
            return 0
        cells = np.array(sorted(self.pending), np.int64)  # (n, 2) iy, ix
        self.pending.clear()
        dy, dx = np.meshgrid(np.arange(Q), np.arange(Q), indexing="ij")
        rows = (cells[:, 0, None] * Q + dy.ravel()[None]).ravel()  # (n Q Q,) sub-cell rows
        cols = (cells[:, 1, None] * Q + dx.ravel()[None]).ravel()
        ok = evaluate(self.region, probe_points(self.region.grid, rows, cols))
        ok = np.asarray(ok, bool).reshape(len(cells), Q, Q)
        for (iy, ix), o in zip(cells.tolist(), ok, strict=True):
            self.exact[iy * Q : iy * Q + Q, ix * Q : ix * Q + Q] = o
        self.done[cells[:, 0], cells[:, 1]] = True
        self.checks += ok.size
        return int(ok.size)


def refine(refinements: Iterable[Refinement], kernels: Iterable[Kernel], evaluate: Evaluate) -> int:
    """Refine every region of ``refinements`` where any of ``kernels`` needs it; returns the
    exact tests run."""
    rs, ks = list(refinements), list(kernels)
    for r in rs:
        for k in ks:
            r.want(k)
    return sum(r.run(evaluate) for r in rs)

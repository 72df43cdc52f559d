"""Fast success estimates: the error's density integrated over the regions' verified cells.

A stop at ``x`` serving trays S succeeds when the base lands, at ``x + e``, where every tray of S
is graspable. The estimate integrates the error's density
(:func:`~pickstop.sequence.success.density`, the distribution the Monte Carlo samples) over a
lattice of sub-cells (each cell of the regions' grid split ``Q x Q``): a sub-cell counts as
feasible for a tray when its cell is one of the region's verified cells, unless an exact
outcome is known for it (``exact``, from :mod:`pickstop.sequence.refine`, which settles the
sub-cells near the boundary, where a cell's verdict at its centre is not its whole area's, by
the exact test at one point of each).

The density is integrated over each sub-cell by ``QUAD x QUAD`` midpoints and normalised over
the window that holds all but 1e-5 of its mass (:func:`~pickstop.sequence.success.support`), so
any error model given by a density plugs in. The yaw error, if any, is left to the Monte Carlo.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from pickstop.regions.cells import CellGrid, TrayRegion
from pickstop.scene.positioning import ErrorDist
from pickstop.sequence.success import Kind, density, support

Q = 2  # sub-cells per cell edge
QUAD = 2  # midpoints per sub-cell edge integrating the density
MIN_MASS = 2e-4  # a cell holding less of a stop's landing mass keeps its verdict


@dataclass(frozen=True)
class Kernel:
    """Where the base lands aiming at one point: the probability of each sub-cell of a window
    of the grid's sub-cell lattice (sub-cell ``(row, col)`` covers
    ``[x0 + col h, x0 + (col + 1) h) x [y0 + row h, ...)``, ``h = res / Q``)."""

    row0: int  # sub-cell row of masses[0, 0]
    col0: int  # sub-cell column of masses[0, 0]
    masses: np.ndarray  # (rows, cols), summing to 1

    @property
    def shape(self) -> tuple[int, int]:
        return self.masses.shape  # type: ignore[return-value]


def kernel(
    kind: Kind,
    sigma: float,
    grid: CellGrid,
    xy: tuple[float, float],
    dist: ErrorDist | None = None,
    yaw: float = 0.0,
) -> Kernel:
    """The landing distribution around ``xy`` [m] on ``grid``'s sub-cells (``sigma > 0``):
    isotropic of ``kind`` and ``sigma``, or ``dist`` (biased or anisotropic, at a stop of
    heading ``yaw`` [rad]) when it is given and not isotropic."""
    if dist is None or dist.legacy:
        return _window(grid, xy, (0.0, 0.0), support(kind, sigma),
                       lambda dxy: density(kind, sigma, dxy))  # fmt: skip
    mu, C = dist.in_map(yaw)
    if not dist.spread:  # it lands at its mean: all the mass in that sub-cell
        h = grid.res / Q
        col = math.floor((xy[0] + float(mu[0]) - grid.x0) / h)
        row = math.floor((xy[1] + float(mu[1]) - grid.y0) / h)
        return Kernel(row, col, np.ones((1, 1)))
    # the window around its mean holding all but 1e-5 of its mass: the Gaussian's largest
    # axis times support()'s factor, or a bounded disc's radius
    scale = math.sqrt(float(np.linalg.eigvalsh(C)[-1]))
    R = dist.sigma if dist.kind == "bounded" else scale * math.sqrt(-2.0 * math.log(1e-5))

    def dens(dxy: np.ndarray) -> np.ndarray:
        return dist.density(dxy.reshape(-1, 2), yaw).reshape(dxy.shape[:-1])

    return _window(grid, xy, (float(mu[0]), float(mu[1])), R, dens)


def _window(
    grid: CellGrid,
    xy: tuple[float, float],
    mean: tuple[float, float],
    R: float,
    dens: Callable[[np.ndarray], np.ndarray],
) -> Kernel:
    """The masses of the sub-cells within ``R`` [m] of ``xy + mean``: the density ``dens``
    of offsets from ``xy`` (``(..., 2)`` -> ``(...)``) by ``QUAD x QUAD`` midpoints, normalised."""
    h = grid.res / Q
    x, y = xy[0] + mean[0], xy[1] + mean[1]
    col0, col1 = math.floor((x - R - grid.x0) / h), math.floor((x + R - grid.x0) / h) + 1
    row0, row1 = math.floor((y - R - grid.y0) / h), math.floor((y + R - grid.y0) / h) + 1
    mid = (np.arange(QUAD) + 0.5) * (h / QUAD)
    xs = (grid.x0 + np.arange(col0, col1)[:, None] * h + mid).ravel() - xy[0]
    ys = (grid.y0 + np.arange(row0, row1)[:, None] * h + mid).ravel() - xy[1]
    d = dens(np.stack(np.meshgrid(xs, ys), axis=-1))
    masses = d.reshape(row1 - row0, QUAD, col1 - col0, QUAD).sum(axis=(1, 3))
    return Kernel(row0, col0, masses / masses.sum())


def cell_masses(k: Kernel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The kernel's mass per grid cell: cell rows ``iy (n,)``, columns ``ix (m,)`` and
    ``mass (n, m)``."""
    cy = np.arange(k.row0, k.row0 + k.shape[0]) // Q
    cx = np.arange(k.col0, k.col0 + k.shape[1]) // Q
    iy, ry = np.unique(cy, return_inverse=True)
    ix, rx = np.unique(cx, return_inverse=True)
    mass = np.zeros((len(iy), len(ix)))
    np.add.at(mass, (ry[:, None], rx[None, :]), k.masses)
    return iy, ix, mass


def feasible_subcells(region: TrayRegion, k: Kernel, exact: np.ndarray | None = None) -> np.ndarray:
    """``(rows, cols)`` bool over ``k``'s window: the sub-cells where the region's tray counts
    as graspable. ``exact``: ``(ny Q, nx Q)`` int8 over the whole grid, 1 or 0 where a
    sub-cell was checked exactly, -1 where its cell's verdict stands; it counts in
    the cells where ``k`` puts :data:`MIN_MASS` or more (those it would have checked), so an
    estimate does not depend on what else was checked before it."""
    rows = np.arange(k.row0, k.row0 + k.shape[0])
    cols = np.arange(k.col0, k.col0 + k.shape[1])
    g = region.grid
    r_in = (rows >= 0) & (rows < g.ny * Q)
    c_in = (cols >= 0) & (cols < g.nx * Q)
    rr, cc = np.clip(rows, 0, g.ny * Q - 1), np.clip(cols, 0, g.nx * Q - 1)
    out = region.mask[np.ix_(rr // Q, cc // Q)]
    if exact is not None:
        iy, ix, mass = cell_masses(k)
        heavy = mass[np.ix_(np.searchsorted(iy, rows // Q), np.searchsorted(ix, cols // Q))]
        known = exact[np.ix_(rr, cc)]
        out = np.where((known >= 0) & (heavy >= MIN_MASS), known == 1, out)
    return out & r_in[:, None] & c_in[None, :]


def estimate(k: Kernel, feasible: Iterable[np.ndarray]) -> float:
    """Success of a stop: the kernel's mass where every tray is graspable (``feasible``: each
    tray's :func:`feasible_subcells`)."""
    every = np.ones(k.shape, bool)
    for f in feasible:
        every &= f
    return min(1.0, float(k.masses[every].sum()))  # the masses' rounding may exceed 1


def subset_estimates(
    k: Kernel, feasible: Mapping[str, np.ndarray], subsets: Iterable[frozenset[str]]
) -> dict[frozenset[str], float]:
    """:func:`estimate` for each set of trays of ``subsets`` (each a subset of ``feasible``)."""
    return {s: estimate(k, (feasible[t] for t in sorted(s))) for s in subsets}

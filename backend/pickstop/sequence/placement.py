"""Stops placed for success: within a candidate intersection, the point where the base's
landing distribution keeps the most mass on ground from which every tray is graspable.

The paper stops at the centre of the intersection's largest inscribed circle: the point
farthest from the boundary, best for a bounded error no larger than the radius. Under a
Gaussian (or biased, or anisotropic) error the best point can lie elsewhere: in a long
intersection the circle touches both sides while the mass that misses the ends matters less.

The search scores every sub-cell centre inside the intersection at once: with the landing
kernel (:func:`~pickstop.sequence.estimate.kernel`) the same at every sub-cell centre (it is,
exactly: its window and its midpoints sit at the same offsets from each), the success of each
point is the correlation of the kernel with the lattice of sub-cells where every tray counts
as graspable (the regions' verified cells, with the exact outcomes known near their
boundaries). The best point found is only a proposal: the planner estimates it as any stop
(refined exactly near the boundaries) and keeps it only if that beats the circle's centre
by :data:`MIN_GAIN`, then verifies it with the exact check like every stop.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np
import shapely
from shapely.geometry import Polygon

from pickstop.regions.cells import TrayRegion
from pickstop.sequence.estimate import Kernel, Q

#: Least gain in estimated success [fraction] worth moving a stop off its circle's centre:
#: below it the move is within the estimate's own error and only costs clearance.
MIN_GAIN = 0.002
MAX_POINTS = 250_000  # sub-cell centres scored per candidate, at most (bounds the correlation)


def lattice_feasible(
    regions: Sequence[TrayRegion],
    rows: np.ndarray,
    cols: np.ndarray,
    exact: Mapping[str, np.ndarray] | None = None,
) -> np.ndarray:
    """``(len(rows), len(cols))`` bool: the sub-cells (of the regions' common grid) where every
    region's tray counts as graspable: its cell is verified, unless the exact outcome of the
    sub-cell is known (``exact``: tray -> ``(ny Q, nx Q)`` int8, 1 / 0 / -1 unknown)."""
    g = regions[0].grid
    r_in = (rows >= 0) & (rows < g.ny * Q)
    c_in = (cols >= 0) & (cols < g.nx * Q)
    rr, cc = np.clip(rows, 0, g.ny * Q - 1), np.clip(cols, 0, g.nx * Q - 1)
    out = r_in[:, None] & c_in[None, :]
    for r in regions:
        ok = r.mask[np.ix_(rr // Q, cc // Q)]
        known = None if exact is None else exact.get(r.tray_id)
        if known is not None:
            k = known[np.ix_(rr, cc)]
            ok = np.where(k >= 0, k == 1, ok)
        out &= ok
    return out


def best_point(
    regions: Sequence[TrayRegion],
    polygon: Polygon,
    centre: tuple[float, float],
    kernel_at: Callable[[tuple[float, float]], Kernel],
    exact: Mapping[str, np.ndarray] | None = None,
) -> tuple[tuple[float, float], float] | None:
    """The sub-cell centre inside ``polygon`` (the candidate intersection) with the highest
    success under the landing kernel (``kernel_at(xy)``: the kernel of a stop at ``xy`` [m]),
    and that score; ties go to the point nearest ``centre`` [m]. None when no sub-cell centre
    lies inside the polygon or there are more than :data:`MAX_POINTS`."""
    g = regions[0].grid
    h = g.res / Q
    x0, y0, x1, y1 = polygon.bounds
    c0, c1 = int(np.floor((x0 - g.x0) / h)), int(np.ceil((x1 - g.x0) / h))
    r0, r1 = int(np.floor((y0 - g.y0) / h)), int(np.ceil((y1 - g.y0) / h))
    if (c1 - c0) * (r1 - r0) > MAX_POINTS or c1 <= c0 or r1 <= r0:
        return None
    cols, rows = np.arange(c0, c1), np.arange(r0, r1)
    xs, ys = g.x0 + (cols + 0.5) * h, g.y0 + (rows + 0.5) * h
    X, Y = np.meshgrid(xs, ys)
    inside = shapely.contains_xy(polygon, X, Y)
    if not inside.any():
        return None
    # The kernel's window starts (dr, dc) sub-cells from the sub-cell it is computed for.
    ar = int(np.floor((centre[1] - g.y0) / h))
    ac = int(np.floor((centre[0] - g.x0) / h))
    k = kernel_at((g.x0 + (ac + 0.5) * h, g.y0 + (ar + 0.5) * h))
    dr, dc = k.row0 - ar, k.col0 - ac
    kr, kc = k.shape
    frows = np.arange(r0 + dr, r1 + dr + kr - 1)
    fcols = np.arange(c0 + dc, c1 + dc + kc - 1)
    F = lattice_feasible(regions, frows, fcols, exact).astype(np.float64)
    from scipy.signal import correlate  # on use: it adds 0.7 s to the API's start

    score = correlate(F, k.masses, mode="valid")  # (r1 - r0, c1 - c0)
    score = np.where(inside, score, -1.0)
    top = score.max()
    near = np.hypot(X - centre[0], Y - centre[1])
    cand = np.flatnonzero(score.ravel() >= top - 1e-9)
    i = cand[np.argmin(near.ravel()[cand])]
    return (float(X.ravel()[i]), float(Y.ravel()[i])), float(min(1.0, top))


def clearance(polygon: Polygon, xy: tuple[float, float]) -> float:
    """Radius [m] of the largest circle centred at ``xy`` inside ``polygon`` (0 outside)."""
    p = shapely.Point(xy)
    return float(polygon.boundary.distance(p)) if polygon.contains(p) else 0.0

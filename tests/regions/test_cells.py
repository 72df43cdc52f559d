"""The cell grid (regions/cells.py)."""

from __future__ import annotations


def test_touching_cells_merge_into_one_polygon():
    """Cells share bit-identical edges, so a solid block is one polygon with its holes."""
    import numpy as np

    from pickstop.regions.cells import CellGrid

    grid = CellGrid(x0=-1.1, y0=0.37, res=0.025, nx=40, ny=30)
    mask = np.ones((30, 40), bool)
    mask[10:14, 20:25] = False  # a hole
    iy, ix = np.nonzero(mask)
    poly = grid.cells_polygon(iy, ix)
    assert poly.geom_type == "Polygon" and len(poly.interiors) == 1
    assert abs(poly.area - mask.sum() * 0.025**2) < 1e-9

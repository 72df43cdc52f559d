"""The base cell grid of a scene, and a tray's region on it (its feasible cells and witnesses).

Cell ``(ix, iy)`` covers ``[x0 + ix res, x0 + (ix + 1) res) x [y0 + iy res, y0 + (iy + 1) res)``;
every edge is computed that way, never as ``x + res``, so that touching cells share bit-identical
edges and their squares merge into one polygon.
"""

from __future__ import annotations

import functools
import hashlib
import math
from dataclasses import dataclass, field

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from pickstop.regions.envelope import Envelope
from pickstop.scene.model import Scene


@dataclass(frozen=True)
class CellGrid:
    """Base cells: centre of cell (ix, iy) is ``(x0 + (ix + .5) res, y0 + (iy + .5) res)``."""

    x0: float
    y0: float
    res: float  # [m]
    nx: int
    ny: int

    @classmethod
    def of(cls, scene: Scene) -> CellGrid:
        ext, res = scene.grid_extent, scene.base_grid.resolution
        nx = math.floor((ext.max[0] - ext.min[0]) / res + 1e-9)
        ny = math.floor((ext.max[1] - ext.min[1]) / res + 1e-9)
        return cls(ext.min[0], ext.min[1], res, nx, ny)

    def centres(self, ix: np.ndarray, iy: np.ndarray) -> np.ndarray:
        return np.stack([self.x0 + (ix + 0.5) * self.res, self.y0 + (iy + 0.5) * self.res], -1)

    def cell_of(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(ix, iy)`` of the cells that hold the points ``xy: (N, 2)`` [m], int64; the
        grid's bounds are not checked (a point outside it gets an index outside it)."""
        ix = np.floor((xy[:, 0] - self.x0) / self.res).astype(np.int64)
        iy = np.floor((xy[:, 1] - self.y0) / self.res).astype(np.int64)
        return ix, iy

    def cells_polygon(self, iy: np.ndarray, ix: np.ndarray) -> BaseGeometry:
        """Union of the cells' squares: polygons with holes, touching cells merged."""
        if len(ix) == 0:
            return shapely.Polygon()
        # Neighbouring cells must share bit-identical edges for the coverage union to merge
        # them: compute every edge as x0 + i * res, never as x + res.
        x, x1 = self.x0 + ix * self.res, self.x0 + (ix + 1) * self.res
        y, y1 = self.y0 + iy * self.res, self.y0 + (iy + 1) * self.res
        boxes = shapely.box(x, y, x1, y1)
        return shapely.coverage_union_all(boxes)


@dataclass(frozen=True)
class TrayRegion:
    """Where the base can stand to pick every part of one tray, at one yaw."""

    tray_id: str
    yaw: float  # [rad]
    grid: CellGrid
    mask: np.ndarray  # (ny, nx) bool feasible cells
    cells: np.ndarray  # (K, 2) int (iy, ix) of feasible cells
    part_ids: tuple[str, ...]
    thetas: np.ndarray  # (K, P, dof) verified witness configuration per cell and part
    grasp_index: np.ndarray  # (K, P) which grasp of the part's grasp set
    polygon: BaseGeometry
    counts: dict[str, int]
    reason: str | None  # why the region is empty, if it is
    seconds: float
    key: str = ""
    envelope: Envelope | None = field(default=None, repr=False, compare=False)

    @functools.cached_property
    def digest(self) -> str:
        """What the region holds, as a key: its feasible cells, their witnesses and grasps
        (with its own key, what it was computed from)."""
        h = hashlib.sha256(f"{self.key}|{self.tray_id}|{self.yaw!r}".encode())
        for a in (self.cells, self.thetas, self.grasp_index):
            h.update(np.ascontiguousarray(a).tobytes())
        return h.hexdigest()

    @property
    def area(self) -> float:
        """[m^2]"""
        return float(len(self.cells)) * self.grid.res**2

    @classmethod
    def of_cells(
        cls,
        tray_id: str,
        yaw: float,
        grid: CellGrid,
        cells: np.ndarray,
        part_ids: tuple[str, ...],
        thetas: np.ndarray,
        grasp_index: np.ndarray,
        counts: dict[str, int],
        reason: str | None,
        seconds: float,
        key: str = "",
        envelope: Envelope | None = None,
    ) -> TrayRegion:
        """The region of feasible ``cells: (K, 2)`` (iy, ix) of ``grid``, their witnesses
        ``thetas: (K, P, dof)`` and grasps ``grasp_index: (K, P)``; mask and polygon follow."""
        K, P = len(cells), len(part_ids)
        assert cells.shape == (K, 2) and thetas.shape[:2] == (K, P)
        assert grasp_index.shape == (K, P)
        mask = np.zeros((grid.ny, grid.nx), bool)
        mask[cells[:, 0], cells[:, 1]] = True
        polygon = grid.cells_polygon(cells[:, 0], cells[:, 1])
        return cls(
            tray_id,
            yaw,
            grid,
            mask,
            cells,
            part_ids,
            thetas,
            grasp_index,
            polygon,
            counts,
            reason,
            seconds,
            key,
            envelope,
        )

    @classmethod
    def empty(
        cls,
        tray_id: str,
        yaw: float,
        grid: CellGrid,
        part_ids: tuple[str, ...],
        dof: int,
        counts: dict[str, int],
        reason: str,
        seconds: float,
        key: str = "",
        envelope: Envelope | None = None,
    ) -> TrayRegion:
        """No feasible cell, and ``reason`` why."""
        P = len(part_ids)
        return cls.of_cells(
            tray_id,
            yaw,
            grid,
            np.zeros((0, 2), int),
            part_ids,
            np.zeros((0, P, dof)),
            np.zeros((0, P), int),
            counts,
            reason,
            seconds,
            key,
            envelope,
        )

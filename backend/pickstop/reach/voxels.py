"""6D voxels: a cubic position grid times the SO(3) grid, packed into one int64 key.

``key = position_cell * n_orientations + orientation_cell``; the position cell packs three
integer coordinates offset by ``OFFSET`` so any pose within +-``OFFSET * resolution`` of the
base frame origin has a key without fixing bounds before a build.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pickstop.reach.so3 import SO3Grid, matrices_to_quats

OFFSET = 512
SPAN = 2 * OFFSET


@dataclass(frozen=True)
class VoxelGrid:
    """``resolution``: position voxel edge [m]; ``orientation``: SO(3) cells per face edge."""

    resolution: float
    orientation: int

    def __post_init__(self) -> None:
        if not (0.005 <= self.resolution <= 0.5):
            raise ValueError(
                f"position resolution must be in [0.005, 0.5] m, got {self.resolution}"
            )
        SO3Grid(self.orientation)  # validates

    @property
    def so3(self) -> SO3Grid:
        return SO3Grid(self.orientation)

    @property
    def n_orientations(self) -> int:
        return self.so3.size

    def position_cells(self, ps: np.ndarray) -> np.ndarray:
        """Integer cell coordinates ``(..., 3)`` of positions ``(..., 3)`` [m]."""
        return np.floor(np.asarray(ps) / self.resolution).astype(np.int64)

    def keys_from_cells(self, cells: np.ndarray, orient: np.ndarray) -> np.ndarray:
        c = np.asarray(cells, dtype=np.int64) + OFFSET
        inside = np.all((c >= 0) & (c < SPAN), axis=-1)
        pos = (c[..., 0] * SPAN + c[..., 1]) * SPAN + c[..., 2]
        key = pos * self.n_orientations + np.asarray(orient, dtype=np.int64)
        return np.where(inside, key, -1)

    def keys(self, ps: np.ndarray, qs: np.ndarray) -> np.ndarray:
        """Voxel keys ``(...,)`` of positions ``(..., 3)`` [m] and quaternions ``(..., 4)`` wxyz.

        A pose beyond the addressable span gets key -1.
        """
        return self.keys_from_cells(self.position_cells(ps), self.so3.index(qs))

    def keys_from_matrices(self, ps: np.ndarray, Rs: np.ndarray) -> np.ndarray:
        return self.keys(ps, matrices_to_quats(Rs))

    def key_one(self, p: tuple[float, float, float], q: tuple[float, float, float, float]) -> int:
        """Scalar :meth:`keys` for one pose (fast path for single queries)."""
        r = self.resolution
        c = [math.floor(v / r) + OFFSET for v in p]
        if not all(0 <= v < SPAN for v in c):
            return -1
        return ((c[0] * SPAN + c[1]) * SPAN + c[2]) * self.n_orientations + self.so3.index_one(q)

    def decode(self, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Keys -> (position cell coordinates ``(..., 3)``, orientation cell ``(...,)``)."""
        keys = np.asarray(keys, dtype=np.int64)
        orient = keys % self.n_orientations
        pos = keys // self.n_orientations
        z = pos % SPAN
        y = (pos // SPAN) % SPAN
        x = pos // (SPAN * SPAN)
        return np.stack([x, y, z], -1) - OFFSET, orient

    def cell_bounds(self, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper corners ``(..., 3)`` [m] of the position cells of ``keys``."""
        cells, _ = self.decode(keys)
        lo = cells * self.resolution
        return lo, lo + self.resolution

    def neighbour_keys(self, p: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Keys of the 27 position cells around ``p`` times the orientation cells near ``q``."""
        base = self.position_cells(np.asarray(p, dtype=float))
        offs = np.array([(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)])
        orient = self.so3.neighbours(q)
        cells = base + offs
        keys = self.keys_from_cells(cells[:, None, :], orient[None, :]).ravel()
        return np.unique(keys[keys >= 0])

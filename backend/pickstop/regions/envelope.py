"""What a region's answer depends on, to tell when a cached region is still valid.

Recorded while a tray's region is computed: the space of the open hand at every grasp and of
the base footprint at every candidate cell (``occ``, coarse voxels), the space the arms of the
accepted witnesses occupy (``witness``), and which objects made the screen reject anything
(``hit_owners``). When another object moves, the region is unchanged if (a) where it was, it
rejected nothing and touched no hand or footprint space: no rejection can flip; and (b) where
it now is, it touches no witness arm, hand or footprint space: every witness stays valid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

VOXEL = 0.1  # [m]
Z_TOP = 3.0  # [m]


@dataclass
class Envelope:
    origin: np.ndarray  # (3,) world corner of voxel (0, 0, 0) [m]
    occ: np.ndarray  # (nx, ny, nz) bool
    _pending: np.ndarray | None = None  # sphere centres not yet grown
    _radius: float = 0.0
    witness: np.ndarray | None = None  # (nx, ny, nz) bool: arms of accepted witnesses
    hit_owners: set[str] = field(default_factory=set)

    @classmethod
    def empty(
        cls, lo_xy: tuple[float, float], hi_xy: tuple[float, float], margin: float = 1.0
    ) -> Envelope:
        origin = np.array([lo_xy[0] - margin, lo_xy[1] - margin, -0.5])
        top = np.array([hi_xy[0] + margin, hi_xy[1] + margin, Z_TOP])
        shape = np.ceil((top - origin) / VOXEL).astype(int) + 1
        return cls(origin, np.zeros(tuple(shape), bool))

    def _index(self, pts: np.ndarray) -> np.ndarray:
        idx = np.floor((pts - self.origin) / VOXEL).astype(int)
        return np.clip(idx, 0, np.array(self.occ.shape) - 1)

    def mark_spheres(self, centres: np.ndarray, radius: float) -> None:
        """Mark every voxel within ``radius`` [m] of any of ``centres: (N, 3)`` (as cubes).

        Centres are collected and grown once, by the largest radius, in :meth:`settle`.
        """
        if len(centres) == 0:
            return
        if self._pending is None:
            self._pending = np.zeros_like(self.occ)
        i = self._index(centres.reshape(-1, 3))
        self._pending[i[:, 0], i[:, 1], i[:, 2]] = True
        self._radius = max(self._radius, radius)

    def settle(self) -> None:
        """Grow the collected sphere centres into the occupancy grid."""
        if self._pending is None:
            return
        hit = self._pending
        k = math.ceil(self._radius / VOXEL) + 1
        for axis in range(3):
            grown = hit.copy()
            for s in range(1, k + 1):
                lo = [slice(None)] * 3
                hi = [slice(None)] * 3
                lo[axis], hi[axis] = slice(s, None), slice(None, -s)
                grown[tuple(lo)] |= hit[tuple(hi)]
                grown[tuple(hi)] |= hit[tuple(lo)]
            hit = grown
        self.witness = hit if self.witness is None else self.witness | hit
        self._pending = None

    def mark_box(self, lo: np.ndarray, hi: np.ndarray) -> None:
        a, b = self._index(np.asarray(lo)), self._index(np.asarray(hi))
        self.occ[a[0] : b[0] + 1, a[1] : b[1] + 1, a[2] : b[2] + 1] = True

    def mark_columns(self, xy: np.ndarray, radius: float, height: float) -> None:
        """Columns from the floor to ``height`` [m] around ``xy: (M, 2)`` (base footprints)."""
        if len(xy) == 0:
            return
        pts = np.concatenate([xy, np.zeros((len(xy), 1))], axis=1)
        i = self._index(pts)
        cols = np.zeros(self.occ.shape[:2], bool)
        cols[i[:, 0], i[:, 1]] = True
        k = math.ceil(radius / VOXEL) + 1
        for axis in range(2):
            grown = cols.copy()
            for s in range(1, k + 1):
                if axis == 0:
                    grown[s:] |= cols[:-s]
                    grown[:-s] |= cols[s:]
                else:
                    grown[:, s:] |= cols[:, :-s]
                    grown[:, :-s] |= cols[:, s:]
            cols = grown
        top = self._index(np.array([self.origin[0], self.origin[1], height]))[2]
        self.occ[:, :, : top + 1] |= cols[:, :, None]

    def touches(self, lo: np.ndarray, hi: np.ndarray, witnesses: bool = True) -> bool:
        """Does the box ``[lo, hi]`` [m] reach any marked voxel (hand, footprint and, if
        ``witnesses``, the witness arms)?

        The grid spans the floor plus a margin and the robot's height, so the part of a box
        beyond it is out of the robot's reach and is clipped away.
        """
        self.settle()
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        top = self.origin + VOXEL * np.array(self.occ.shape)
        if np.any(hi < self.origin) or np.any(lo > top):
            return False
        a, b = self._index(lo), self._index(hi)
        box = (slice(a[0], b[0] + 1), slice(a[1], b[1] + 1), slice(a[2], b[2] + 1))
        if self.occ[box].any():
            return True
        return bool(witnesses and self.witness is not None and self.witness[box].any())

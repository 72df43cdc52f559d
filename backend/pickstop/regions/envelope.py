"""What a region's answer depends on, to tell when a cached region is still valid.

Recorded while a tray's region is computed: the space of the open hand at every grasp and of
the base footprint at every candidate cell (``occ``, coarse voxels), and which objects made the
screen reject anything (``hit_owners``). When another object moves, the region is unchanged if
(a) where it was, it rejected nothing and touched no hand or footprint space: no rejection can
flip; and (b) where it now is, it touches no hand or footprint space, blocks no free cell
(``free_xy``) and no witness arm collides with it (checked exactly by the region planner):
every witness stays valid. Objects overhanging cells whose footprint is clear count as having
rejected something.
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
    hit_owners: set[str] = field(default_factory=set)
    free_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # free cells [m]

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

    def touches(self, lo: np.ndarray, hi: np.ndarray) -> bool:
        """Does the box ``[lo, hi]`` [m] reach any marked voxel (hand or footprint space)?

        The grid spans the floor plus a margin and the robot's height, so the part of a box
        beyond it is out of the robot's reach and is clipped away.
        """
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        top = self.origin + VOXEL * np.array(self.occ.shape)
        if np.any(hi < self.origin) or np.any(lo > top):
            return False
        a, b = self._index(lo), self._index(hi)
        box = (slice(a[0], b[0] + 1), slice(a[1], b[1] + 1), slice(a[2], b[2] + 1))
        return bool(self.occ[box].any())

"""A near-uniform grid on SO(3): the equi-angular cube over the unit-quaternion 3-sphere.

A rotation's quaternion (wxyz, ``q ~ -q``) is put on the face of the 4D cube along its largest
component ``f`` (made positive). The other three components, divided by ``q_f``, lie in
[-1, 1]; mapping each through ``u = atan(t) * 4 / pi`` and cutting ``u`` into ``n`` equal parts
gives ``4 n^3`` cells. Unlike roll-pitch-yaw bins nothing degenerates anywhere (a top-down grasp
at pitch 90 degrees is an ordinary cell), and cell volumes stay within a factor ~2.3 of each
other (the equi-angular map flattens the gnomonic 16:1 distortion).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

_FOUR_OVER_PI = 4.0 / math.pi


def matrices_to_quats(Rs: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` -> unit quaternions ``(..., 4)`` wxyz with ``w >= 0``."""
    Rs = np.asarray(Rs, dtype=np.float64)
    m00, m11, m22 = Rs[..., 0, 0], Rs[..., 1, 1], Rs[..., 2, 2]
    # Squared magnitudes of each component; take the largest for a stable division.
    t = np.stack(
        [1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22]
    )
    k = np.argmax(t, axis=0)
    s = np.sqrt(np.maximum(np.take_along_axis(t, k[None], 0)[0], 1e-300))
    q = np.empty((*Rs.shape[:-2], 4))
    d21, d02, d10 = (
        Rs[..., 2, 1] - Rs[..., 1, 2],
        Rs[..., 0, 2] - Rs[..., 2, 0],
        Rs[..., 1, 0] - Rs[..., 0, 1],
    )
    s21, s02, s10 = (
        Rs[..., 2, 1] + Rs[..., 1, 2],
        Rs[..., 0, 2] + Rs[..., 2, 0],
        Rs[..., 1, 0] + Rs[..., 0, 1],
    )
    cand = [
        np.stack([s, d21 / s, d02 / s, d10 / s], -1),
        np.stack([d21 / s, s, s10 / s, s02 / s], -1),
        np.stack([d02 / s, s10 / s, s, s21 / s], -1),
        np.stack([d10 / s, s02 / s, s21 / s, s], -1),
    ]
    for i in range(4):
        sel = k == i
        q[sel] = cand[i][sel]
    q *= 0.5
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def quats_to_matrices(qs: np.ndarray) -> np.ndarray:
    """Quaternions ``(..., 4)`` wxyz (any norm > 0) -> rotation matrices ``(..., 3, 3)``."""
    q = np.asarray(qs, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def quat_angle(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Rotation angle between unit quaternions (broadcast over ``(..., 4)``) [rad], in [0, pi]."""
    d = np.abs(np.sum(np.asarray(q1) * np.asarray(q2), axis=-1))
    return 2.0 * np.arccos(np.clip(d, 0.0, 1.0))


@dataclass(frozen=True)
class SO3Grid:
    """``4 n^3`` near-equal cells; ``n`` cells per face edge.

    A face edge spans 90 degrees of quaternion angle, i.e. a cell is about ``180 / n`` degrees
    of rotation across.
    """

    n: int

    def __post_init__(self) -> None:
        if not (1 <= self.n <= 64):
            raise ValueError(f"SO3Grid.n must be in 1..64, got {self.n}")

    @property
    def size(self) -> int:
        return 4 * self.n**3

    @property
    def cell_angle(self) -> float:
        """Typical rotation angle across one cell [rad]."""
        return math.pi / self.n

    def index(self, qs: np.ndarray) -> np.ndarray:
        """Cell index ``(...,)`` int64 of unit quaternions ``(..., 4)`` wxyz (either sign)."""
        q = np.asarray(qs, dtype=np.float64)
        a = np.abs(q)
        f = np.argmax(a, axis=-1)
        qf = np.take_along_axis(q, f[..., None], -1)  # signed largest component
        # The three other components in order, divided by the (signed) largest one.
        others = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])[f]
        t = np.take_along_axis(q, others, -1) / qf
        u = np.arctan(t) * _FOUR_OVER_PI  # [-1, 1]
        b = np.clip(((u + 1.0) * (0.5 * self.n)).astype(np.int64), 0, self.n - 1)
        n = self.n
        return ((f.astype(np.int64) * n + b[..., 0]) * n + b[..., 1]) * n + b[..., 2]

    def index_one(self, q: tuple[float, float, float, float]) -> int:
        """Scalar :meth:`index` without numpy overhead (single queries)."""
        a = [abs(v) for v in q]
        f = a.index(max(a))
        qf = q[f]
        n = self.n
        idx = f
        for i in range(4):
            if i == f:
                continue
            u = math.atan(q[i] / qf) * _FOUR_OVER_PI
            idx = idx * n + min(max(int((u + 1.0) * 0.5 * n), 0), n - 1)
        return idx

    def centers(self, idx: np.ndarray | None = None) -> np.ndarray:
        """Cell centres as unit quaternions ``(..., 4)`` wxyz (all cells if ``idx`` is None)."""
        n = self.n
        idx = np.arange(self.size) if idx is None else np.asarray(idx, dtype=np.int64)
        b2 = idx % n
        b1 = (idx // n) % n
        b0 = (idx // (n * n)) % n
        f = idx // (n**3)
        u = (np.stack([b0, b1, b2], -1) + 0.5) / n * 2.0 - 1.0
        t = np.tan(u / _FOUR_OVER_PI)
        q = np.empty((*idx.shape, 4))
        others = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])[f]
        np.put_along_axis(q, f[..., None], 1.0, -1)
        np.put_along_axis(q, others, t, -1)
        return q / np.linalg.norm(q, axis=-1, keepdims=True)

    def neighbours(self, q: np.ndarray) -> np.ndarray:
        """Cells touched by rotating unit quaternion ``q: (4,)`` by up to about one cell.

        The rotation is perturbed by +-``cell_angle`` about the 26 directions of a cube (and
        kept as is), so the answer crosses face boundaries correctly. Sorted, unique, int64.
        """
        dirs = np.array(
            [(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)], dtype=float
        )
        norms = np.linalg.norm(dirs, axis=1)
        norms[norms == 0] = 1.0
        rotvec = dirs / norms[:, None] * self.cell_angle
        half = np.linalg.norm(rotvec, axis=1) / 2
        with np.errstate(invalid="ignore", divide="ignore"):
            scale = np.where(half > 0, np.sin(half) / np.where(half > 0, 2 * half, 1), 0.5)
        dq = np.concatenate([np.cos(half)[:, None], rotvec * scale[:, None]], axis=1)
        q = np.asarray(q, dtype=float)
        # Left multiplication: perturbation expressed in the base frame.
        w1, v1 = dq[:, 0], dq[:, 1:]
        w2, v2 = q[0], q[1:]
        w = w1 * w2 - v1 @ v2
        v = w1[:, None] * v2 + w2 * v1 + np.cross(v1, v2)
        return np.unique(self.index(np.concatenate([w[:, None], v], axis=1)))

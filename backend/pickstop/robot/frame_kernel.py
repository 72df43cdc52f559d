"""Rigid transforms for the compiled kernels (numba, inlined where they are called): a frame
held by value (:data:`Frame`), composed with another and put into arrays, and points and boxes
carried through it and the base pose (:data:`Base`) into the world.

Every kernel that composes frames or places a point computes each entry here, with the same
operations in the same order, so the kernels agree bit for bit. A frame ``(R, p)`` maps a
point ``l`` of its own to ``R l + p``; the base stands at ``(x, y)`` turned by yaw about z:
world = R_z(yaw) (R l + p) + (x, y, 0). Each helper is straight-line code: inlined, the arrays
it takes cost no reference counts.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: A frame by value, the rows of ``[R | p]``: R00 R01 R02 p0 R10 R11 R12 p1 R20 R21 R22 p2
#: (read once, then used for every point of the frame; a tuple carries no reference count).
Frame = tuple[float, float, float, float, float, float, float, float, float, float, float, float]
#: A base pose by value: ``(x [m], y [m], cos(yaw), sin(yaw))``.
Base = tuple[float, float, float, float]


@njit(cache=True, nogil=True, inline="always")
def frame(R: np.ndarray, p: np.ndarray) -> Frame:
    """The frame of ``R: (3, 3)``, ``p: (3,)`` (any layout: larger arrays are read in their
    top-left corner)."""
    return (
        R[0, 0], R[0, 1], R[0, 2], p[0],
        R[1, 0], R[1, 1], R[1, 2], p[1],
        R[2, 0], R[2, 1], R[2, 2], p[2],
    )  # fmt: skip


@njit(cache=True, nogil=True, inline="always")
def put(F: Frame, R: np.ndarray, p: np.ndarray) -> None:
    """In place: ``R[:3, :3], p[:3]`` the frame ``F``."""
    R[0, 0], R[0, 1], R[0, 2], p[0] = F[0], F[1], F[2], F[3]
    R[1, 0], R[1, 1], R[1, 2], p[1] = F[4], F[5], F[6], F[7]
    R[2, 0], R[2, 1], R[2, 2], p[2] = F[8], F[9], F[10], F[11]


@njit(cache=True, nogil=True, inline="always")
def apply(F: Frame, x: float, y: float, z: float) -> tuple[float, float, float]:
    """The point ``(x, y, z)`` of ``F`` in the frame ``F`` is given in: ``R l + p``."""
    return (
        F[0] * x + F[1] * y + F[2] * z + F[3],
        F[4] * x + F[5] * y + F[6] * z + F[7],
        F[8] * x + F[9] * y + F[10] * z + F[11],
    )


@njit(cache=True, nogil=True, inline="always")
def compose(A: Frame, B: Frame) -> Frame:
    """``A B``: the frame ``B``, given in ``A``, in the frame ``A`` is given in."""
    p0, p1, p2 = apply(A, B[3], B[7], B[11])
    return (
        A[0] * B[0] + A[1] * B[4] + A[2] * B[8],
        A[0] * B[1] + A[1] * B[5] + A[2] * B[9],
        A[0] * B[2] + A[1] * B[6] + A[2] * B[10],
        p0,
        A[4] * B[0] + A[5] * B[4] + A[6] * B[8],
        A[4] * B[1] + A[5] * B[5] + A[6] * B[9],
        A[4] * B[2] + A[5] * B[6] + A[6] * B[10],
        p1,
        A[8] * B[0] + A[9] * B[4] + A[10] * B[8],
        A[8] * B[1] + A[9] * B[5] + A[10] * B[9],
        A[8] * B[2] + A[9] * B[6] + A[10] * B[10],
        p2,
    )


@njit(cache=True, nogil=True, inline="always")
def to_world(F: Frame, base: Base, x: float, y: float, z: float) -> tuple[float, float, float]:
    """The point ``(x, y, z)`` of the joint frame ``F`` (given in the base frame) in the world,
    the base at ``base``."""
    px, py, pz = apply(F, x, y, z)
    bx, by, c, s = base
    return c * px - s * py + bx, s * px + c * py + by, pz


@njit(cache=True, nogil=True, inline="always")
def world_box(
    F: Frame, base: Base, lo: np.ndarray, hi: np.ndarray, pad: float
) -> tuple[float, float, float, float, float, float]:
    """The world box around the box ``lo, hi: (3,)`` [m] of the joint frame ``F``, the base at
    ``base``: its centre and half extents, these grown by ``pad`` [m]."""
    cx, cy, cz = to_world(F, base, (lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2)
    e0, e1, e2 = (hi[0] - lo[0]) / 2, (hi[1] - lo[1]) / 2, (hi[2] - lo[2]) / 2
    c, s = base[2], base[3]
    # each world axis: |row of R_z(yaw) R| . e
    hx = pad + abs(c * F[0] - s * F[4]) * e0 + abs(c * F[1] - s * F[5]) * e1
    hx += abs(c * F[2] - s * F[6]) * e2
    hy = pad + abs(s * F[0] + c * F[4]) * e0 + abs(s * F[1] + c * F[5]) * e1
    hy += abs(s * F[2] + c * F[6]) * e2
    hz = pad + abs(F[8]) * e0 + abs(F[9]) * e1 + abs(F[10]) * e2
    return cx, cy, cz, hx, hy, hz

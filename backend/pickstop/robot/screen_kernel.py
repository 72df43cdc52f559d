"""The self-collision sphere screen, compiled (numba): :func:`screen_rows` walks each
configuration's sphere trees depth first and stops at its first leaf that may touch, where
:func:`pickstop.robot.screen.screen`'s numpy passes go breadth first over every
configuration at once (the faster way for large batches). Both evaluate each node's bound in
the same float32 operations, in the same order, so they answer the same; the tests hold them
to each other."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def screen_rows(
    poses: np.ndarray,
    B: int,
    roots: np.ndarray,
    node_rec: np.ndarray,
    node_offset: np.ndarray,
    field_values: np.ndarray,
    node_body_pair: np.ndarray,
    child_start: np.ndarray,
    child_count: np.ndarray,
    children: np.ndarray,
    step: float,
    out: np.ndarray,
) -> None:
    """``out[c]`` True where configuration ``c`` of ``B`` may collide with itself.

    ``poses: (BP * B, 12)`` float32 (row ``body pair * B + c``: body b's pose in body a as R's
    columns, then p: :func:`pickstop.robot.screen._poses`); the rest is the
    :class:`~pickstop.robot.screen.SphereModel`'s plan."""
    h = np.float32(step)
    inv_h = np.float32(1 / step)
    zero = np.float32(0.0)
    stack = np.empty(node_rec.shape[0] + roots.shape[0], np.int64)
    x = np.empty(3, np.float32)
    for c in range(B):
        top = 0
        for r in range(roots.shape[0] - 1, -1, -1):
            stack[top] = roots[r]
            top += 1
        hit = False
        while top > 0 and not hit:
            top -= 1
            n = stack[top]
            row = node_body_pair[n] * B + c
            rec = node_rec[n]
            for k in range(3):
                x[k] = (
                    poses[row, k] * rec[0]
                    + poses[row, 3 + k] * rec[1]
                    + poses[row, 6 + k] * rec[2]
                    + poses[row, 9 + k]
                )
            i0 = np.rint((min(max(x[0], rec[4]), rec[7]) - rec[4]) * inv_h)
            i1 = np.rint((min(max(x[1], rec[5]), rec[8]) - rec[5]) * inv_h)
            i2 = np.rint((min(max(x[2], rec[6]), rec[9]) - rec[6]) * inv_h)
            flat = np.int64((i0 * rec[10] + i1) * rec[11] + i2)
            val = field_values[flat + node_offset[n]]
            d0 = x[0] - rec[4] - i0 * h
            d1 = x[1] - rec[5] - i1 * h
            d2 = x[2] - rec[6] - i2 * h
            lb = val - np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            g0 = x[0] - min(max(x[0], rec[4]), rec[7])
            g1 = x[1] - min(max(x[1], rec[5]), rec[8])
            g2 = x[2] - min(max(x[2], rec[6]), rec[9])
            gap2 = g0 * g0 + g1 * g1 + g2 * g2
            if gap2 > zero:
                lb = max(lb, np.sqrt(gap2) + rec[12])
            if lb <= rec[3]:
                count = child_count[n]
                if count == 0:
                    hit = True
                else:
                    for k in range(count - 1, -1, -1):
                        stack[top] = children[child_start[n] + k]
                        top += 1
        out[c] = hit

"""Forward kinematics, compiled (numba): :func:`joint_frames` of one configuration, for the
compiled kernels that walk configurations one by one (:mod:`pickstop.regions.arm_kernel`,
:mod:`pickstop.reach.ik_kernel`), and :func:`chain_fk` of many, behind
:func:`pickstop.robot.kinematics.fk_soa`. The tests hold both to pinocchio."""

from __future__ import annotations

import numpy as np
from numba import njit

from pickstop.robot.frame_kernel import compose, frame, put


@njit(cache=True, nogil=True)
def joint_frames(
    R_parent: np.ndarray,
    p_parent: np.ndarray,
    axis_index: np.ndarray,
    axes: np.ndarray,
    prismatic: np.ndarray,
    theta: np.ndarray,
    R: np.ndarray,
    p: np.ndarray,
) -> None:
    """:func:`pickstop.robot.kinematics.fk_soa`'s joint frames of one configuration
    ``theta: (n,)``, into ``R: (n, 3, 3)``, ``p: (n, 3)`` (base frame); the chain's arrays as
    :class:`~pickstop.robot.kinematics.Chain` holds them."""
    n = theta.shape[0]
    for i in range(n):
        # the joint's frame at zero motion: its parent's (the last joint's, moved) times its
        # placement there
        F = frame(R_parent[i], p_parent[i])
        if i > 0:
            F = compose(frame(R[i - 1], p[i - 1]), F)
        put(F, R[i], p[i])
        a = axis_index[i]
        if prismatic[i]:
            for r in range(3):
                if a >= 0:
                    p[i, r] += R[i, r, a] * theta[i]
                else:
                    p[i, r] += (
                        R[i, r, 0] * axes[i, 0] + R[i, r, 1] * axes[i, 1] + R[i, r, 2] * axes[i, 2]
                    ) * theta[i]
        else:
            cs, sn = np.cos(theta[i]), np.sin(theta[i])
            if a >= 0:
                u = (a + 1) % 3
                v = (a + 2) % 3
                for r in range(3):
                    cu, cv = R[i, r, u], R[i, r, v]
                    R[i, r, u] = cs * cu + sn * cv
                    R[i, r, v] = cs * cv - sn * cu
            else:  # Rodrigues: Rot = c I + s [k]x + (1 - c) k k^T, row by row
                k0, k1, k2 = axes[i, 0], axes[i, 1], axes[i, 2]
                t = 1.0 - cs
                rot00, rot01, rot02 = (
                    cs + t * k0 * k0,
                    -sn * k2 + t * k0 * k1,
                    sn * k1 + t * k0 * k2,
                )
                rot10, rot11, rot12 = (
                    sn * k2 + t * k1 * k0,
                    cs + t * k1 * k1,
                    -sn * k0 + t * k1 * k2,
                )
                rot20, rot21, rot22 = (
                    -sn * k1 + t * k2 * k0,
                    sn * k0 + t * k2 * k1,
                    cs + t * k2 * k2,
                )
                for r in range(3):
                    x, y, z = R[i, r, 0], R[i, r, 1], R[i, r, 2]
                    R[i, r, 0] = x * rot00 + y * rot10 + z * rot20
                    R[i, r, 1] = x * rot01 + y * rot11 + z * rot21
                    R[i, r, 2] = x * rot02 + y * rot12 + z * rot22


@njit(cache=True, nogil=True)
def chain_fk(
    R_parent: np.ndarray,
    p_parent: np.ndarray,
    axis_index: np.ndarray,
    axes: np.ndarray,
    prismatic: np.ndarray,
    R_joint_tool: np.ndarray,
    p_joint_tool: np.ndarray,
    th: np.ndarray,
    R_tool: np.ndarray,
    p_tool: np.ndarray,
    R_frames: np.ndarray,
    p_frames: np.ndarray,
) -> None:
    """:func:`joint_frames` of each configuration ``th: (n, B)`` (a column each), in place:
    the tool's pose ``R_tool: (3, 3, B)``, ``p_tool: (3, B)`` and, unless ``R_frames`` is
    empty, every joint frame ``R_frames: (n, 3, 3, B)``, ``p_frames: (n, 3, B)``."""
    n, B = th.shape
    want = R_frames.shape[0] > 0
    R = np.empty((n, 3, 3))
    p = np.empty((n, 3))
    theta = np.empty(n)
    last = n - 1
    for b in range(B):
        for i in range(n):
            theta[i] = th[i, b]
        joint_frames(R_parent, p_parent, axis_index, axes, prismatic, theta, R, p)
        for r in range(3):
            p_tool[r, b] = (
                p[last, r]
                + R[last, r, 0] * p_joint_tool[0]
                + R[last, r, 1] * p_joint_tool[1]
                + R[last, r, 2] * p_joint_tool[2]
            )
            for c in range(3):
                R_tool[r, c, b] = (
                    R[last, r, 0] * R_joint_tool[0, c]
                    + R[last, r, 1] * R_joint_tool[1, c]
                    + R[last, r, 2] * R_joint_tool[2, c]
                )
        if want:
            for i in range(n):
                for r in range(3):
                    p_frames[i, r, b] = p[i, r]
                    for c in range(3):
                        R_frames[i, r, c, b] = R[i, r, c]

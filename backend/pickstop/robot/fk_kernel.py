"""Forward kinematics of one configuration, compiled (numba), for the compiled kernels that
walk configurations one by one (:mod:`pickstop.regions.arm_kernel`,
:mod:`pickstop.reach.ik_kernel`); the vectorised numpy FK is
:func:`pickstop.robot.kinematics.fk_soa`, and the tests hold the two together."""

from __future__ import annotations

import numpy as np
from numba import njit


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
    Rc = R_parent[0].copy()
    pc = p_parent[0].copy()
    tmp = np.empty((3, 3))
    for i in range(n):
        if i > 0:
            for r in range(3):
                pc[r] += (
                    Rc[r, 0] * p_parent[i, 0]
                    + Rc[r, 1] * p_parent[i, 1]
                    + Rc[r, 2] * p_parent[i, 2]
                )
            for r in range(3):
                for c in range(3):
                    tmp[r, c] = (
                        Rc[r, 0] * R_parent[i, 0, c]
                        + Rc[r, 1] * R_parent[i, 1, c]
                        + Rc[r, 2] * R_parent[i, 2, c]
                    )
            Rc[:, :] = tmp
        a = axis_index[i]
        if prismatic[i]:
            for r in range(3):
                if a >= 0:
                    pc[r] += Rc[r, a] * theta[i]
                else:
                    pc[r] += (
                        Rc[r, 0] * axes[i, 0] + Rc[r, 1] * axes[i, 1] + Rc[r, 2] * axes[i, 2]
                    ) * theta[i]
        else:
            cs, sn = np.cos(theta[i]), np.sin(theta[i])
            if a >= 0:
                u = (a + 1) % 3
                v = (a + 2) % 3
                for r in range(3):
                    cu, cv = Rc[r, u], Rc[r, v]
                    Rc[r, u] = cs * cu + sn * cv
                    Rc[r, v] = cs * cv - sn * cu
            else:  # Rodrigues: Rot = c I + s [k]x + (1 - c) k k^T
                k0, k1, k2 = axes[i, 0], axes[i, 1], axes[i, 2]
                rot = np.empty((3, 3))
                K = np.array([[0.0, -k2, k1], [k2, 0.0, -k0], [-k1, k0, 0.0]])
                for r in range(3):
                    for c in range(3):
                        rot[r, c] = (
                            (cs if r == c else 0.0)
                            + sn * K[r, c]
                            + (1 - cs) * (axes[i, r] * axes[i, c])
                        )
                for r in range(3):
                    for c in range(3):
                        tmp[r, c] = (
                            Rc[r, 0] * rot[0, c] + Rc[r, 1] * rot[1, c] + Rc[r, 2] * rot[2, c]
                        )
                Rc[:, :] = tmp
        R[i] = Rc
        p[i] = pc

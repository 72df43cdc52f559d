"""Forward kinematics of the arm chain over many configurations (compiled for a few, numpy for
many), its Jacobian and manipulability.

A :class:`Chain` is plain arrays extracted once from the reduced pinocchio model, so it pickles
cheaply into worker processes. ``reference_fk`` (pinocchio, one call per configuration) is the
slow, obviously correct twin that the tests compare against.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pickstop.robot.fk_kernel import chain_fk
from pickstop.robot.model import RobotModel


@dataclass(frozen=True)
class Chain:
    """Serial chain base -> joint 1 -> ... -> joint n -> tool.

    ``R_parent_joint[i], p_parent_joint[i]``: placement of joint i's frame in its parent's frame
    at zero motion. ``axes[i]``: unit axis in joint i's frame; ``axis_index[i]`` is 0/1/2 when it
    is x/y/z (fast path) else -1. ``prismatic[i]``: translation rather than rotation.
    """

    R_parent_joint: np.ndarray  # (n, 3, 3)
    p_parent_joint: np.ndarray  # (n, 3) [m]
    axes: np.ndarray  # (n, 3)
    axis_index: np.ndarray  # (n,) int
    prismatic: np.ndarray  # (n,) bool
    R_joint_tool: np.ndarray  # (3, 3) tool frame in the last joint's frame
    p_joint_tool: np.ndarray  # (3,) [m]

    @property
    def dof(self) -> int:
        return len(self.prismatic)

    @classmethod
    def from_robot(cls, robot: RobotModel) -> Chain:
        m = robot.model
        n = robot.dof
        Rs = np.stack([m.jointPlacements[i + 1].rotation for i in range(n)])
        ps = np.stack([m.jointPlacements[i + 1].translation for i in range(n)])
        axes = np.array([j.axis for j in robot.joints], dtype=float)
        idx = np.array(
            [int(np.argmax(a)) if np.count_nonzero(a) == 1 and a.max() == 1.0 else -1 for a in axes]
        )
        tool = m.frames[robot.tool_frame_id].placement
        return cls(  # C order, as the compiled kernels take them
            R_parent_joint=np.ascontiguousarray(Rs),
            p_parent_joint=np.ascontiguousarray(ps),
            axes=axes,
            axis_index=idx.astype(np.int64),
            prismatic=np.array([j.kind == "prismatic" for j in robot.joints]),
            R_joint_tool=np.ascontiguousarray(tool.rotation),
            p_joint_tool=np.ascontiguousarray(tool.translation),
        )


BLOCK = 4096  # configurations per block: keeps the working set in cache
FEW = 1024  # configurations up to which one compiled pass beats numpy (measured: 2-30x below)


_OTHER_AXES = {0: (1, 2), 1: (2, 0), 2: (0, 1)}


def _rotate_soa(R: np.ndarray, axis_index: int, axis: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """``R <- R @ Rot(axis, theta)`` for ``R: (3, 3, B)`` (rows, cols, batch), ``theta: (B,)``."""
    c, s = np.cos(theta), np.sin(theta)
    if axis_index >= 0:
        a, b = _OTHER_AXES[axis_index]
        ca = R[:, a, :].copy()
        cb = R[:, b, :]
        R[:, a, :] = c * ca + s * cb
        R[:, b, :] = c * cb - s * ca
        return R
    # Rodrigues for a general unit axis k: Rot = c I + s [k]x + (1 - c) k k^T.
    k = axis
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    Rot = c * np.eye(3)[:, :, None] + s * K[:, :, None] + (1 - c) * np.outer(k, k)[:, :, None]
    return np.einsum("ikn,kjn->ijn", R, Rot)


def _fk_numpy(
    chain: Chain, th: np.ndarray, frames: bool
) -> tuple[np.ndarray, np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
    """:func:`fk_soa` of many configurations: numpy, joint by joint over the whole batch."""
    n, B = th.shape
    R = np.repeat(chain.R_parent_joint[0][:, :, None], B, axis=2)
    p = np.repeat(chain.p_parent_joint[0][:, None], B, axis=1)
    out: list[tuple[np.ndarray, np.ndarray]] = []
    for i in range(n):
        if i > 0:
            p = p + np.einsum("k,ikn->in", chain.p_parent_joint[i], R)
            R = np.einsum("ikn,kj->ijn", R, chain.R_parent_joint[i])
        a = int(chain.axis_index[i])
        if chain.prismatic[i]:
            p = p + (R[:, a, :] if a >= 0 else np.einsum("ikn,k->in", R, chain.axes[i])) * th[i]
        else:
            R = _rotate_soa(R, a, chain.axes[i], th[i])
        if frames:
            out.append((R.copy(), p.copy()))
    p_tool = p + np.einsum("k,ikn->in", chain.p_joint_tool, R)
    R_tool = np.einsum("ikn,kj->ijn", R, chain.R_joint_tool)
    return R_tool, p_tool, out


def fk_soa(
    chain: Chain, th: np.ndarray, frames: bool = False
) -> tuple[np.ndarray, np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
    """FK in structure-of-arrays layout, the hot path: a batch of up to :data:`FEW`
    configurations compiled (:func:`~pickstop.robot.fk_kernel.chain_fk`, where numpy's calls
    would cost more than the arithmetic), more with numpy, joint by joint.

    th: (n, B) joint values [rad or m], one column per configuration.
    Returns ``R_base_tool: (3, 3, B)``, ``p_base_tool: (3, B)`` [m] and, if ``frames``, the list
    of every joint frame after its motion as ``(R: (3, 3, B), p: (3, B))``.
    """
    n, B = th.shape
    assert n == chain.dof, (th.shape, chain.dof)
    if B > FEW:
        return _fk_numpy(chain, th, frames)
    R_tool = np.empty((3, 3, B))
    p_tool = np.empty((3, B))
    R_frames = np.empty((n if frames else 0, 3, 3, B))
    p_frames = np.empty((n if frames else 0, 3, B))
    chain_fk(
        chain.R_parent_joint,
        chain.p_parent_joint,
        chain.axis_index,
        chain.axes,
        chain.prismatic,
        chain.R_joint_tool,
        chain.p_joint_tool,
        np.ascontiguousarray(th, dtype=np.float64),
        R_tool,
        p_tool,
        R_frames,
        p_frames,
    )
    return R_tool, p_tool, [(R_frames[i], p_frames[i]) for i in range(len(R_frames))]


def fk(chain: Chain, thetas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tool poses ``T_base_tool``: ``Rs: (N, 3, 3)``, ``ps: (N, 3)`` [m] for ``thetas: (N, n)``."""
    thetas = np.asarray(thetas, dtype=np.float64)
    N, n = thetas.shape
    assert n == chain.dof, (thetas.shape, chain.dof)
    Rs = np.empty((N, 3, 3))
    ps = np.empty((N, 3))
    th_all = np.ascontiguousarray(thetas.T)
    for s in range(0, N, BLOCK):
        R, p, _ = fk_soa(chain, th_all[:, s : s + BLOCK])
        Rs[s : s + BLOCK] = R.transpose(2, 0, 1)
        ps[s : s + BLOCK] = p.T
    return Rs, ps


def jacobian_soa(
    chain: Chain, frames: list[tuple[np.ndarray, np.ndarray]], p_tool: np.ndarray
) -> np.ndarray:
    """Geometric Jacobian of the tool point in the base frame from :func:`fk_soa` frames.

    Returns ``J: (6, n, B)``: rows 0-2 linear [m/rad or 1], rows 3-5 angular [1 or 0].
    """
    n = len(frames)
    B = p_tool.shape[1]
    J = np.empty((6, n, B))
    for i, (R, p) in enumerate(frames):
        a = int(chain.axis_index[i])
        axis = R[:, a, :] if a >= 0 else np.einsum("ikn,k->in", R, chain.axes[i])
        if chain.prismatic[i]:
            J[:3, i] = axis
            J[3:, i] = 0.0
        else:
            lever = p_tool - p
            J[0, i] = axis[1] * lever[2] - axis[2] * lever[1]
            J[1, i] = axis[2] * lever[0] - axis[0] * lever[2]
            J[2, i] = axis[0] * lever[1] - axis[1] * lever[0]
            J[3:, i] = axis
    return J


def manipulability_soa(
    chain: Chain, frames: list[tuple[np.ndarray, np.ndarray]], p_tool: np.ndarray
) -> np.ndarray:
    """Yoshikawa's ``sqrt(det(J J^T))`` from :func:`fk_soa` frames, ``(B,)``.

    The determinant comes from a batched Cholesky factorisation of the 6 x 6 ``J J^T``.
    """
    J = jacobian_soa(chain, frames, p_tool)
    B = p_tool.shape[1]
    A = np.einsum("ajn,bjn->abn", J, J)
    det = np.ones(B)
    L = np.zeros_like(A)
    for j in range(6):
        d = A[j, j] - np.einsum("kn,kn->n", L[j, :j], L[j, :j])
        d = np.maximum(d, 1e-300)
        det *= d
        L[j, j] = np.sqrt(d)
        for i in range(j + 1, 6):
            L[i, j] = (A[i, j] - np.einsum("kn,kn->n", L[i, :j], L[j, :j])) / L[j, j]
    det = np.where(det < 1e-200, 0.0, det)
    return np.sqrt(det)


def manipulability(chain: Chain, thetas: np.ndarray) -> np.ndarray:
    """Yoshikawa's manipulability ``(N,)`` of the tool for ``thetas: (N, n)``."""
    thetas = np.asarray(thetas, dtype=np.float64)
    N, n = thetas.shape
    assert n == chain.dof, (thetas.shape, chain.dof)
    out = np.empty(N)
    th_all = np.ascontiguousarray(thetas.T)
    for s in range(0, N, BLOCK):
        _, p, frames = fk_soa(chain, th_all[:, s : s + BLOCK], frames=True)
        out[s : s + BLOCK] = manipulability_soa(chain, frames, p)
    return out


def reference_fk(robot: RobotModel, theta: np.ndarray) -> pin.SE3:
    """Tool pose of one configuration with pinocchio (the reference for :func:`fk`)."""
    data = robot.model.createData()
    q = robot.angles_to_q(np.asarray(theta, dtype=float))
    pin.framesForwardKinematics(robot.model, data, q)
    return data.oMf[robot.tool_frame_id].copy()


def reference_manipulability(robot: RobotModel, theta: np.ndarray) -> float:
    """Manipulability of one configuration with pinocchio's Jacobian."""
    data = robot.model.createData()
    q = robot.angles_to_q(np.asarray(theta, dtype=float))
    J = pin.computeFrameJacobian(
        robot.model, data, q, robot.tool_frame_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    )
    # pinocchio's columns are per velocity coordinate; continuous joints have one, like ours.
    return float(np.sqrt(max(np.linalg.det(J @ J.T), 0.0)))

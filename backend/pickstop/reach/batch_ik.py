"""Damped least squares IK for many targets at once (the same FK as the build): the
iterations compiled row by row (:mod:`pickstop.reach.ik_kernel`), the result judged on the
numpy FK.

Used where thousands of problems are solved together: refining database candidates of every
base cell of a region, the single-seed baseline and the multi-start oracle. The one-target
solver with pinocchio is :mod:`pickstop.reach.ik`; both are tested against each other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pickstop.reach.ik import POS_TOL, ROT_TOL
from pickstop.reach.ik_kernel import refine_rows
from pickstop.reach.so3 import matrices_to_quats
from pickstop.robot.kinematics import Chain, fk_soa
from pickstop.robot.model import RobotModel


@dataclass(frozen=True)
class BatchSolver:
    """One robot's chain and limits, as arrays."""

    chain: Chain
    lower: np.ndarray  # (n,)
    upper: np.ndarray  # (n,)
    continuous: np.ndarray  # (n,) bool

    @classmethod
    def of(cls, robot: RobotModel) -> BatchSolver:
        return cls(
            Chain.from_robot(robot),
            robot.lower,
            robot.upper,
            np.array([j.kind == "continuous" for j in robot.joints]),
        )


@dataclass(frozen=True)
class BatchResult:
    thetas: np.ndarray  # (B, n) [rad or m]
    success: np.ndarray  # (B,) within both tolerances and the joint limits
    pos_err: np.ndarray  # (B,) [m]
    rot_err: np.ndarray  # (B,) [rad]
    iterations: np.ndarray  # (B,)


def _errors(
    R: np.ndarray, p: np.ndarray, R_t: np.ndarray, p_t: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """6D error ``(6, B)`` (target minus current, base frame) and rotation angle ``(B,)``.

    All structure-of-arrays: ``R, R_t: (3, 3, B)`` current and target, ``p, p_t: (3, B)``.
    The rotation error is the log of ``R_t R^T`` from its trace and skew part; the few near a
    half turn, where that loses its axis, go through the quaternion.
    """
    E = np.einsum("ikb,jkb->ijb", R_t, R)  # R_t R^T, in the base frame
    v = 0.5 * np.stack([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])  # sin(a) axis
    sv = np.sqrt(np.einsum("ib,ib->b", v, v))
    angle = np.arctan2(sv, 0.5 * (E[0, 0] + E[1, 1] + E[2, 2] - 1.0))
    e = np.empty((6, len(angle)))
    e[:3] = p_t - p
    e[3:] = v * np.where(sv > 1e-12, angle / np.maximum(sv, 1e-300), 1.0)
    flip = np.flatnonzero(angle > 3.0)
    if len(flip):
        q = matrices_to_quats(E[:, :, flip].transpose(2, 0, 1))
        sq = np.linalg.norm(q[:, 1:], axis=1)
        a = 2.0 * np.arctan2(sq, q[:, 0])
        e[3:, flip] = (q[:, 1:] * np.where(sq > 1e-12, a / np.maximum(sq, 1e-300), 2.0)[:, None]).T
        angle[flip] = a
    return e, angle


def refine_batch(
    solver: BatchSolver,
    thetas0: np.ndarray,
    Rs_target: np.ndarray,
    ps_target: np.ndarray,
    *,
    pos_tol: float = POS_TOL,
    rot_tol: float = ROT_TOL,
    max_iter: int = 30,
    damping: float = 1e-4,
    max_step: float = 0.3,
    give_up: tuple[tuple[int, float], ...] = (),
) -> BatchResult:
    """Refine ``thetas0: (B, n)`` towards ``T_base_tool`` targets ``(B, 3, 3)``, ``(B, 3)``.

    Levenberg-Marquardt style: damping grows where a step fails to reduce the error. Joint
    values stay within limits (continuous joints wrap into theirs). Success is judged on the
    final FK, so ``success`` is honest whatever the iterations did.

    give_up: ``((k, err), ...)``: after ``k`` iterations, rows still farther than ``err`` [m]
    from their target (position error plus 0.1 m per radian of rotation error) stop. Seeds
    that converge are within millimetres by then; the rest mostly slide along a joint limit.
    """
    th = np.array(thetas0, dtype=np.float64)
    B, n = th.shape
    assert n == solver.chain.dof and Rs_target.shape == (B, 3, 3) and ps_target.shape == (B, 3)
    iters = np.zeros(B, np.int64)
    chain = solver.chain
    refine_rows(
        chain.R_parent_joint, chain.p_parent_joint, chain.axis_index.astype(np.int64),
        chain.axes, chain.prismatic, chain.R_joint_tool, chain.p_joint_tool, solver.lower,
        solver.upper, solver.continuous, th, np.ascontiguousarray(Rs_target, dtype=float),
        np.ascontiguousarray(ps_target, dtype=float), pos_tol, rot_tol, max_iter, damping,
        max_step, np.array([k for k, _ in give_up], np.int64),
        np.array([err for _, err in give_up], float), iters,
    )  # fmt: skip
    Rs_t = np.ascontiguousarray(Rs_target.transpose(1, 2, 0))  # (3, 3, B)
    ps_t = np.ascontiguousarray(ps_target.T)  # (3, B)
    Rf, pf, _ = fk_soa(solver.chain, np.ascontiguousarray(th.T))
    ef, angf = _errors(Rf, pf, Rs_t, ps_t)
    pos_err = np.linalg.norm(ef[:3], axis=0)
    inside = np.all((th >= solver.lower - 1e-12) & (th <= solver.upper + 1e-12), axis=1)
    ok = (pos_err <= pos_tol) & (angf <= rot_tol) & inside
    return BatchResult(th, ok, pos_err, angf, iters)

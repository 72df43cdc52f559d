"""Damped least squares IK for many targets at once (numpy, the same FK as the build).

Used where thousands of problems are solved together: refining database candidates of every
base cell of a region, the single-seed baseline and the multi-start oracle. The one-target
solver with pinocchio is :mod:`pickstop.reach.ik`; both are tested against each other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pickstop.reach.ik import POS_TOL, ROT_TOL
from pickstop.reach.so3 import matrices_to_quats
from pickstop.robot.kinematics import Chain, fk_soa, jacobian_soa
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


def _dls_step(J: np.ndarray, e: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """``J^T (J J^T + lam I)^-1 e`` for ``J: (A, 6, n)``, ``e: (A, 6, 1)``, ``lam: (A,)``."""
    JJt = np.matmul(J, J.transpose(0, 2, 1))
    JJt[:, range(6), range(6)] += lam[:, None]
    return np.matmul(J.transpose(0, 2, 1), np.linalg.solve(JJt, e))[:, :, 0]


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
    Rs_t = np.ascontiguousarray(Rs_target.transpose(1, 2, 0))  # (3, 3, B)
    ps_t = np.ascontiguousarray(ps_target.T)  # (3, B)
    lam = np.full(B, damping)
    iters = np.zeros(B, np.int64)
    R, p, frames = fk_soa(solver.chain, np.ascontiguousarray(th.T), frames=True)
    e, ang = _errors(R, p, Rs_t, ps_t)
    cost = np.einsum("ib,ib->b", e, e)
    done = (np.linalg.norm(e[:3], axis=0) < pos_tol * 0.5) & (ang < rot_tol * 0.5)
    span = solver.upper - solver.lower
    for it in range(max_iter):
        for k, err in give_up:
            if it == k:
                done |= np.linalg.norm(e[:3], axis=0) + 0.1 * ang > err
        act = np.flatnonzero(~done)
        if len(act) == 0:
            break
        iters[act] += 1
        fr = [(Rj[:, :, act], pj[:, act]) for Rj, pj in frames]
        J = jacobian_soa(solver.chain, fr, p[:, act]).transpose(2, 0, 1)  # (A, 6, n)
        ea = e[:, act].T[:, :, None]
        step = _dls_step(J, ea, lam[act])
        # Joints pinned at a limit and pushed outwards leave the step; solve for the rest.
        ta = th[act]
        blocked = ((ta <= solver.lower + 1e-9) & (step < 0)) | (
            (ta >= solver.upper - 1e-9) & (step > 0)
        )
        blocked &= ~solver.continuous
        rows = np.flatnonzero(blocked.any(axis=1))
        if len(rows):
            Jb = J[rows] * ~blocked[rows][:, None, :]
            step[rows] = _dls_step(Jb, ea[rows], lam[act][rows])
        big = np.abs(step).max(axis=1)
        step *= np.minimum(1.0, max_step / np.maximum(big, 1e-12))[:, None]
        trial = th[act] + step
        cont = solver.continuous
        if cont.any():
            trial[:, cont] = solver.lower[cont] + np.mod(
                trial[:, cont] - solver.lower[cont], span[cont]
            )
        trial = np.clip(trial, solver.lower, solver.upper)
        Rn, pn, frn = fk_soa(solver.chain, np.ascontiguousarray(trial.T), frames=True)
        en, angn = _errors(Rn, pn, Rs_t[:, :, act], ps_t[:, act])
        cn = np.einsum("ib,ib->b", en, en)
        better = cn < cost[act]
        acc = act[better]
        th[acc] = trial[better]
        cost[acc] = cn[better]
        e[:, acc] = en[:, better]
        ang[acc] = angn[better]
        p[:, acc] = pn[:, better]
        R[:, :, acc] = Rn[:, :, better]
        for (Rj, pj), (Rk, pk) in zip(frames, frn, strict=True):
            Rj[:, :, acc] = Rk[:, :, better]
            pj[:, acc] = pk[:, better]
        lam[acc] = np.maximum(lam[acc] * 0.3, damping)
        lam[act[~better]] *= 10.0
        done[acc] = (np.linalg.norm(e[:3, acc], axis=0) < pos_tol * 0.5) & (
            ang[acc] < rot_tol * 0.5
        )
        done[act[~better]] |= lam[act[~better]] > 1e3  # stalled
    Rf, pf, _ = fk_soa(solver.chain, np.ascontiguousarray(th.T))
    ef, angf = _errors(Rf, pf, Rs_t, ps_t)
    pos_err = np.linalg.norm(ef[:3], axis=0)
    inside = np.all((th >= solver.lower - 1e-12) & (th <= solver.upper + 1e-12), axis=1)
    ok = (pos_err <= pos_tol) & (angf <= rot_tol) & inside
    return BatchResult(th, ok, pos_err, angf, iters)

"""The damped least squares iterations of :func:`pickstop.reach.batch_ik.refine_batch`,
compiled (numba), one row at a time: the same forward kinematics, Jacobian, error, step,
limits and damping schedule as the numpy batch, without a batch of numpy calls per iteration
(a refinement of a few dozen seeds was mostly those calls). The caller judges the result on
its own forward kinematics."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from pickstop.robot.fk_kernel import joint_frames


@njit(cache=True, nogil=True)
def _tool(
    Rj: np.ndarray, pj: np.ndarray, R_joint_tool: np.ndarray, p_joint_tool: np.ndarray,
    R: np.ndarray, p: np.ndarray,
) -> None:  # fmt: skip
    """The tool frame ``R (3, 3), p (3,)`` from the last joint's ``Rj, pj``."""
    for r in range(3):
        p[r] = (
            pj[r]
            + Rj[r, 0] * p_joint_tool[0]
            + Rj[r, 1] * p_joint_tool[1]
            + (Rj[r, 2] * p_joint_tool[2])
        )
        for c in range(3):
            R[r, c] = (
                Rj[r, 0] * R_joint_tool[0, c]
                + Rj[r, 1] * R_joint_tool[1, c]
                + Rj[r, 2] * R_joint_tool[2, c]
            )


@njit(cache=True, nogil=True)
def _error(R: np.ndarray, p: np.ndarray, Rt: np.ndarray, pt: np.ndarray, e: np.ndarray) -> float:
    """``e (6,)``: target minus current (position, rotation vector of ``Rt R^T``); returns
    the rotation angle. Near a half turn the axis comes from the quaternion, as
    :func:`pickstop.reach.batch_ik._errors` does."""
    E = np.empty((3, 3))
    for r in range(3):
        for c in range(3):
            E[r, c] = Rt[r, 0] * R[c, 0] + Rt[r, 1] * R[c, 1] + Rt[r, 2] * R[c, 2]
    v0 = 0.5 * (E[2, 1] - E[1, 2])
    v1 = 0.5 * (E[0, 2] - E[2, 0])
    v2 = 0.5 * (E[1, 0] - E[0, 1])
    sv = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    angle = math.atan2(sv, 0.5 * (E[0, 0] + E[1, 1] + E[2, 2] - 1.0))
    for r in range(3):
        e[r] = pt[r] - p[r]
    f = angle / max(sv, 1e-300) if sv > 1e-12 else 1.0
    e[3], e[4], e[5] = v0 * f, v1 * f, v2 * f
    if angle > 3.0:
        # the quaternion (Shepperd), as pickstop.reach.so3.matrices_to_quats
        m00, m11, m22 = E[0, 0], E[1, 1], E[2, 2]
        t0, t1, t2, t3 = (
            1 + m00 + m11 + m22,
            1 + m00 - m11 - m22,
            1 - m00 + m11 - m22,
            (1 - m00 - m11 + m22),
        )
        k, tk = 0, t0
        if t1 > tk:
            k, tk = 1, t1
        if t2 > tk:
            k, tk = 2, t2
        if t3 > tk:
            k, tk = 3, t3
        s = math.sqrt(max(tk, 1e-300))
        d21, d02, d10 = E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]
        s21, s02, s10 = E[2, 1] + E[1, 2], E[0, 2] + E[2, 0], E[1, 0] + E[0, 1]
        if k == 0:
            q = (s, d21 / s, d02 / s, d10 / s)
        elif k == 1:
            q = (d21 / s, s, s10 / s, s02 / s)
        elif k == 2:
            q = (d02 / s, s10 / s, s, s21 / s)
        else:
            q = (d10 / s, s02 / s, s21 / s, s)
        norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
        sign = -1.0 if q[0] < 0 else 1.0
        w, x, y, z = (sign * q[0] / norm, sign * q[1] / norm, sign * q[2] / norm,
                      sign * q[3] / norm)  # fmt: skip
        sq = math.sqrt(x * x + y * y + z * z)
        a = 2.0 * math.atan2(sq, w)
        g = a / max(sq, 1e-300) if sq > 1e-12 else 2.0
        e[3], e[4], e[5] = x * g, y * g, z * g
        angle = a
    return angle


@njit(cache=True, nogil=True)
def _jacobian(
    Rj: np.ndarray, pj: np.ndarray, p_tool: np.ndarray, axis_index: np.ndarray,
    axes: np.ndarray, prismatic: np.ndarray, J: np.ndarray,
) -> None:  # fmt: skip
    """``J (6, n)`` of the tool point, as :func:`pickstop.robot.kinematics.jacobian_soa`."""
    n = J.shape[1]
    for i in range(n):
        a = axis_index[i]
        if a >= 0:
            ax0, ax1, ax2 = Rj[i, 0, a], Rj[i, 1, a], Rj[i, 2, a]
        else:
            ax0 = Rj[i, 0, 0] * axes[i, 0] + Rj[i, 0, 1] * axes[i, 1] + Rj[i, 0, 2] * axes[i, 2]
            ax1 = Rj[i, 1, 0] * axes[i, 0] + Rj[i, 1, 1] * axes[i, 1] + Rj[i, 1, 2] * axes[i, 2]
            ax2 = Rj[i, 2, 0] * axes[i, 0] + Rj[i, 2, 1] * axes[i, 1] + Rj[i, 2, 2] * axes[i, 2]
        if prismatic[i]:
            J[0, i], J[1, i], J[2, i] = ax0, ax1, ax2
            J[3, i] = J[4, i] = J[5, i] = 0.0
        else:
            l0, l1, l2 = p_tool[0] - pj[i, 0], p_tool[1] - pj[i, 1], p_tool[2] - pj[i, 2]
            J[0, i] = ax1 * l2 - ax2 * l1
            J[1, i] = ax2 * l0 - ax0 * l2
            J[2, i] = ax0 * l1 - ax1 * l0
            J[3, i], J[4, i], J[5, i] = ax0, ax1, ax2


@njit(cache=True, nogil=True)
def _dls(J: np.ndarray, e: np.ndarray, lam: float, step: np.ndarray) -> None:
    """``step = J^T (J J^T + lam I)^-1 e``."""
    A = J @ J.T
    for r in range(6):
        A[r, r] += lam
    x = np.linalg.solve(A, e)
    step[:] = J.T @ x


@njit(cache=True, nogil=True)
def refine_rows(
    R_parent: np.ndarray,
    p_parent: np.ndarray,
    axis_index: np.ndarray,
    axes: np.ndarray,
    prismatic: np.ndarray,
    R_joint_tool: np.ndarray,
    p_joint_tool: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    continuous: np.ndarray,
    th: np.ndarray,
    Rs_t: np.ndarray,
    ps_t: np.ndarray,
    pos_tol: float,
    rot_tol: float,
    max_iter: int,
    damping: float,
    max_step: float,
    give_up_at: np.ndarray,
    give_up_err: np.ndarray,
    iters: np.ndarray,
) -> None:
    """In place: ``th (B, n)`` refined towards ``Rs_t (B, 3, 3)``, ``ps_t (B, 3)``,
    ``iters (B,)`` the iterations each took (:func:`~pickstop.reach.batch_ik.refine_batch`)."""
    B, n = th.shape
    Rj = np.empty((n, 3, 3))
    pj = np.empty((n, 3))
    Rn = np.empty((n, 3, 3))
    pn = np.empty((n, 3))
    R = np.empty((3, 3))
    p = np.empty(3)
    Rtr = np.empty((3, 3))
    ptr = np.empty(3)
    e = np.empty(6)
    en = np.empty(6)
    J = np.empty((6, n))
    Jb = np.empty((6, n))
    step = np.empty(n)
    trial = np.empty(n)
    blocked = np.zeros(n, np.bool_)
    for b in range(B):
        joint_frames(R_parent, p_parent, axis_index, axes, prismatic, th[b], Rj, pj)
        _tool(Rj[n - 1], pj[n - 1], R_joint_tool, p_joint_tool, R, p)
        ang = _error(R, p, Rs_t[b], ps_t[b], e)
        cost = 0.0
        for r in range(6):
            cost += e[r] * e[r]
        lam = damping
        done = math.sqrt(e[0] ** 2 + e[1] ** 2 + e[2] ** 2) < pos_tol * 0.5 and (
            ang < rot_tol * 0.5
        )
        for it in range(max_iter):
            for g in range(give_up_at.shape[0]):
                if it == give_up_at[g] and (
                    math.sqrt(e[0] ** 2 + e[1] ** 2 + e[2] ** 2) + 0.1 * ang > give_up_err[g]
                ):
                    done = True
            if done:
                break
            iters[b] += 1
            _jacobian(Rj, pj, p, axis_index, axes, prismatic, J)
            _dls(J, e, lam, step)
            # Joints pinned at a limit and pushed outwards leave the step; solve for the rest.
            any_blocked = False
            for i in range(n):
                blocked[i] = not continuous[i] and (
                    (th[b, i] <= lower[i] + 1e-9 and step[i] < 0)
                    or (th[b, i] >= upper[i] - 1e-9 and step[i] > 0)
                )
                any_blocked |= blocked[i]
            if any_blocked:
                for r in range(6):
                    for i in range(n):
                        Jb[r, i] = 0.0 if blocked[i] else J[r, i]
                _dls(Jb, e, lam, step)
            big = 0.0
            for i in range(n):
                big = max(big, abs(step[i]))
            scale = min(1.0, max_step / max(big, 1e-12))
            for i in range(n):
                t = th[b, i] + step[i] * scale
                if continuous[i]:
                    span = upper[i] - lower[i]
                    t = lower[i] + (t - lower[i]) % span
                trial[i] = min(max(t, lower[i]), upper[i])
            joint_frames(R_parent, p_parent, axis_index, axes, prismatic, trial, Rn, pn)
            _tool(Rn[n - 1], pn[n - 1], R_joint_tool, p_joint_tool, Rtr, ptr)
            angn = _error(Rtr, ptr, Rs_t[b], ps_t[b], en)
            cn = 0.0
            for r in range(6):
                cn += en[r] * en[r]
            if cn < cost:
                th[b] = trial
                cost = cn
                e[:] = en
                ang = angn
                R[:, :] = Rtr
                p[:] = ptr
                Rj[:, :, :] = Rn
                pj[:, :] = pn
                lam = max(lam * 0.3, damping)
                done = math.sqrt(e[0] ** 2 + e[1] ** 2 + e[2] ** 2) < pos_tol * 0.5 and (
                    ang < rot_tol * 0.5
                )
            else:
                lam *= 10.0
                done = lam > 1e3  # stalled

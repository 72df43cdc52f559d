"""Numerical inverse kinematics of the arm: damped least squares with adaptive damping.

The error is pinocchio's ``log6`` of the tool-to-target transform, expressed in the tool frame,
with its exact Jacobian ``-Jlog6 @ J_local`` (as in pinocchio's own IK example). Each step solves
``(J^T J + lam I) dq = -J^T e`` with Levenberg-Marquardt damping ``lam = mu * cost + damping``
(Sugihara's choice: large far away, vanishing near a solution so the last steps are Gauss-Newton),
keeps a step only if it lowers the cost, and clamps to the joint limits. Joints pressed against a
limit are dropped from the step (a one-pass active set) so the others keep converging.

Each joint has one velocity coordinate, so stepping the angles ``theta + dq`` and rebuilding
pinocchio's ``q`` is exactly ``pin.integrate`` (continuous joints get a valid cos/sin pair by
construction); continuous angles are then wrapped into the robot's continuous limits.

Success is judged only on a final pinocchio FK of the returned configuration: position error
``<= pos_tol`` [m], rotation angle ``<= rot_tol`` [rad] and every joint within its limits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pickstop.errors import InputError, QueryError
from pickstop.robot.model import RobotModel

POS_TOL = 1e-3  # [m]
ROT_TOL = math.radians(0.5)  # [rad]
DAMPING = 1e-6  # floor of the LM damping [m^2 ~ rad^2]
MAX_STEP = 0.5  # largest change of one joint in one step [rad or m]
_LIMIT_EPS = 1e-9  # slack on joint limits [rad or m]
_ROTATION_TOL = 1e-6  # allowed deviation of R^T R from the identity
_STALL_RATIO = 1e-3  # an accepted step improving the cost by less than this is no progress
_STALL_STEPS = 3  # consecutive steps without progress before giving up
_MU_MAX = 1e8  # rejections push mu up to here before giving up
_MAX_NUDGES = 2  # times a solve stalled against joint limits steps back inside and goes on
_NUDGE = 0.1  # that step back [rad], at most a quarter of the joint's range


@dataclass(frozen=True)
class IKResult:
    """Outcome of one IK solve.

    ``theta: (dof,)`` the final configuration [rad or m] (the best one reached, also on failure).
    ``pos_err`` [m] and ``rot_err`` [rad] come from a final pinocchio FK of ``theta``.
    ``iterations``: FK + Jacobian evaluations spent. ``reason``: ``"converged"``, ``"max_iter"``,
    ``"stalled"`` (a local minimum of the error: often an unreachable pose), ``"joint_limits"``
    (stalled with joints pressed against their limits) or ``"numerical"``.
    ``seed_index``: which seed of :func:`refine_many` produced it (0 for a single seed).
    """

    success: bool
    theta: np.ndarray
    pos_err: float
    rot_err: float
    iterations: int
    reason: str
    seed_index: int = 0


def check_target(R_target: np.ndarray, p_target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Validate a pose target ``R_base_tool: (3, 3)``, ``p_base_tool: (3,)`` [m] or raise."""
    R = np.asarray(R_target, dtype=np.float64)
    p = np.asarray(p_target, dtype=np.float64)
    if R.shape != (3, 3):
        raise QueryError(f"R_target must have shape (3, 3), got {R.shape}", field="R_target")
    if p.shape != (3,):
        raise QueryError(f"p_target must have shape (3,), got {p.shape}", field="p_target")
    if not np.isfinite(R).all():
        raise QueryError("R_target contains NaN or infinite values", field="R_target")
    if not np.isfinite(p).all():
        raise QueryError("p_target contains NaN or infinite values", field="p_target")
    dev = float(np.abs(R.T @ R - np.eye(3)).max())
    if dev > _ROTATION_TOL or np.linalg.det(R) <= 0:
        raise QueryError(
            f"R_target is not a rotation matrix (|R^T R - I| = {dev:.2e}, det = "
            f"{np.linalg.det(R):.3f})",
            field="R_target",
        )
    return np.ascontiguousarray(R), np.ascontiguousarray(p)


@dataclass(frozen=True)
class _Point:
    """One configuration of the LM loop: ``theta: (dof,)`` [rad or m], error ``e: (6,)``, its
    Jacobian ``J: (6, dof)``, position [m] and rotation [rad] errors, and ``cost = e.e / 2``."""

    theta: np.ndarray
    e: np.ndarray
    J: np.ndarray
    pos_err: float
    rot_err: float
    cost: float

    def within(self, pos_tol: float, rot_tol: float) -> bool:
        return self.pos_err <= pos_tol and self.rot_err <= rot_tol


def _check_thetas(thetas: np.ndarray, dof: int, name: str, batched: bool) -> np.ndarray:
    th = np.asarray(thetas, dtype=np.float64)
    want = "(k, dof)" if batched else "(dof,)"
    ok = (
        (th.ndim == 2 and th.shape[0] >= 1 and th.shape[1] == dof)
        if batched
        else th.shape == (dof,)
    )
    if not ok:
        raise QueryError(
            f"{name} must have shape {want} with dof={dof}, got {th.shape}", field=name
        )
    if not np.isfinite(th).all():
        raise QueryError(f"{name} contains NaN or infinite values", field=name)
    return th


def _check_options(pos_tol: float, rot_tol: float, max_iter: int, damping: float) -> None:
    for name, v in (("pos_tol", pos_tol), ("rot_tol", rot_tol), ("damping", damping)):
        if not (math.isfinite(v) and v > 0):
            raise InputError(f"{name} must be a positive number, got {v}", field=name)
    if max_iter < 0:
        raise InputError(f"max_iter must be >= 0, got {max_iter}", field="max_iter")


def _score(r: IKResult, pos_tol: float, rot_tol: float) -> tuple[bool, float]:
    """Sort key: successes first, then the smaller error relative to the tolerances."""
    return (not r.success, max(r.pos_err / pos_tol, r.rot_err / rot_tol))


class Refiner:
    """IK solver bound to one robot, holding one pinocchio ``data`` (never share across threads)."""

    def __init__(self, robot: RobotModel) -> None:
        self.robot = robot
        self.model = robot.model
        self.data = robot.model.createData()
        self.frame_id = robot.tool_frame_id
        self.dof = robot.dof
        self.lower = robot.lower
        self.upper = robot.upper
        kinds = [j.kind for j in robot.joints]
        # Continuous joints: wrap into [centre - pi, centre + pi) before clamping (a no-op clamp
        # when the continuous limits span a full turn).
        self._cont = np.array([k == "continuous" for k in kinds])
        self._cont_i = np.flatnonzero(self._cont)
        self._centre = 0.5 * (self.lower + self.upper)
        # Joints whose limits can stop a step (not a full-turn continuous joint).
        self._bounded = ~(self._cont & (self.upper - self.lower >= 2 * math.pi - 1e-9))
        one = [i for i, j in enumerate(robot.joints) if j.nq == 1]
        two = [i for i, j in enumerate(robot.joints) if j.nq == 2]
        self._one_i = np.array(one, dtype=int)
        self._one_q = np.array([robot.joints[i].idx_q for i in one], dtype=int)
        self._two_i = np.array(two, dtype=int)
        self._two_q = np.array([robot.joints[i].idx_q for i in two], dtype=int)
        self._eye = np.eye(self.dof)
        self._nudge = np.minimum(_NUDGE, 0.25 * (self.upper - self.lower))

    # -- kinematics ---------------------------------------------------------------------------

    def project(self, theta: np.ndarray) -> np.ndarray:
        """Wrap continuous joints and clamp every joint into its limits, ``(dof,)``."""
        th = np.array(theta, dtype=np.float64)
        if self._cont_i.size:
            c = self._centre[self._cont_i]
            th[self._cont_i] = c + np.mod(th[self._cont_i] - c + np.pi, 2 * np.pi) - np.pi
        return np.minimum(np.maximum(th, self.lower), self.upper)

    def _q(self, theta: np.ndarray) -> np.ndarray:
        q = np.empty(self.model.nq)
        q[self._one_q] = theta[self._one_i]
        a = theta[self._two_i]
        q[self._two_q] = np.cos(a)
        q[self._two_q + 1] = np.sin(a)
        return q

    def pose(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tool pose by pinocchio FK: ``R_base_tool: (3, 3)``, ``p_base_tool: (3,)`` [m]."""
        pin.framesForwardKinematics(self.model, self.data, self._q(theta))
        T_base_tool = self.data.oMf[self.frame_id]
        return T_base_tool.rotation.copy(), T_base_tool.translation.copy()

    def _eval(
        self, theta: np.ndarray, oMdes: pin.SE3
    ) -> tuple[np.ndarray, np.ndarray, float, float]:
        """Error ``e: (6,)``, its Jacobian ``(6, dof)``, position [m] and rotation [rad] errors."""
        pin.computeJointJacobians(self.model, self.data, self._q(theta))
        oMf = pin.updateFramePlacement(self.model, self.data, self.frame_id)
        fMd = oMf.actInv(oMdes)
        e = pin.log6(fMd).vector
        J = -pin.Jlog6(fMd.inverse()) @ pin.getFrameJacobian(
            self.model, self.data, self.frame_id, pin.ReferenceFrame.LOCAL
        )
        pos_err = float(np.linalg.norm(oMdes.translation - oMf.translation))
        rot_err = float(np.linalg.norm(pin.log3(fMd.rotation)))
        return e, J, pos_err, rot_err

    # -- solvers ------------------------------------------------------------------------------

    def refine(
        self,
        theta0: np.ndarray,
        R_target: np.ndarray,
        p_target: np.ndarray,
        *,
        pos_tol: float = POS_TOL,
        rot_tol: float = ROT_TOL,
        max_iter: int = 100,
        damping: float = DAMPING,
    ) -> IKResult:
        """Refine ``theta0: (dof,)`` [rad or m] to the tool pose ``R_target``, ``p_target`` [m].

        ``theta0`` is first projected into the joint limits. ``damping`` is the floor of the LM
        damping; the rest scales with the current squared error.
        """
        theta = self.project(_check_thetas(theta0, self.dof, "theta0", batched=False))
        R, p = check_target(R_target, p_target)
        _check_options(pos_tol, rot_tol, max_iter, damping)
        return self._refine(theta, pin.SE3(R, p), pos_tol, rot_tol, max_iter, damping)

    def _refine(
        self,
        theta: np.ndarray,
        oMdes: pin.SE3,
        pos_tol: float,
        rot_tol: float,
        max_iter: int,
        damping: float,
    ) -> IKResult:
        """The LM loop from ``theta: (dof,)`` (within limits) to ``oMdes``, judged at the end
        by :meth:`_verify`; stalled against joint limits, it steps back inside and goes on."""
        x = self._at(theta, oMdes)
        best = x
        mu, n_eval, nudges, no_progress = 1.0, 1, _MAX_NUDGES, 0
        reason = "max_iter"
        lo_b, hi_b = self.lower + _LIMIT_EPS, self.upper - _LIMIT_EPS
        while True:
            if x.within(pos_tol, rot_tol):
                reason = "converged"
                break
            if not math.isfinite(x.cost):
                reason = "numerical"
                break
            if n_eval > max_iter:
                break
            dq, blocked = self._step(x.theta, x.e, x.J, mu * x.cost + damping, lo_b, hi_b)
            cand = self.project(x.theta + dq)
            stalled = float(np.abs(cand - x.theta).max()) < 1e-12
            if not stalled:
                c = self._at(cand, oMdes)
                n_eval += 1
                if c.cost < x.cost:
                    no_progress = no_progress + 1 if x.cost - c.cost < _STALL_RATIO * x.cost else 0
                    x = c
                    mu = max(mu / 3.0, 1e-3)
                else:
                    mu *= 4.0
                stalled = (no_progress >= _STALL_STEPS or mu > _MU_MAX) and not x.within(
                    pos_tol, rot_tol
                )
            if not stalled:
                continue
            if not blocked.any():
                reason = "stalled"
                break
            if nudges == 0 or n_eval > max_iter:
                reason = "joint_limits"
                break
            nudges -= 1
            if x.cost < best.cost:
                best = x
            x = self._nudged(x.theta, blocked, hi_b, oMdes)
            n_eval += 1
            mu, no_progress = 1.0, 0
        theta = best.theta if reason != "converged" and best.cost < x.cost else x.theta
        return self._verify(theta, oMdes, pos_tol, rot_tol, n_eval - 1, reason)

    def _at(self, theta: np.ndarray, oMdes: pin.SE3) -> _Point:
        """The loop's view of ``theta: (dof,)``: its error to ``oMdes``, Jacobian and cost."""
        e, J, pos_err, rot_err = self._eval(theta, oMdes)
        return _Point(theta, e, J, pos_err, rot_err, 0.5 * float(e @ e))

    def _nudged(
        self, theta: np.ndarray, blocked: np.ndarray, hi_b: np.ndarray, oMdes: pin.SE3
    ) -> _Point:
        """``theta: (dof,)`` with its ``blocked`` joints stepped back inside their limits.

        Pressed against limits (typically a straight elbow, where the gradient cannot tell
        which way to bend), the loop carries on from there."""
        inward = np.where(theta >= hi_b, -1.0, 1.0)
        return self._at(self.project(theta + np.where(blocked, inward * self._nudge, 0.0)), oMdes)

    def _step(
        self,
        theta: np.ndarray,
        e: np.ndarray,
        J: np.ndarray,
        lam: float,
        lo_b: np.ndarray,
        hi_b: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Damped step ``dq: (dof,)`` and the mask of joints held at a limit it pushed against."""
        g = J.T @ e
        H = J.T @ J
        dq = np.linalg.solve(H + lam * self._eye, -g)
        blocked = self._bounded & (((theta <= lo_b) & (dq < 0)) | ((theta >= hi_b) & (dq > 0)))
        if blocked.any():
            # Drop the blocked joints and solve again for the others.
            free = ~blocked
            dq = np.zeros(self.dof)
            if free.any():
                Hf = H[np.ix_(free, free)] + lam * np.eye(int(free.sum()))
                dq[free] = np.linalg.solve(Hf, -g[free])
        big = float(np.abs(dq).max())
        if big > MAX_STEP:
            dq *= MAX_STEP / big
        return dq, blocked

    def _verify(
        self,
        theta: np.ndarray,
        oMdes: pin.SE3,
        pos_tol: float,
        rot_tol: float,
        it: int,
        reason: str,
    ) -> IKResult:
        """Judge ``theta`` on a fresh pinocchio FK, whatever the loop believed."""
        R, p = self.pose(theta)
        pos_err = float(np.linalg.norm(oMdes.translation - p))
        rot_err = float(np.linalg.norm(pin.log3(R.T @ oMdes.rotation)))
        in_limits = bool(
            np.all(theta >= self.lower - _LIMIT_EPS) and np.all(theta <= self.upper + _LIMIT_EPS)
        )
        success = pos_err <= pos_tol and rot_err <= rot_tol and in_limits
        if reason == "converged" and not success:
            reason = "numerical"
        return IKResult(success, theta.copy(), pos_err, rot_err, it, reason)

    def refine_many(
        self,
        thetas0: np.ndarray,
        R_target: np.ndarray,
        p_target: np.ndarray,
        *,
        pos_tol: float = POS_TOL,
        rot_tol: float = ROT_TOL,
        max_iter: int = 100,
        damping: float = DAMPING,
        stop_at_first: bool = True,
    ) -> IKResult:
        """Refine each seed of ``thetas0: (k, dof)`` in order.

        ``stop_at_first``: return the first success; otherwise refine every seed and return the
        success (else failure) with the smallest error relative to the tolerances.
        ``seed_index`` of the result says which seed it came from.
        """
        ths = _check_thetas(thetas0, self.dof, "thetas0", batched=True)
        R, p = check_target(R_target, p_target)
        _check_options(pos_tol, rot_tol, max_iter, damping)
        oMdes = pin.SE3(R, p)
        best: IKResult | None = None
        for k, th in enumerate(ths):
            r = self._refine(self.project(th), oMdes, pos_tol, rot_tol, max_iter, damping)
            r = IKResult(r.success, r.theta, r.pos_err, r.rot_err, r.iterations, r.reason, k)
            if r.success and stop_at_first:
                return r
            if best is None or _score(r, pos_tol, rot_tol) < _score(best, pos_tol, rot_tol):
                best = r
        assert best is not None
        return best

    def mid_range(self) -> np.ndarray:
        """Middle of the joint limits, ``(dof,)`` [rad or m]: the default fixed seed."""
        return self._centre.copy()

    def random_thetas(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``(n, dof)`` configurations uniform within the joint limits [rad or m]."""
        return rng.uniform(self.lower, self.upper, size=(n, self.dof))

    def distance(self, a: np.ndarray, b: np.ndarray) -> float:
        """Largest joint difference [rad or m], continuous joints measured the short way round."""
        d = np.abs(a - b)
        d = np.where(self._cont, np.minimum(d, 2 * np.pi - np.mod(d, 2 * np.pi)), d)
        return float(d.max())


def refine(
    robot: RobotModel,
    theta0: np.ndarray,
    R_target: np.ndarray,
    p_target: np.ndarray,
    *,
    pos_tol: float = POS_TOL,
    rot_tol: float = ROT_TOL,
    max_iter: int = 100,
    damping: float = DAMPING,
) -> IKResult:
    """Refine a seed ``theta0: (dof,)`` to ``R_target: (3, 3)``, ``p_target: (3,)`` [m].

    Makes a fresh :class:`Refiner`; keep one per thread for repeated calls.
    """
    return Refiner(robot).refine(
        theta0,
        R_target,
        p_target,
        pos_tol=pos_tol,
        rot_tol=rot_tol,
        max_iter=max_iter,
        damping=damping,
    )


def refine_many(
    robot: RobotModel,
    thetas0: np.ndarray,
    R_target: np.ndarray,
    p_target: np.ndarray,
    *,
    pos_tol: float = POS_TOL,
    rot_tol: float = ROT_TOL,
    max_iter: int = 100,
    damping: float = DAMPING,
    stop_at_first: bool = True,
) -> IKResult:
    """Try the seeds ``thetas0: (k, dof)`` in order: first success, or the best failure."""
    return Refiner(robot).refine_many(
        thetas0,
        R_target,
        p_target,
        pos_tol=pos_tol,
        rot_tol=rot_tol,
        max_iter=max_iter,
        damping=damping,
        stop_at_first=stop_at_first,
    )


def solve_from_fixed_seed(
    robot: RobotModel,
    R_target: np.ndarray,
    p_target: np.ndarray,
    seed_theta: np.ndarray | None = None,
    *,
    pos_tol: float = POS_TOL,
    rot_tol: float = ROT_TOL,
    max_iter: int = 300,
) -> IKResult:
    """Baseline: the same solver from one fixed seed (default: mid-range of the joint limits)."""
    solver = Refiner(robot)
    seed = solver.mid_range() if seed_theta is None else seed_theta
    return solver.refine(
        seed, R_target, p_target, pos_tol=pos_tol, rot_tol=rot_tol, max_iter=max_iter
    )


def solve_multistart(
    robot: RobotModel,
    R_target: np.ndarray,
    p_target: np.ndarray,
    n_starts: int,
    rng: np.random.Generator,
    *,
    pos_tol: float = POS_TOL,
    rot_tol: float = ROT_TOL,
    max_iter: int = 100,
    distinct_tol: float = 1e-2,
) -> tuple[IKResult, ...]:
    """Dense multi-start oracle: every distinct success from ``n_starts`` uniform random seeds.

    Two solutions are the same when no joint differs by more than ``distinct_tol`` [rad or m].
    ``seed_index`` says which random seed found each one; an empty tuple means none succeeded.
    """
    if n_starts < 1:
        raise InputError(f"n_starts must be >= 1, got {n_starts}", field="n_starts")
    solver = Refiner(robot)
    R, p = check_target(R_target, p_target)
    _check_options(pos_tol, rot_tol, max_iter, DAMPING)
    oMdes = pin.SE3(R, p)
    found: list[IKResult] = []
    for k, seed in enumerate(solver.random_thetas(n_starts, rng)):
        r = solver._refine(seed, oMdes, pos_tol, rot_tol, max_iter, DAMPING)
        if r.success and all(solver.distance(r.theta, s.theta) > distinct_tol for s in found):
            found.append(IKResult(True, r.theta, r.pos_err, r.rot_err, r.iterations, r.reason, k))
    return tuple(found)

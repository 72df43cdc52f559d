"""IK refinement: converges from nearby seeds, reports failure honestly, validates its inputs."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pickstop.errors import InputError, QueryError
from pickstop.reach.ik import (
    POS_TOL,
    ROT_TOL,
    IKResult,
    Refiner,
    refine,
    refine_many,
    solve_from_fixed_seed,
    solve_multistart,
)
from pickstop.robot.kinematics import reference_fk
from tests.utils import random_thetas


def target_of(robot, theta):
    M = reference_fk(robot, theta)
    return M.rotation.copy(), M.translation.copy()


def perturb(robot, theta, rng, size=0.15):
    """Every joint moved by ``size`` rad (prismatic: a quarter of that in m), random sign."""
    scale = np.where([j.kind == "prismatic" for j in robot.joints], 0.25 * size, size)
    return theta + scale * rng.choice([-1.0, 1.0], robot.dof)


def assert_solves(robot, r: IKResult, R, p, pos_tol=POS_TOL, rot_tol=ROT_TOL):
    """``r`` claims success: check it independently with pinocchio."""
    assert r.success, r
    assert r.reason == "converged"
    assert r.theta.shape == (robot.dof,)
    assert np.all(r.theta >= robot.lower - 1e-9) and np.all(r.theta <= robot.upper + 1e-9)
    M = reference_fk(robot, r.theta)
    pos_err = np.linalg.norm(M.translation - p)
    rot_err = np.linalg.norm(pin.log3(M.rotation.T @ R))
    assert pos_err <= pos_tol and rot_err <= rot_tol
    assert r.pos_err == pytest.approx(pos_err, abs=1e-12)
    assert r.rot_err == pytest.approx(rot_err, abs=1e-9)


def test_converges_from_nearby_seeds(robot):
    solver = Refiner(robot)
    rng = np.random.default_rng(1)
    for theta in random_thetas(robot, 30, seed=2):
        R, p = target_of(robot, theta)
        r = solver.refine(perturb(robot, theta, rng), R, p)
        assert_solves(robot, r, R, p)
        assert r.iterations <= 10


@settings(max_examples=20, deadline=None, derandomize=True)
@given(
    u=st.lists(st.floats(0.0, 1.0), min_size=8, max_size=8),
    d=st.lists(st.floats(-0.15, 0.15), min_size=8, max_size=8),
)
def test_property_random_configuration(robot, u, d):
    """Any configuration within limits is found again from a seed 0.15 rad away per joint."""
    theta = robot.lower + np.array(u) * (robot.upper - robot.lower)
    R, p = target_of(robot, theta)
    r = refine(robot, theta + np.array(d), R, p)
    assert_solves(robot, r, R, p)


def test_exact_seed_needs_no_iteration(tiago):
    theta = random_thetas(tiago, 1, seed=5)[0]
    R, p = target_of(tiago, theta)
    r = refine(tiago, theta, R, p)
    assert_solves(tiago, r, R, p)
    assert r.iterations == 0
    np.testing.assert_array_equal(r.theta, theta)


def test_tighter_tolerances(robot):
    theta = random_thetas(robot, 1, seed=6)[0]
    R, p = target_of(robot, theta)
    seed = perturb(robot, theta, np.random.default_rng(0))
    r = refine(robot, seed, R, p, pos_tol=1e-6, rot_tol=1e-6)
    assert_solves(robot, r, R, p, pos_tol=1e-6, rot_tol=1e-6)


@pytest.mark.parametrize("p", [(3.0, 0.0, 1.0), (0.0, -3.0, 0.5), (0.0, 0.0, 3.5)])
def test_unreachable_pose_fails_honestly(robot, p):
    solver = Refiner(robot)
    r = solver.refine(solver.mid_range(), np.eye(3), np.array(p))
    assert not r.success
    assert r.reason in ("stalled", "joint_limits", "max_iter")
    assert r.pos_err > 1.0
    assert np.all(r.theta >= robot.lower) and np.all(r.theta <= robot.upper)
    M = reference_fk(robot, r.theta)
    assert r.pos_err == pytest.approx(np.linalg.norm(M.translation - np.array(p)))


def test_max_iter_is_reported(tiago):
    theta = random_thetas(tiago, 1, seed=7)[0]
    R, p = target_of(tiago, theta)
    r = refine(tiago, perturb(tiago, theta, np.random.default_rng(0), 0.4), R, p, max_iter=1)
    assert not r.success
    assert r.reason == "max_iter"
    assert r.iterations == 1


def test_continuous_joints_wrap(pr2):
    """A PR2 solution with both roll joints near +pi, seeded from just past -pi."""
    cont = [i for i, j in enumerate(pr2.joints) if j.kind == "continuous"]
    assert len(cont) == 2
    theta = np.clip(random_thetas(pr2, 1, seed=8)[0], pr2.lower + 0.2, pr2.upper - 0.2)
    theta[cont] = 3.1
    R, p = target_of(pr2, theta)
    seed = perturb(pr2, theta, np.random.default_rng(3), 0.05)
    seed[cont] = -3.1  # the same angles 0.08 rad away across the wrap
    r = refine(pr2, seed, R, p)
    assert_solves(pr2, r, R, p)
    assert np.all(np.abs(r.theta[cont]) <= math.pi)
    assert Refiner(pr2).distance(r.theta, theta) < 0.2


def test_continuous_seed_outside_limits_is_wrapped(pr2):
    cont = [i for i, j in enumerate(pr2.joints) if j.kind == "continuous"]
    theta = random_thetas(pr2, 1, seed=9)[0]
    R, p = target_of(pr2, theta)
    seed = theta.copy()
    seed[cont] += np.array([4 * math.pi, -2 * math.pi])
    r = refine(pr2, seed, R, p)
    assert_solves(pr2, r, R, p)
    assert r.iterations <= 1
    np.testing.assert_allclose(r.theta, theta, atol=1e-9)


def test_angle_step_is_pin_integrate(pr2):
    """Stepping angles then rebuilding q is what pinocchio's integrate does, cos/sin included."""
    solver = Refiner(pr2)
    theta = solver.mid_range()
    dq = np.random.default_rng(0).uniform(-0.3, 0.3, pr2.dof)
    q_next = pin.integrate(pr2.model, pr2.angles_to_q(theta), dq)
    np.testing.assert_allclose(pr2.angles_to_q(solver.project(theta + dq)), q_next, atol=1e-12)


def test_refine_many_returns_first_success(tiago):
    theta = random_thetas(tiago, 1, seed=10)[0]
    R, p = target_of(tiago, theta)
    solver = Refiner(tiago)
    seeds = np.stack([solver.mid_range(), theta, perturb(tiago, theta, np.random.default_rng(0))])
    r = refine_many(tiago, seeds, R, p, max_iter=1)
    assert r.seed_index == 1
    assert_solves(tiago, r, R, p)
    best = refine_many(tiago, seeds, R, p, max_iter=20, stop_at_first=False)
    assert best.success and best.seed_index in (0, 1, 2)
    assert best.pos_err <= r.pos_err + 1e-12


def test_refine_many_best_failure(tiago):
    solver = Refiner(tiago)
    seeds = random_thetas(tiago, 3, seed=11)
    p = np.array([2.5, 0.0, 1.0])
    r = solver.refine_many(seeds, np.eye(3), p)
    singles = [solver.refine(s, np.eye(3), p) for s in seeds]
    assert not r.success
    assert r.pos_err == pytest.approx(min(s.pos_err for s in singles), rel=1e-9)


def test_fixed_seed_baseline(robot):
    solver = Refiner(robot)
    theta = solver.project(perturb(robot, solver.mid_range(), np.random.default_rng(4), 0.3))
    R, p = target_of(robot, theta)
    r = solve_from_fixed_seed(robot, R, p)
    assert_solves(robot, r, R, p)
    r2 = solve_from_fixed_seed(robot, R, p, seed_theta=theta)
    assert r2.iterations == 0


def test_multistart_returns_distinct_solutions(tiago):
    theta = random_thetas(tiago, 1, seed=12)[0]
    R, p = target_of(tiago, theta)
    sols = solve_multistart(tiago, R, p, 8, np.random.default_rng(0))
    assert len(sols) >= 1
    solver = Refiner(tiago)
    for a, s in enumerate(sols):
        assert_solves(tiago, s, R, p)
        for t in sols[:a]:
            assert solver.distance(s.theta, t.theta) > 1e-2
    assert [s.seed_index for s in sols] == sorted(s.seed_index for s in sols)
    far = np.array([3.0, 0.0, 1.0])
    assert solve_multistart(tiago, np.eye(3), far, 3, np.random.default_rng(0)) == ()
    with pytest.raises(InputError, match="n_starts"):
        solve_multistart(tiago, R, p, 0, np.random.default_rng(0))


@pytest.mark.parametrize(
    ("theta0", "R", "p", "field", "match"),
    [
        (np.zeros(7), np.eye(3), np.zeros(3), "theta0", r"shape \(dof,\) with dof=8, got \(7,\)"),
        (np.full(8, np.nan), np.eye(3), np.zeros(3), "theta0", "NaN"),
        (np.zeros(8), np.eye(4), np.zeros(3), "R_target", r"shape \(3, 3\)"),
        (np.zeros(8), np.eye(3), np.zeros(4), "p_target", r"shape \(3,\)"),
        (np.zeros(8), np.eye(3), np.array([0.0, np.inf, 0.0]), "p_target", "NaN or infinite"),
        (np.zeros(8), np.full((3, 3), np.nan), np.zeros(3), "R_target", "NaN"),
        (np.zeros(8), 2 * np.eye(3), np.zeros(3), "R_target", "not a rotation"),
        (np.zeros(8), -np.eye(3), np.zeros(3), "R_target", "not a rotation"),
    ],
)
def test_bad_input_raises_query_error(tiago, theta0, R, p, field, match):
    with pytest.raises(QueryError, match=match) as info:
        refine(tiago, theta0, R, p)
    assert info.value.field == field


def test_bad_batch_and_options(tiago):
    with pytest.raises(QueryError, match=r"\(k, dof\)"):
        refine_many(tiago, np.zeros(8), np.eye(3), np.zeros(3))
    with pytest.raises(QueryError, match=r"\(k, dof\)"):
        refine_many(tiago, np.zeros((0, 8)), np.eye(3), np.zeros(3))
    with pytest.raises(InputError, match="pos_tol"):
        refine(tiago, np.zeros(8), np.eye(3), np.zeros(3), pos_tol=0.0)
    with pytest.raises(InputError, match="max_iter"):
        refine(tiago, np.zeros(8), np.eye(3), np.zeros(3), max_iter=-1)


def test_result_is_frozen(tiago):
    theta = random_thetas(tiago, 1, seed=13)[0]
    r = refine(tiago, theta, *target_of(tiago, theta))
    with pytest.raises(AttributeError):
        r.success = False  # type: ignore[misc]


def test_compiled_error_is_the_batch_error_near_a_half_turn_too():
    """The compiled IK's 6D error and angle are the numpy batch's, for rotations of every
    angle, those within a few degrees of a half turn (the quaternion path) included."""
    from pickstop.reach.batch_ik import _errors
    from pickstop.reach.ik_kernel import _error
    from pickstop.reach.so3 import quats_to_matrices

    rng = np.random.default_rng(4)
    n = 400
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    angle = np.concatenate([rng.uniform(0, np.pi, n // 2), np.pi - rng.uniform(0, 0.1, n // 2)])
    q = np.concatenate([np.cos(angle / 2)[:, None], axis * np.sin(angle / 2)[:, None]], 1)
    Rt = quats_to_matrices(q)
    R = quats_to_matrices(rng.normal(size=(n, 4)))
    Rt = Rt @ R  # targets at those angles from the current rotations
    p, pt = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    want_e, want_a = _errors(
        R.transpose(1, 2, 0).copy(), p.T.copy(), Rt.transpose(1, 2, 0).copy(), pt.T.copy()
    )
    assert (want_a > 3.0).sum() > n // 4
    e = np.empty(6)
    for i in range(n):
        a = _error(R[i], p[i], Rt[i], pt[i], e)
        assert abs(a - want_a[i]) < 1e-9 and np.allclose(e, want_e[:, i], atol=1e-9)

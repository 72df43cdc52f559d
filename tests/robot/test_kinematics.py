"""Vectorised FK and manipulability against pinocchio (property tests, both presets)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pickstop.robot.kinematics import (
    Chain,
    fk,
    manipulability,
    reference_fk,
    reference_manipulability,
)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 40))
def test_fk_matches_pinocchio(robot, seed, n):
    chain = Chain.from_robot(robot)
    th = np.random.default_rng(seed).uniform(robot.lower, robot.upper, (n, robot.dof))
    Rs, ps = fk(chain, th)
    assert Rs.shape == (n, 3, 3) and ps.shape == (n, 3)
    for k in range(n):
        M = reference_fk(robot, th[k])
        np.testing.assert_allclose(Rs[k], M.rotation, atol=1e-9)
        np.testing.assert_allclose(ps[k], M.translation, atol=1e-9)


def test_fk_block_boundaries(tiago):
    """More configurations than one internal block: every block agrees with pinocchio."""
    chain = Chain.from_robot(tiago)
    th = np.random.default_rng(3).uniform(tiago.lower, tiago.upper, (9000, tiago.dof))
    Rs, ps = fk(chain, th)
    for k in (0, 4095, 4096, 8191, 8192, 8999):
        M = reference_fk(tiago, th[k])
        np.testing.assert_allclose(ps[k], M.translation, atol=1e-9)
        np.testing.assert_allclose(Rs[k], M.rotation, atol=1e-9)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_manipulability_matches_pinocchio(robot, seed):
    chain = Chain.from_robot(robot)
    th = np.random.default_rng(seed).uniform(robot.lower, robot.upper, (20, robot.dof))
    w = manipulability(chain, th)
    ref = np.array([reference_manipulability(robot, t) for t in th])
    np.testing.assert_allclose(w, ref, rtol=1e-7, atol=1e-10)

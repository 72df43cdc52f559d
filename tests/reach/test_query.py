"""IK by query: candidates of a pose's voxel, ranked; batched; refined."""

from __future__ import annotations

import numpy as np
import pytest

from pickstop.errors import QueryError
from pickstop.reach.database import RANK_LENGTH
from pickstop.reach.so3 import quats_to_matrices
from pickstop.robot.kinematics import Chain, fk

TOP_DOWN = np.array([0.70710678, 0.0, 0.70710678, 0.0])


def test_top_down_grasp_in_front_finds_many_diverse_candidates(small_loaded):
    c = small_loaded.query([0.65, -0.15, 0.75], TOP_DOWN, neighbours=True)
    assert len(c.rows) >= 20
    # Diverse: genuinely different arm configurations, not one solution repeated.
    arm = c.thetas[:, 1:]
    d = np.linalg.norm(arm[:, None] - arm[None], axis=-1)
    assert np.median(d[np.triu_indices(len(arm), 1)]) > 0.5
    assert d.max() > 2.0


def test_candidates_ranked_by_pose_distance(small_loaded):
    db = small_loaded
    for r in (10, 5000, 90_000):
        p, q = db.positions[r].astype(float), db.quats[r].astype(float)
        q /= np.linalg.norm(q)
        c = db.query(p, q, neighbours=True)
        score = c.pos_err + RANK_LENGTH * c.rot_err
        assert (np.diff(score) >= -1e-9).all()
        assert c.pos_err[0] < 2e-3 and c.rot_err[0] < 1e-2  # the row itself comes first
        own = db.query(p, q)
        assert set(own.rows) <= set(c.rows)
        assert (db.keys[own.rows] == db.voxel.keys(p[None], q[None])[0]).all()


def test_batch_query_equals_single_queries(small_loaded):
    db = small_loaded
    rng = np.random.default_rng(5)
    rows = rng.integers(0, len(db), 200)
    ps = db.positions[rows].astype(float) + rng.normal(0, 0.02, (200, 3))
    qs = db.quats[rows].astype(float)
    qs /= np.linalg.norm(qs, axis=1, keepdims=True)
    cs = db.query_many(ps, qs)
    for i in range(200):
        single = db.query(ps[i], qs[i])
        np.testing.assert_array_equal(cs.rows[cs.offsets[i] : cs.offsets[i + 1]], single.rows)


def test_unreachable_pose_has_no_candidates(small_loaded):
    assert len(small_loaded.query([3.0, 0.0, 0.5], TOP_DOWN, neighbours=True).rows) == 0


@pytest.mark.parametrize(
    ("p", "q", "match"),
    [
        ([0.5, 0.0], TOP_DOWN, "positions must have shape"),
        ([0.5, 0.0, np.nan], TOP_DOWN, "NaN"),
        ([0.5, 0.0, 0.7], [1.0, 1.0, 0.0, 0.0], "unit quaternion"),
        ([0.5, 0.0, 0.7], [1.0, 0.0, 0.0], "quaternions must have shape"),
    ],
)
def test_bad_query_input(small_loaded, p, q, match):
    with pytest.raises(QueryError, match=match):
        small_loaded.query(p, q)


def test_refinement_turns_candidates_into_exact_solutions(small_loaded, tiago):
    from pickstop.reach.ik import refine_many

    chain = Chain.from_robot(tiago)
    db = small_loaded
    rng = np.random.default_rng(11)
    ok = 0
    for r in rng.integers(0, len(db), 15):
        # A target near a stored pose, off by a few mm and degrees: reachable by construction.
        theta = db.thetas(np.array([r]))[0] + rng.normal(0, 0.02, tiago.dof)
        theta = np.clip(theta, tiago.lower, tiago.upper)
        R, p = fk(chain, theta[None])
        q = db.quats[r].astype(float)
        c = db.query(p[0], _quat(R[0]), neighbours=True)
        res = refine_many(tiago, c.thetas[:10], R[0], p[0])
        assert len(q) == 4
        if res.success:
            ok += 1
            _, pf = fk(chain, res.theta[None])
            assert np.linalg.norm(pf[0] - p[0]) <= 1e-3
            assert ((res.theta >= tiago.lower - 1e-9) & (res.theta <= tiago.upper + 1e-9)).all()
    assert ok >= 14


def _quat(R):
    from pickstop.reach.so3 import matrices_to_quats

    return matrices_to_quats(R[None])[0]


def test_refinement_reports_failure_when_unreachable(small_loaded, tiago):
    from pickstop.reach.ik import refine_many

    seeds = small_loaded.thetas(np.arange(5))
    res = refine_many(tiago, seeds, quats_to_matrices(TOP_DOWN), np.array([2.5, 0.0, 0.7]))
    assert not res.success and res.reason

"""The SO(3) grid: near-uniform, no degenerate cells, consistent scalar and batch paths."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from pickstop.reach.so3 import SO3Grid, matrices_to_quats, quat_angle, quats_to_matrices
from pickstop.reach.voxels import VoxelGrid


def _uniform_quats(n: int, seed: int = 0) -> np.ndarray:
    q = np.random.default_rng(seed).normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


@pytest.mark.parametrize("n", [3, 6, 8])
def test_cells_near_equal_volume(n):
    """Uniform random rotations fill every cell; largest / smallest cell below 2.5."""
    grid = SO3Grid(n)
    counts = np.bincount(grid.index(_uniform_quats(600 * grid.size)), minlength=grid.size)
    assert counts.min() > 0
    assert counts.max() / counts.min() < 2.5


@settings(max_examples=50, deadline=None)
@given(q=arrays(np.float64, 4, elements=st.floats(-1, 1)).filter(lambda v: np.linalg.norm(v) > 0.1))
def test_sign_invariant_and_scalar_matches_batch(q):
    q = q / np.linalg.norm(q)
    grid = SO3Grid(7)
    i = grid.index(q[None])[0]
    assert grid.index((-q)[None])[0] == i
    assert grid.index_one(tuple(q)) == i


def test_centres_lie_in_their_cell():
    grid = SO3Grid(6)
    assert (grid.index(grid.centers()) == np.arange(grid.size)).all()


def test_cells_are_small_everywhere():
    """Every sample is within ~one cell angle of its cell centre (pitch 90 degrees included)."""
    grid = SO3Grid(6)
    q = _uniform_quats(200_000, 1)
    top_down = np.array([[0.70710678, 0.0, 0.70710678, 0.0]])
    q = np.vstack([q, top_down])
    d = quat_angle(q, grid.centers(grid.index(q)))
    assert d.max() < 1.05 * grid.cell_angle


def test_top_down_grasp_is_an_ordinary_cell():
    """Roll-pitch-yaw bins collapse at pitch 90 degrees; here yaw about vertical still matters."""
    grid = SO3Grid(6)
    base = np.array([0.70710678, 0.0, 0.70710678, 0.0])
    yaws = np.linspace(0, np.pi, 12, endpoint=False)
    qz = np.stack([np.cos(yaws / 2), 0 * yaws, 0 * yaws, np.sin(yaws / 2)], 1)
    w1, v1 = qz[:, 0], qz[:, 1:]
    w = w1 * base[0] - v1 @ base[1:]
    v = w1[:, None] * base[1:] + base[0] * v1 + np.cross(v1, base[1:])
    cells = grid.index(np.concatenate([w[:, None], v], 1))
    assert len(set(cells.tolist())) >= 6


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_matrix_quaternion_round_trip(seed):
    q = _uniform_quats(100, seed)
    R = quats_to_matrices(q)
    assert np.allclose(np.einsum("nij,nkj->nik", R, R), np.eye(3), atol=1e-12)
    q2 = matrices_to_quats(R)
    assert np.allclose(np.abs(np.sum(q * q2, axis=1)), 1.0, atol=1e-12)
    assert (q2[:, 0] >= 0).all()


def test_neighbours_include_own_cell_and_cross_faces():
    grid = SO3Grid(4)
    for q in _uniform_quats(50, 2):
        nb = grid.neighbours(q)
        assert grid.index(q[None])[0] in nb
        assert 4 <= len(nb) <= 27
    corner = np.array([0.5, 0.5, 0.5, 0.5])  # on the boundary of all four faces
    faces = set((grid.neighbours(corner) // grid.n**3).tolist())
    assert len(faces) >= 2


def test_voxel_keys_decode_and_bounds():
    vg = VoxelGrid(0.05, 6)
    rng = np.random.default_rng(0)
    p = rng.uniform(-1.5, 1.5, (1000, 3))
    q = _uniform_quats(1000, 3)
    keys = vg.keys(p, q)
    lo, hi = vg.cell_bounds(keys)
    assert ((lo <= p) & (p < hi)).all()
    _, orient = vg.decode(keys)
    assert (orient == vg.so3.index(q)).all()
    assert [vg.key_one(tuple(a), tuple(b)) for a, b in zip(p[:50], q[:50], strict=True)] == list(
        keys[:50]
    )
    assert vg.keys(np.array([[100.0, 0, 0]]), q[:1])[0] == -1


def test_invalid_grid_parameters():
    with pytest.raises(ValueError, match="resolution"):
        VoxelGrid(0.0, 6)
    with pytest.raises(ValueError, match=r"SO3Grid\.n"):
        SO3Grid(0)

"""The compiled frame helpers against the same transforms in numpy."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from pickstop.frames import R_z
from pickstop.robot.frame_kernel import compose, frame, put, to_world, world_box


def _pose(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    return Rotation.random(random_state=rng).as_matrix(), rng.uniform(-1.0, 1.0, 3)


def _T(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_frames_compose_and_carry_points_and_boxes_as_numpy_does(seed):
    """A frame read and put back is unchanged; ``compose`` is the product of the homogeneous
    matrices; ``to_world`` is ``R_z(yaw) (R l + p) + (x, y, 0)``; ``world_box`` holds the
    box's corners so carried, and its half extents are ``|R_z(yaw) R| e + pad``."""
    rng = np.random.default_rng(seed)
    (Ra, pa), (Rb, pb) = _pose(rng), _pose(rng)
    A, B = frame(Ra, pa), frame(Rb, pb)
    R, p = np.empty((3, 3)), np.empty(3)
    put(A, R, p)
    assert np.array_equal(R, Ra) and np.array_equal(p, pa)
    put(compose(A, B), R, p)
    assert np.allclose(_T(R, p), _T(Ra, pa) @ _T(Rb, pb), atol=1e-12)

    x, y, yaw = *rng.uniform(-3.0, 3.0, 2), float(rng.uniform(-np.pi, np.pi))
    base = (x, y, np.cos(yaw), np.sin(yaw))
    local = rng.uniform(-0.5, 0.5, 3)
    want = R_z(yaw) @ (Ra @ local + pa) + np.array([x, y, 0.0])
    assert np.allclose(to_world(A, base, *local), want, atol=1e-12)

    lo = rng.uniform(-0.5, 0.0, 3)
    hi = lo + rng.uniform(0.0, 0.5, 3)
    pad = 0.01
    cx, cy, cz, hx, hy, hz = world_box(A, base, lo, hi, pad)
    c, h = np.array([cx, cy, cz]), np.array([hx, hy, hz])
    assert np.allclose(h, np.abs(R_z(yaw) @ Ra) @ ((hi - lo) / 2) + pad, atol=1e-12)
    corners = np.array([[(lo, hi)[i >> k & 1][k] for k in range(3)] for i in range(8)])
    placed = (R_z(yaw) @ (Ra @ corners.T + pa[:, None])).T + np.array([x, y, 0.0])
    assert np.all(np.abs(placed - c) <= h - pad + 1e-12)
    assert np.allclose(np.abs(placed - c).max(0), h - pad, atol=1e-12)  # tight

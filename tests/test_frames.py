"""pickstop.frames against independent references (pinocchio, viser's SO3) and its group laws."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
import viser.transforms as vtf
from hypothesis import given, settings
from hypothesis import strategies as st

from pickstop import frames as fr

angles = st.floats(-10.0, 10.0, allow_nan=False)
coords = st.floats(-50.0, 50.0, allow_nan=False)


def _random_T(rng: np.random.Generator, batch: tuple[int, ...] = ()) -> np.ndarray:
    q = rng.normal(size=(*batch, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    R = np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )
    T = np.zeros((*batch, 4, 4))
    T[..., :3, :3], T[..., :3, 3], T[..., 3, 3] = R, rng.normal(size=(*batch, 3)), 1.0
    return T


def test_known_values():
    assert np.allclose(fr.R_z(math.pi / 2) @ [1, 0, 0], [0, 1, 0])
    assert np.allclose(fr.R_x(math.pi / 2) @ [0, 1, 0], [0, 0, 1])  # y towards z
    assert np.allclose(fr.R_y(math.pi / 2) @ [0, 0, 1], [1, 0, 0])  # z towards x
    assert np.allclose(fr.rot2(math.pi / 2) @ [1, 0], [0, 1])
    assert np.allclose(fr.yaw_quat(math.pi), (0, 0, 0, 1))
    assert fr.wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
    assert fr.angle_gap(math.pi - 0.1, -math.pi + 0.1) == pytest.approx(0.2)
    T = fr.T_world_base(1.0, 2.0, math.pi / 2)
    assert np.allclose(fr.apply(T, np.array([1.0, 0.0, 0.5])), [1.0, 3.0, 0.5])  # x forward
    assert np.allclose(fr.R_base_world(0.3) @ fr.R_z(0.3), np.eye(3))


@settings(max_examples=60, deadline=None)
@given(angles, angles, angles)
def test_rotations_match_pinocchio(roll, pitch, yaw):
    assert np.allclose(fr.R_rpy(roll, pitch, yaw), pin.rpy.rpyToMatrix(roll, pitch, yaw))
    assert np.allclose(fr.R_rpy(roll, pitch, yaw), fr.R_z(yaw) @ fr.R_y(pitch) @ fr.R_x(roll))
    for axis, R in (("x", fr.R_x), ("y", fr.R_y), ("z", fr.R_z)):
        assert np.allclose(fr.R_axis(axis, roll), R(roll))
        assert np.allclose(fr.R_axis(axis, roll), pin.exp3(roll * np.eye(3)["xyz".index(axis)]))


@settings(max_examples=60, deadline=None)
@given(angles, st.sampled_from(["x", "y", "z"]))
def test_quaternions_are_the_same_rotations(angle, axis):
    q = fr.axis_quat(axis, angle)
    assert np.allclose(vtf.SO3(np.array(q)).as_matrix(), fr.R_axis(axis, angle))
    assert math.isclose(math.fsum(v * v for v in q), 1.0)
    assert fr.yaw_quat(angle) == fr.axis_quat("z", angle)
    assert fr.quat_yaw(fr.yaw_quat(angle)) == pytest.approx(fr.wrap_angle(angle), abs=1e-9)


def test_quat_yaw_is_the_heading_of_x():
    R = fr.R_z(0.7) @ fr.R_y(0.3) @ fr.R_x(-0.4)
    q = vtf.SO3.from_matrix(R).wxyz
    x = R[:, 0]
    assert fr.quat_yaw(q) == pytest.approx(math.atan2(x[1], x[0]))


@settings(max_examples=60, deadline=None)
@given(angles)
def test_wrap_angle(a):
    w = fr.wrap_angle(a)
    assert -math.pi <= w <= math.pi
    assert math.cos(w) == pytest.approx(math.cos(a), abs=1e-12)
    assert math.sin(w) == pytest.approx(math.sin(a), abs=1e-12)
    assert fr.wrap_angle(np.array([a]))[0] == pytest.approx(w, abs=1e-12)
    assert 0.0 <= fr.angle_gap(a, 0.0) <= math.pi


@settings(max_examples=40, deadline=None)
@given(st.lists(angles, min_size=0, max_size=7))
def test_batched_equals_single(yaws):
    Rs = fr.Rs_z(np.array(yaws))
    assert Rs.shape == (len(yaws), 3, 3)
    for R, yaw in zip(Rs, yaws, strict=True):
        assert np.array_equal(R, fr.R_z(yaw))


def test_rs_z_rejects_other_shapes():
    with pytest.raises(AssertionError, match=r"yaws: expected \(N,\)"):
        fr.Rs_z(np.zeros((2, 2)))


@settings(max_examples=60, deadline=None)
@given(coords, coords, coords, angles)
def test_yaw_transforms(x, y, z, yaw):
    T = fr.T_yaw(x, y, z, yaw)
    ref = pin.SE3(pin.rpy.rpyToMatrix(0, 0, yaw), np.array([x, y, z])).homogeneous
    assert np.allclose(T, ref)
    assert np.array_equal(fr.T_world_base(x, y, yaw), fr.T_yaw(x, y, 0.0, yaw))
    assert np.array_equal(T[:2, :2], fr.rot2(yaw))
    assert np.allclose(fr.transform(fr.R_z(yaw), (x, y, z)), T)


@pytest.mark.parametrize("batch", [(), (5,), (2, 3)])
def test_inverse_and_compose(batch):
    rng = np.random.default_rng(7)
    T_a_b, T_b_c = _random_T(rng, batch), _random_T(rng, batch)
    assert np.allclose(fr.inverse(T_a_b), np.linalg.inv(T_a_b))
    assert np.allclose(fr.compose(T_a_b, fr.inverse(T_a_b)), np.eye(4))
    assert np.allclose(fr.inverse(fr.inverse(T_a_b)), T_a_b)
    T_a_c = fr.compose(T_a_b, T_b_c)
    assert np.allclose(fr.inverse(T_a_c), fr.compose(fr.inverse(T_b_c), fr.inverse(T_a_b)))
    assert np.array_equal(fr.compose(T_a_b), T_a_b)
    if not batch:
        ref = pin.SE3(T_a_b[:3, :3], T_a_b[:3, 3]) * pin.SE3(T_b_c[:3, :3], T_b_c[:3, 3])
        assert np.allclose(T_a_c, ref.homogeneous)
        ps = rng.normal(size=(4, 3))
        assert np.allclose(fr.apply(T_a_c, ps), fr.apply(T_a_b, fr.apply(T_b_c, ps)))
        assert np.allclose(fr.apply(fr.inverse(T_a_b), fr.apply(T_a_b, ps)), ps)

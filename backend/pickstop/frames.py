"""Rotations and rigid transforms, as ``docs/conventions.md`` fixes them.

``T_a_b`` (4, 4) is the pose of frame ``b`` in frame ``a`` (``p_a = T_a_b @ p_b``), ``R_a_b``
(3, 3) its rotation; batched arrays are plural (``Rs_a_b: (N, 3, 3)``). Angles are in [rad],
lengths in [m], quaternions ``wxyz``. A base pose is ``(x, y, yaw)`` in ``world``.

Pure numpy and math: imported by the core, the fleet export and the planner UI alike.
"""

from __future__ import annotations

import math
from typing import Literal, overload

import numpy as np

Axis = Literal["x", "y", "z"]
Quat = tuple[float, float, float, float]


# ---------------------------------------------------------------------------------------------
# Angles


@overload
def wrap_angle(angle: float) -> float: ...
@overload
def wrap_angle(angle: np.ndarray) -> np.ndarray: ...
def wrap_angle(angle: float | np.ndarray) -> float | np.ndarray:
    """``angle`` [rad] (scalar or any shape) wrapped into [-pi, pi]."""
    if isinstance(angle, np.ndarray):
        return np.arctan2(np.sin(angle), np.cos(angle))
    return math.atan2(math.sin(angle), math.cos(angle))


def angle_gap(a: float, b: float) -> float:
    """The smallest rotation [rad] between headings ``a`` and ``b``, in [0, pi]."""
    return abs(wrap_angle(a - b))


# ---------------------------------------------------------------------------------------------
# Rotations


def rot2(yaw: float) -> np.ndarray:
    """``(2, 2)`` rotation of the plane by ``yaw`` [rad]: ``p' = rot2(yaw) @ p``."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


def R_x(angle: float) -> np.ndarray:
    """``(3, 3)`` rotation by ``angle`` [rad] about x (positive turns y towards z)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def R_y(angle: float) -> np.ndarray:
    """``(3, 3)`` rotation by ``angle`` [rad] about y (positive turns z towards x)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def R_z(yaw: float) -> np.ndarray:
    """``(3, 3)`` rotation by ``yaw`` [rad] about z (positive turns x towards y)."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def Rs_z(yaws: np.ndarray) -> np.ndarray:
    """``(N, 3, 3)`` rotations about z by ``yaws: (N,)`` [rad], ``R_z`` of each."""
    yaws = np.asarray(yaws, dtype=float)
    assert yaws.ndim == 1, f"yaws: expected (N,), got {yaws.shape}"
    c, s = np.cos(yaws), np.sin(yaws)
    out = np.zeros((len(yaws), 3, 3))
    out[:, 0, 0], out[:, 0, 1] = c, -s
    out[:, 1, 0], out[:, 1, 1] = s, c
    out[:, 2, 2] = 1.0
    return out


def R_axis(axis: Axis, angle: float) -> np.ndarray:
    """``(3, 3)`` rotation by ``angle`` [rad] about the named axis."""
    return {"x": R_x, "y": R_y, "z": R_z}[axis](angle)


def R_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``(3, 3)`` ``R_z(yaw) @ R_y(pitch) @ R_x(roll)`` [rad], the URDF ``rpy`` convention."""
    cr, sr, cp, sp, cy, sy = (f(a) for a in (roll, pitch, yaw) for f in (math.cos, math.sin))
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def R_base_world(yaw: float) -> np.ndarray:
    """``(3, 3)`` the world's axes in a base facing ``yaw`` [rad]: ``R_z(yaw).T``."""
    return R_z(yaw).T


# ---------------------------------------------------------------------------------------------
# Quaternions (wxyz)


def axis_quat(axis: Axis, angle: float) -> Quat:
    """``wxyz`` of a rotation by ``angle`` [rad] about the named axis."""
    c, s = math.cos(angle / 2), math.sin(angle / 2)
    return {"x": (c, s, 0.0, 0.0), "y": (c, 0.0, s, 0.0), "z": (c, 0.0, 0.0, s)}[axis]


def yaw_quat(yaw: float) -> Quat:
    """``wxyz`` of the rotation by ``yaw`` [rad] about z."""
    return axis_quat("z", yaw)


def quat_yaw(wxyz: Quat | np.ndarray) -> float:
    """The heading [rad] of a rotation ``wxyz: (4,)``: where it turns x, seen from above
    (exact for rotations about z, the heading of the turned x axis otherwise)."""
    w, x, y, z = (float(v) for v in wxyz)
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


# ---------------------------------------------------------------------------------------------
# Homogeneous transforms


def transform(R: np.ndarray, p: np.ndarray | tuple[float, float, float]) -> np.ndarray:
    """``(4, 4)`` transform of rotation ``R: (3, 3)`` and translation ``p: (3,)`` [m]."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return T


def T_yaw(x: float, y: float, z: float, yaw: float) -> np.ndarray:
    """``(4, 4)`` a frame at ``(x, y, z)`` [m] turned by ``yaw`` [rad] about z."""
    return transform(R_z(yaw), (x, y, z))


def T_world_base(x: float, y: float, yaw: float) -> np.ndarray:
    """``(4, 4)`` the base at ``(x, y)`` [m] on the floor, facing ``yaw`` [rad]."""
    return T_yaw(x, y, 0.0, yaw)


def compose(*Ts: np.ndarray) -> np.ndarray:
    """``T_a_b @ T_b_c @ ...`` of ``(..., 4, 4)`` transforms (batches broadcast)."""
    out = Ts[0]
    for T in Ts[1:]:
        out = out @ T
    return out


def inverse(T_a_b: np.ndarray) -> np.ndarray:
    """``T_b_a`` of a rigid ``T_a_b: (..., 4, 4)``, without a general matrix inverse."""
    R_b_a = np.swapaxes(T_a_b[..., :3, :3], -1, -2)
    out = np.zeros_like(T_a_b, dtype=float)
    out[..., :3, :3] = R_b_a
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", R_b_a, T_a_b[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def apply(T_a_b: np.ndarray, ps_b: np.ndarray) -> np.ndarray:
    """Points ``ps_b: (..., 3)`` in ``b`` expressed in ``a`` (``T_a_b: (4, 4)``)."""
    return ps_b @ T_a_b[:3, :3].T + T_a_b[:3, 3]

"""What a click in the 3D view hits: pure geometry of rays, item boxes and the floor.

A click gives a ray in the world frame (origin [m], unit direction). Each tray or obstacle is
tested as one box, oriented with its yaw, that bounds all its shapes (walls, parts, a tilted
tray's body); the nearest box the ray enters is the item clicked. The floor is the plane
z = 0. Boxes are cheap to test exactly and a click needs no finer answer: where two items
overlap on screen the nearer one wins, as the eye expects.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from pickstop.frames import quat_yaw
from pickstop_ui.scene_view import Item, Shape

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class Box:
    """An item's bounding box: ``centre`` in the world [m], ``half`` extents along the item's
    own axes [m], turned by ``yaw`` [rad] about z."""

    kind: str
    id: str
    centre: Vec3
    half: Vec3
    yaw: float


def _R(wxyz: tuple[float, float, float, float]) -> np.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion (w, x, y, z)."""
    w, x, y, z = wxyz
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])  # fmt: skip


def shape_corners(s: Shape) -> np.ndarray:
    """The 8 corners ``(8, 3)`` of a shape's box (a cylinder's: its bounding box) [m] in its
    parent frame."""
    half = np.array(s.dims) / 2 if s.kind == "box" else np.array([s.dims[0], s.dims[0],
                                                                   s.dims[1] / 2])  # fmt: skip
    signs = np.array(list(itertools.product((-1, 1), repeat=3)), float)
    return (signs * half) @ _R(s.wxyz).T + np.asarray(s.position)


def item_box(item: Item) -> Box | None:
    """The box around all of ``item``'s shapes (None: it has none drawn)."""
    if not item.shapes:
        return None
    body = _R(item.body_wxyz) if item.body_wxyz is not None else np.eye(3)
    pts = np.concatenate([
        shape_corners(s) @ (body.T if s.name.startswith("body/") else np.eye(3))
        for s in item.shapes
    ])  # fmt: skip
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    yaw = quat_yaw(item.wxyz)
    centre = np.asarray(item.position) + _R(item.wxyz) @ ((lo + hi) / 2)
    cx, cy, cz = (float(v) for v in centre)
    hx, hy, hz = (float(v) for v in (hi - lo) / 2)
    return Box(item.kind, item.id, (cx, cy, cz), (hx, hy, hz), yaw)


def ray_box(origin: np.ndarray, direction: np.ndarray, box: Box) -> float | None:
    """Distance along the ray (``origin`` (3,) [m], ``direction`` (3,) unit) to where it
    enters ``box``; 0 when it starts inside; None when it misses (slab test in the box's
    frame)."""
    c, s = np.cos(-box.yaw), np.sin(-box.yaw)
    Rinv = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    o = Rinv @ (np.asarray(origin, float) - np.asarray(box.centre))
    d = Rinv @ np.asarray(direction, float)
    half = np.asarray(box.half)
    t0, t1 = -np.inf, np.inf
    for k in range(3):
        if abs(d[k]) < 1e-12:
            if abs(o[k]) > half[k]:
                return None
            continue
        a, b = (-half[k] - o[k]) / d[k], (half[k] - o[k]) / d[k]
        t0, t1 = max(t0, min(a, b)), min(t1, max(a, b))
    if t1 < max(t0, 0.0):
        return None
    return float(max(t0, 0.0))


def pick(boxes: list[Box], origin: np.ndarray, direction: np.ndarray) -> Box | None:
    """The nearest box the ray enters (None: it hits none)."""
    hits = [(t, b) for b in boxes if (t := ray_box(origin, direction, b)) is not None]
    return min(hits, key=lambda h: h[0])[1] if hits else None


def floor_point(origin: np.ndarray, direction: np.ndarray, z: float = 0.0) -> Vec3 | None:
    """Where the ray meets the plane at height ``z`` [m] (None: it never does ahead)."""
    o, d = np.asarray(origin, float), np.asarray(direction, float)
    if abs(d[2]) < 1e-12:
        return None
    t = (z - o[2]) / d[2]
    if t < 0:
        return None
    p = o + t * d
    return (float(p[0]), float(p[1]), float(p[2]))


def hit_point(boxes: list[Box], origin: np.ndarray, direction: np.ndarray) -> Vec3 | None:
    """The point a click lands on: the nearest box's surface, else the floor."""
    box = pick(boxes, origin, direction)
    if box is None:
        return floor_point(origin, direction)
    t = ray_box(origin, direction, box)
    assert t is not None
    p = np.asarray(origin, float) + t * np.asarray(direction, float)
    return (float(p[0]), float(p[1]), float(p[2]))

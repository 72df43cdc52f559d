"""The base's floor outline from its own collision geometry.

By default a robot's footprint is the convex hull, seen from above, of the collision geometry
fixed to the base (links on no sampled joint) below the footprint's height, grown by a stated
clearance. The hull holds every point of that geometry: a mesh's triangles are clipped at the
height exactly; a primitive counts whole, by points whose hull holds it (box corners, polygons
circumscribing circles).
"""

from __future__ import annotations

import math
from typing import Any

import coal
import numpy as np
import shapely

from pickstop.errors import RobotConfigError
from pickstop.robot.config import Footprint

_CIRCLE = 16  # sides of the polygons circumscribing round primitives


def _circle(radius: float) -> np.ndarray:
    """``(16, 2)`` vertices of a polygon holding the circle of ``radius`` [m]."""
    a = 2 * math.pi * np.arange(_CIRCLE) / _CIRCLE
    r = radius / math.cos(math.pi / _CIRCLE)
    return np.stack([r * np.cos(a), r * np.sin(a)], 1)


def _local_points(geom: Any) -> np.ndarray | None:
    """Points ``(N, 3)`` in a primitive's frame whose convex hull holds it (None for meshes)."""
    if isinstance(geom, coal.Box):
        h = np.asarray(geom.halfSide, float)
        return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
    if isinstance(geom, coal.Sphere):
        r = float(geom.radius)
        c = _circle(r)
        return np.concatenate([np.c_[c, np.full(len(c), z)] for z in (-r, r)])
    if isinstance(geom, coal.Cylinder | coal.Capsule):
        r, hl = float(geom.radius), float(geom.halfLength)
        reach = hl + (r if isinstance(geom, coal.Capsule) else 0.0)
        c = _circle(r)
        return np.concatenate([np.c_[c, np.full(len(c), z)] for z in (-reach, reach)])
    if isinstance(geom, coal.BVHModelBase):
        return None
    geom.computeLocalAABB()
    lo, hi = np.asarray(geom.aabb_local.min_, float), np.asarray(geom.aabb_local.max_, float)
    corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], float)
    return lo + corners * (hi - lo)


def _clipped_mesh(geom: Any, R: np.ndarray, t: np.ndarray, height: float) -> np.ndarray:
    """Points ``(N, 3)`` of a mesh's part below ``height`` [m] (vertices and edge crossings)."""
    verts = np.asarray(geom.vertices(), float) @ R.T + t
    idx = np.array([[tr[0], tr[1], tr[2]] for tr in map(geom.tri_indices, range(geom.num_tris))])
    if not len(idx):
        return np.zeros((0, 3))
    tris = verts[idx]
    a, b = tris.reshape(-1, 3), tris[:, [1, 2, 0]].reshape(-1, 3)
    cross = (a[:, 2] - height) * (b[:, 2] - height) < 0
    s = (height - a[cross, 2]) / (b[cross, 2] - a[cross, 2])
    crossing = a[cross] + s[:, None] * (b[cross] - a[cross])
    return np.concatenate([verts[verts[:, 2] <= height], crossing])


def base_points(robot: Any, height: float) -> np.ndarray:
    """Floor-plane points ``(N, 2)`` [m] of the base-fixed geometry below ``height`` [m]."""
    pts = []
    for obj in robot.geom_model.geometryObjects:
        if obj.parentJoint != 0:
            continue
        R, t = np.asarray(obj.placement.rotation, float), np.asarray(obj.placement.translation)
        local = _local_points(obj.geometry)
        if local is None:
            pts.append(_clipped_mesh(obj.geometry, R, t, height)[:, :2])
            continue
        world = local @ R.T + t
        if world[:, 2].min() <= height:
            pts.append(world[:, :2])
    return np.concatenate(pts) if pts else np.zeros((0, 2))


def derived_footprint(robot: Any, config: Footprint) -> Footprint:
    """``config`` if it gives a radius or polygon, else the base's outline plus clearance."""
    if config.radius is not None or config.polygon is not None:
        return config
    pts = base_points(robot, config.height)
    if len(pts) < 3:
        raise RobotConfigError(
            f"{robot.urdf_path.name}: no collision geometry fixed to the base below "
            f"{config.height} m to derive a footprint from; give footprint.radius or "
            "footprint.polygon",
            field="footprint",
        )
    hull = shapely.MultiPoint(pts).convex_hull.buffer(config.clearance, quad_segs=2)
    ring = np.asarray(hull.exterior.coords)[:-1]
    return Footprint(
        polygon=[(float(x), float(y)) for x, y in ring],
        height=config.height,
        clearance=config.clearance,
        derived=True,
    )

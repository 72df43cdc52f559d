"""Outlines of a scene's objects in the floor plane, and their height ranges.

Pure shapely and numpy: the scene checks (:mod:`pickstop.scene.checks`) and the supports
(:mod:`pickstop.scene.supports`) see obstacles and trays through these.
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry import Point, Polygon
from shapely.geometry.base import BaseGeometry

from pickstop.frames import R_z, rot2
from pickstop.scene.model import Box, Cylinder, Mesh, Pose, Tray

TOUCH = 1e-6  # [m] resting on a surface is not intersecting it


def rect(cx: float, cy: float, yaw: float, sx: float, sy: float) -> Polygon:
    """Rectangle of size ``sx x sy`` [m] centred at ``(cx, cy)``, rotated by ``yaw`` [rad]."""
    corners = np.array([(-sx / 2, -sy / 2), (sx / 2, -sy / 2), (sx / 2, sy / 2), (-sx / 2, sy / 2)])
    return Polygon(corners @ rot2(yaw).T + (cx, cy))


def footprint(geometry: Box | Cylinder | Mesh, pose: Pose) -> BaseGeometry | None:
    """Floor footprint of a shape at ``pose`` (None for meshes: unknown until loaded)."""
    if isinstance(geometry, Box):
        return rect(pose.x, pose.y, pose.yaw, geometry.size[0], geometry.size[1])
    if isinstance(geometry, Cylinder):
        return Point(pose.x, pose.y).buffer(geometry.radius, quad_segs=16)
    return None


def height(geometry: Box | Cylinder | Mesh) -> float | None:
    """Height [m] of a shape (None for meshes)."""
    if isinstance(geometry, Box):
        return geometry.size[2]
    if isinstance(geometry, Cylinder):
        return geometry.height
    return None


def tray_corners(tray: Tray) -> list[tuple[float, float, float]]:
    """World corners of the tray's outer box (floor bottom to wall top), tilt included."""
    ox, oy = tray.outer_size
    R_world_tray = R_z(tray.pose.yaw)
    if tray.tilt is not None:
        R_world_tray = R_world_tray @ tray.tilt.matrix()
    corners = np.array(
        [
            (x, y, z)
            for x in (-ox / 2, ox / 2)
            for y in (-oy / 2, oy / 2)
            for z in (-tray.floor_thickness, tray.wall_height)
        ]
    )
    world = corners @ R_world_tray.T + (tray.pose.x, tray.pose.y, tray.pose.z)
    return [(float(x), float(y), float(z)) for x, y, z in world]


def tray_footprint(tray: Tray) -> Polygon:
    """The tray's outline in the floor plane (of its tilted box, if tilted)."""
    if tray.tilt is None:
        return rect(tray.pose.x, tray.pose.y, tray.pose.yaw, *tray.outer_size)
    hull = shapely.MultiPoint([(x, y) for x, y, _ in tray_corners(tray)]).convex_hull
    assert isinstance(hull, Polygon)
    return hull


def tray_z_range(tray: Tray) -> tuple[float, float]:
    """Lowest and highest point [m] of the tray's outer box."""
    zs = [z for _, _, z in tray_corners(tray)]
    return (min(zs), max(zs))


def overlaps(a: BaseGeometry, b: BaseGeometry) -> bool:
    """Whether two outlines share more than :data:`TOUCH` of area."""
    return bool(a.intersects(b)) and a.intersection(b).area > TOUCH


def overlap_depth(a: BaseGeometry, b: BaseGeometry) -> float:
    """[m] The shortest slide in the floor plane that parts two outlines (of their convex
    hulls, by separating axes): how deep one reaches into the other."""
    pa = np.asarray(a.convex_hull.exterior.coords)[:-1]  # type: ignore[attr-defined]
    pb = np.asarray(b.convex_hull.exterior.coords)[:-1]  # type: ignore[attr-defined]
    best = np.inf
    for poly in (pa, pb):
        edges = np.roll(poly, -1, axis=0) - poly
        normals = np.stack([-edges[:, 1], edges[:, 0]], 1)
        lengths = np.hypot(*normals.T)
        normals = normals[lengths > 0] / lengths[lengths > 0, None]
        ja, jb = pa @ normals.T, pb @ normals.T  # (n, k) projections
        depth = np.minimum(ja.max(0) - jb.min(0), jb.max(0) - ja.min(0))
        best = min(best, float(depth.min(initial=np.inf)))
    return max(best, 0.0)

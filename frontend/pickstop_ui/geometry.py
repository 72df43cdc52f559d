"""Floor drawings as meshes and line segments: region patches, circles, routes, poses."""

from __future__ import annotations

import itertools
import math

import numpy as np
import shapely
from shapely.geometry import Polygon

from pickstop.frames import rot2


def patch_mesh(polys: list[Polygon], z: float) -> tuple[np.ndarray, np.ndarray]:
    """Triangles covering ``polys`` (holes respected) at height ``z``: vertices, faces."""
    verts: list[np.ndarray] = []
    faces: list[np.ndarray] = []
    n = 0
    for poly in polys:
        if poly.is_empty:
            continue
        tris = shapely.constrained_delaunay_triangles(poly)
        for tri in getattr(tris, "geoms", []):
            xy = np.asarray(tri.exterior.coords)[:3]
            verts.append(np.column_stack([xy, np.full(3, z)]))
            faces.append(np.array([[n, n + 1, n + 2]]))
            n += 3
    if not verts:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint32)
    return np.concatenate(verts).astype(np.float32), np.concatenate(faces).astype(np.uint32)


def ring_segments(coords: np.ndarray, z: float) -> np.ndarray:
    """A closed or open ring of ``(K, 2)`` points as ``(K - 1, 2, 3)`` segments."""
    c = np.asarray(coords, float)
    p = np.column_stack([c, np.full(len(c), z)])
    return np.stack([p[:-1], p[1:]], axis=1)


def circle_segments(
    centre: tuple[float, float], r: float, z: float, n: int = 48, dashed: bool = False
) -> np.ndarray:
    a = np.linspace(0, 2 * math.pi, n + 1)
    pts = np.column_stack([centre[0] + r * np.cos(a), centre[1] + r * np.sin(a)])
    seg = ring_segments(pts, z)
    return seg[::2] if dashed else seg


def route_segments(line: list[tuple[float, float]], z: float, arrow: float = 0.12) -> np.ndarray:
    """The route and a chevron at each leg's middle pointing the way."""
    pts = np.asarray(line, float)
    segs = [ring_segments(pts, z)] if len(pts) > 1 else []
    for a, b in itertools.pairwise(pts):
        d = b - a
        L = float(np.hypot(*d))
        if 3 * arrow > L:
            continue
        u = d / L
        m = a + 0.5 * d
        left, right = (m - arrow * (rot2(a) @ u) for a in (-0.5, 0.5))
        for q in (left, right):
            segs.append(np.array([[[q[0], q[1], z], [m[0], m[1], z]]]))
    return np.concatenate(segs) if segs else np.zeros((0, 2, 3))


def polyline_at(line: np.ndarray, s: float) -> tuple[np.ndarray, float]:
    """The point at arc length ``s`` along ``line: (K, 2)`` and the heading there."""
    seg = np.diff(line, axis=0)
    lens = np.hypot(seg[:, 0], seg[:, 1])
    if len(lens) == 0 or lens.sum() == 0:
        return line[0], 0.0
    s = min(max(s, 0.0), float(lens.sum()))
    k = int(np.searchsorted(np.cumsum(lens), s))
    k = min(k, len(lens) - 1)
    before = float(lens[:k].sum())
    t = (s - before) / lens[k] if lens[k] > 0 else 0.0
    return line[k] + t * seg[k], math.atan2(seg[k, 1], seg[k, 0])

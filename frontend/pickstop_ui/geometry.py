"""Floor drawings as meshes and line segments: region patches, circles, routes, poses."""

from __future__ import annotations

import itertools
import math

import numpy as np
import shapely
from shapely.geometry import Polygon

from pickstop.frames import rot2


def patch_mesh(polys: list[Polygon], z: float) -> tuple[np.ndarray, np.ndarray]:
    """Triangles covering ``polys`` (holes respected) at height ``z``: vertices ``(3T, 3)``
    float32 [m] (three of its own per triangle) and faces ``(T, 3)`` uint32."""
    tris = [
        t
        for poly in polys
        if not poly.is_empty
        for t in getattr(shapely.constrained_delaunay_triangles(poly), "geoms", [])
    ]
    if not tris:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint32)
    # Each triangle's exterior ring holds 4 points (closed): keep the first three.
    xy = shapely.get_coordinates(shapely.get_exterior_ring(np.asarray(tris, dtype=object)))
    xy = xy.reshape(len(tris), 4, 2)[:, :3].reshape(-1, 2)
    verts = np.column_stack([xy, np.full(len(xy), z)]).astype(np.float32)
    return verts, np.arange(len(verts), dtype=np.uint32).reshape(-1, 3)


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

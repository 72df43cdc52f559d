"""Shortest collision-free paths for the base on the floor: a visibility graph.

Obstacles (every solid reaching below the base body's height) are inflated by the footprint's
bounding radius; the polygonal buffer is made to circumscribe the true rounded one, so a path
along its edges never comes closer than the radius. Paths run between the query points and the
inflated corners; a leg is kept only if it stays out of every inflated obstacle and on the floor.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import LineString, Point
from shapely.geometry.base import BaseGeometry

from pickstop.sequence.cover import InfeasiblePlanError

QUAD_SEGS = 3  # segments per quarter circle of the inflation


@dataclass(frozen=True)
class FloorMap:
    """Where the base centre may be: the floor shrunk by the radius, minus inflated obstacles."""

    free: BaseGeometry  # (multi)polygon of allowed base centres
    blocked: BaseGeometry  # inflated obstacles
    corners: np.ndarray  # (V, 2) graph vertices: corners of the inflated obstacles

    @classmethod
    def build(
        cls, floor: tuple[float, float, float, float], obstacles: list[BaseGeometry], radius: float
    ) -> FloorMap:
        """floor: (xmin, ymin, xmax, ymax) [m]; obstacles: floor outlines; radius [m]."""
        # A polygon buffer with n segments per quarter lies inside the true rounded buffer by
        # the sagitta; growing the distance by 1 / cos(pi / (4 n)) makes it circumscribe it.
        grow = radius / math.cos(math.pi / (4 * QUAD_SEGS)) + 1e-4
        blocked = (
            shapely.union_all([o.buffer(grow, quad_segs=QUAD_SEGS) for o in obstacles])
            if obstacles
            else shapely.Polygon()
        )
        inner = shapely.box(*floor).buffer(-radius, join_style="mitre")
        free = inner.difference(blocked)
        pts = []
        for poly in getattr(blocked, "geoms", [blocked]):
            if poly.is_empty:
                continue
            pts.extend(poly.exterior.coords[:-1])
        corners = np.array(pts, float).reshape(-1, 2)
        if len(corners):  # corners off the floor are of no use
            corners = corners[shapely.contains_xy(inner, corners[:, 0], corners[:, 1])]
        return cls(free, blocked, corners)

    def is_free(self, xy: tuple[float, float]) -> bool:
        return bool(self.free.buffer(1e-6).contains(Point(xy)))

    def leg_ok(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Which legs ``a[i] -> b[i]`` stay in the free floor (touching corners allowed)."""
        lines = shapely.linestrings(np.stack([a, b], axis=1))
        core = self.blocked.buffer(-1e-5) if not self.blocked.is_empty else self.blocked
        ok = ~shapely.intersects(lines, core) if not core.is_empty else np.ones(len(a), bool)
        floor = self.free.union(self.blocked).buffer(1e-6)
        return ok & shapely.covers(floor, lines)


@dataclass(frozen=True)
class Paths:
    """Shortest paths between query points: ``dist[i, j]`` [m] (inf if none), polylines."""

    points: np.ndarray  # (Q, 2)
    dist: np.ndarray  # (Q, Q)
    _prev: list[np.ndarray]
    _nodes: np.ndarray  # (Q + V, 2)

    def polyline(self, i: int, j: int) -> np.ndarray:
        """Waypoints ``(K, 2)`` from query point i to j."""
        prev = self._prev[i]
        out = [j]
        while out[-1] != i:
            p = int(prev[out[-1]])
            if p < 0:
                raise InfeasiblePlanError(f"no path from point {i} to point {j}")
            out.append(p)
        return self._nodes[out[::-1]]


def shortest_paths(fmap: FloorMap, points: np.ndarray) -> Paths:
    """All-pairs shortest collision-free paths between ``points: (Q, 2)`` [m]."""
    points = np.asarray(points, float).reshape(-1, 2)
    Q = len(points)
    nodes = np.concatenate([points, fmap.corners])
    n = len(nodes)
    ii, jj = np.triu_indices(n, 1)
    ok = fmap.leg_ok(nodes[ii], nodes[jj])
    ii, jj = ii[ok], jj[ok]
    w = np.linalg.norm(nodes[ii] - nodes[jj], axis=1)
    adj: list[list[tuple[int, float]]] = [[] for _ in range(n)]
    for a, b, d in zip(ii.tolist(), jj.tolist(), w.tolist(), strict=True):
        adj[a].append((b, d))
        adj[b].append((a, d))
    dist = np.full((Q, Q), np.inf)
    prevs = []
    for s in range(Q):
        d = np.full(n, np.inf)
        prev = np.full(n, -1)
        d[s] = 0.0
        heap = [(0.0, s)]
        while heap:
            du, u = heapq.heappop(heap)
            if du > d[u]:
                continue
            for v, wv in adj[u]:
                nd = du + wv
                if nd < d[v] - 1e-12:
                    d[v] = nd
                    prev[v] = u
                    heapq.heappush(heap, (nd, v))
        dist[s] = d[:Q]
        prevs.append(prev)
    return Paths(points, dist, prevs, nodes)


def polyline_clear(fmap: FloorMap, line: np.ndarray) -> bool:
    """Does the polyline ``(K, 2)`` stay out of every inflated obstacle?"""
    if len(line) < 2:
        return True
    core = fmap.blocked.buffer(-1e-5)
    return core.is_empty or not LineString(line).intersects(core)

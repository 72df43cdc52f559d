"""Shortest collision-free paths for the base on the floor: a visibility graph with docking.

Obstacles (every solid reaching below the base body's height) are inflated by the body's
bounding radius; the polygonal buffer is made to circumscribe the true rounded one, so a path
along its edges never comes closer than the radius. In that circle-free floor the base may turn
anywhere. Paths run between the query points, the inflated corners and staging points; a leg is
kept only if it stays out of every inflated obstacle and on the floor.

A query point with a yaw that lies outside the circle-free floor (a long base's stop close to a
table) is *docked*: joined by straight legs driven at its fixed yaw to staging points in the
circle-free floor (the first free point along a few directions and toward the nearest free
point), and to other docked points of the same yaw, each leg kept only if the body swept along
it at that yaw is clear (:class:`Docking`, computed exactly by the caller).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import shapely
import shapely.ops
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra
from shapely.geometry import LineString, Point
from shapely.geometry.base import BaseGeometry

from pickstop.sequence.cover import InfeasiblePlanError

QUAD_SEGS = 3  # segments per quarter circle of the inflation
DOCK_DIRECTIONS = 16  # directions, from the point's own heading, searched for staging points
DOCK_MARGIN = 0.05  # [m] how far past the circle-free floor's edge a staging point goes
MAX_SLIDE = 1.5  # [m] longest fixed-yaw leg tried between two docked points

#: ``sweep(a, b, yaw) -> (blocked, owners)``: is the straight move from ``a[i]`` to ``b[i]``
#: (``(M, 2)`` [m]) at the fixed ``yaw`` [rad] blocked, and by which obstacles (per leg).
Sweep = Callable[[np.ndarray, np.ndarray, float], tuple[np.ndarray, list[set[str]]]]


@dataclass(frozen=True)
class Docking:
    """How points outside the circle-free floor are joined to it."""

    sweep: Sweep
    reach: float  # [m] longest docking leg searched
    #: a differential base moves straight only along its heading (forward or back); an
    #: omnidirectional one in any direction
    omnidirectional: bool = False


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

    @cached_property
    def _free_tol(self) -> BaseGeometry:
        return self.free.buffer(1e-6)

    @cached_property
    def _free_core(self) -> BaseGeometry:
        return self.free.buffer(-1e-4)

    def is_free(self, xy: tuple[float, float]) -> bool:
        return bool(self._free_tol.contains(Point(xy)))

    def free_xy(self, points: np.ndarray) -> np.ndarray:
        """``(Q,)`` which of ``points: (Q, 2)`` [m] lie in the circle-free floor."""
        pts = np.asarray(points, float).reshape(-1, 2)
        return shapely.contains_xy(self._free_tol, pts[:, 0], pts[:, 1])

    def staging(
        self, p: np.ndarray, yaw: float, reach: float, omnidirectional: bool = True
    ) -> np.ndarray:
        """``(S, 2)`` candidate staging points [m] for a docked point ``p``: along
        ``DOCK_DIRECTIONS`` directions from its heading ``yaw`` [rad] and toward the nearest
        circle-free point (a differential base: only straight ahead and straight back), the
        first point within ``reach`` [m] inside the circle-free floor, moved up to
        ``DOCK_MARGIN`` further in."""
        p = np.asarray(p, float).reshape(2)
        core = self._free_core
        if core.is_empty:
            return np.zeros((0, 2))
        n = DOCK_DIRECTIONS if omnidirectional else 2
        ang = yaw + np.arange(n) * 2 * math.pi / n
        dirs = [np.stack([np.cos(ang), np.sin(ang)], axis=1)]
        near = np.asarray(shapely.ops.nearest_points(core, Point(p))[0].coords[0])
        gap = float(np.linalg.norm(near - p))
        if omnidirectional and 1e-9 < gap <= reach:
            dirs.append(((near - p) / gap)[None])
        d = np.concatenate(dirs)
        rays = shapely.linestrings(np.stack([np.broadcast_to(p, d.shape), p + reach * d], axis=1))
        out = []
        for ray, u, piece in zip(rays, d, shapely.intersection(rays, core), strict=True):
            spans = []
            for g in getattr(piece, "geoms", [piece]):
                if g.is_empty or g.geom_type != "LineString":
                    continue
                ends = shapely.line_locate_point(ray, shapely.points(np.asarray(g.coords)))
                spans.append((float(ends.min()), float(ends.max())))
            if not spans:
                continue
            t0, t1 = min(spans)
            out.append(p + (t0 + min(DOCK_MARGIN, (t1 - t0) / 2)) * u)
        if not out:
            return np.zeros((0, 2))
        pts = np.array(out)
        gaps = np.linalg.norm(pts[:, None] - pts[None], axis=2)
        keep = [i for i in range(len(pts)) if not (gaps[i, :i] <= 1e-3).any()]  # one of each
        return pts[keep]

    @cached_property
    def _blocked_core(self) -> BaseGeometry:
        core = self.blocked.buffer(-1e-5) if not self.blocked.is_empty else self.blocked
        shapely.prepare(core)
        return core

    @cached_property
    def _floor_tol(self) -> BaseGeometry:
        floor = self.free.union(self.blocked).buffer(1e-6)
        shapely.prepare(floor)
        return floor

    def leg_ok(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Which legs ``a[i] -> b[i]`` stay in the free floor (touching corners allowed)."""
        lines = shapely.linestrings(np.stack([a, b], axis=1))
        core = self._blocked_core
        ok = ~shapely.intersects(lines, core) if not core.is_empty else np.ones(len(a), bool)
        return ok & shapely.covers(self._floor_tol, lines)

    @cached_property
    def corner_legs(self) -> tuple[np.ndarray, np.ndarray]:
        """The legs between corners that stay in the free floor, ``(i, j)`` (i < j): the same
        for every query of this map, so made once."""
        i, j = np.triu_indices(len(self.corners), 1)
        ok = self.leg_ok(self.corners[i], self.corners[j])
        return i[ok], j[ok]


@dataclass(frozen=True)
class Paths:
    """Shortest paths between query points: ``dist[i, j]`` [m] (inf if none), polylines, the
    yaw held along each docking segment, and why a query point could not be docked."""

    points: np.ndarray  # (Q, 2)
    dist: np.ndarray  # (Q, Q)
    _prev: list[np.ndarray]
    _nodes: np.ndarray  # (Q + V + S, 2): query points, corners, staging points
    _held: dict[tuple[int, int], float] = field(default_factory=dict)  # docking edge -> yaw
    undocked: dict[int, str] = field(default_factory=dict)  # query point -> why not

    def _route(self, i: int, j: int) -> list[int]:
        prev = self._prev[i]
        out = [j]
        while out[-1] != i:
            p = int(prev[out[-1]])
            if p < 0:
                raise InfeasiblePlanError(f"no path from point {i} to point {j}")
            out.append(p)
        return out[::-1]

    def polyline(self, i: int, j: int) -> np.ndarray:
        """Waypoints ``(K, 2)`` from query point i to j."""
        return self._nodes[self._route(i, j)]

    def segment_yaws(self, i: int, j: int) -> list[float | None]:
        """Per segment of :meth:`polyline` ``(i, j)``: the yaw [rad] the base holds along it (a
        docking leg), or None where it may turn as it likes."""
        route = self._route(i, j)
        return [self._held.get((a, b)) for a, b in itertools.pairwise(route)]

    @property
    def docked(self) -> bool:
        """Does any path use a docking leg?"""
        return bool(self._held)


def _along(d: np.ndarray, yaw: float) -> bool:
    """Does the move ``d: (2,)`` [m] run along the heading ``yaw`` [rad] (forward or back)?"""
    return abs(math.cos(yaw) * d[1] - math.sin(yaw) * d[0]) <= 1e-9 * max(1.0, float(np.hypot(*d)))


def shortest_paths(
    fmap: FloorMap,
    points: np.ndarray,
    yaws: np.ndarray | None = None,
    docking: Docking | None = None,
) -> Paths:
    """All-pairs shortest collision-free paths between ``points: (Q, 2)`` [m]; with ``yaws:
    (Q,)`` [rad] (NaN: any) and ``docking``, the points outside the circle-free floor are
    docked at their yaw."""
    points = np.asarray(points, float).reshape(-1, 2)
    Q = len(points)
    yaws = np.full(Q, np.nan) if yaws is None else np.asarray(yaws, float).reshape(Q)
    docked: list[int] = []
    undocked: dict[int, str] = {}
    stage_pts: list[np.ndarray] = []
    dock_edges: list[tuple[int, int, float]] = []  # (query point, node, yaw)
    if docking is not None:
        outside = ~fmap.free_xy(points) & np.isfinite(yaws)
        docked = np.flatnonzero(outside).tolist()
        base = Q + len(fmap.corners)
        for q in docked:
            stage, why = _staging(fmap, points[q], float(yaws[q]), docking)
            if why is not None:
                undocked[q] = why
                continue
            for sxy in stage:
                dock_edges.append((q, base + len(stage_pts), float(yaws[q])))
                stage_pts.append(sxy)
        ok_docked = [q for q in docked if q not in undocked]
        dock_edges += _slides(points, yaws, ok_docked, docking)

    nodes = np.concatenate([points, fmap.corners, np.array(stage_pts, float).reshape(-1, 2)])
    ii, jj = _free_legs(fmap, nodes, docked, Q)
    held: dict[tuple[int, int], float] = {}
    for a, b, yaw in dock_edges:
        held[a, b] = held[b, a] = yaw
    if dock_edges:
        ii = np.concatenate([ii, [a for a, _, _ in dock_edges]]).astype(np.int64)
        jj = np.concatenate([jj, [b for _, b, _ in dock_edges]]).astype(np.int64)
    dist, prevs = _dijkstra(nodes, ii, jj, Q)
    return Paths(points, dist, prevs, nodes, held, undocked)


def _staging(
    fmap: FloorMap, p: np.ndarray, yaw: float, docking: Docking
) -> tuple[np.ndarray, str | None]:
    """The staging points ``(S, 2)`` [m] a docked point ``p`` at ``yaw`` [rad] is reached from
    by a clear straight leg, or (empty, why the point cannot be docked)."""
    none = np.empty((0, 2))
    blocked, owners = docking.sweep(p[None], p[None], yaw)
    if blocked[0]:
        return none, (
            f"the base at yaw {math.degrees(yaw):.0f} deg does not fit there: it meets "
            + ", ".join(sorted(owners[0]))
        )
    stage = fmap.staging(p, yaw, docking.reach, docking.omnidirectional)
    if not len(stage):
        return none, (
            f"no floor where the base may turn lies within {docking.reach:.2f} m of it"
            if docking.omnidirectional
            else f"no floor where the base may turn lies straight ahead or behind it "
            f"within {docking.reach:.2f} m at yaw {math.degrees(yaw):.0f} deg (a "
            "differential base moves straight only along its heading)"
        )
    blocked, owners = docking.sweep(np.repeat(p[None], len(stage), 0), stage, yaw)
    if blocked.all():
        met = sorted(set().union(*owners))
        return none, (
            f"every straight leg at yaw {math.degrees(yaw):.0f} deg toward floor where the "
            f"base may turn ({len(stage)} tried) meets " + ", ".join(met)
        )
    return stage[~blocked], None


def _slides(
    points: np.ndarray, yaws: np.ndarray, docked: list[int], docking: Docking
) -> list[tuple[int, int, float]]:
    """Two docked points of the same yaw: a slide between them at that yaw, where it is clear
    and at most :data:`MAX_SLIDE` long (along the heading for a differential base)."""
    pairs = [
        (a, b)
        for k, a in enumerate(docked)
        for b in docked[k + 1 :]
        if abs(math.remainder(yaws[a] - yaws[b], 2 * math.pi)) < 1e-9
        and np.linalg.norm(points[a] - points[b]) <= MAX_SLIDE
        and (docking.omnidirectional or _along(points[b] - points[a], yaws[a]))
    ]
    edges = []
    for yaw in sorted({float(yaws[a]) for a, _ in pairs}):
        mine = [(a, b) for a, b in pairs if float(yaws[a]) == yaw]
        ia, ib = np.array(mine).T
        blocked, _ = docking.sweep(points[ia], points[ib], yaw)
        edges += [(a, b, yaw) for (a, b), bl in zip(mine, blocked, strict=True) if not bl]
    return edges


def _free_legs(
    fmap: FloorMap, nodes: np.ndarray, docked: list[int], Q: int
) -> tuple[np.ndarray, np.ndarray]:
    """The free-floor legs ``(ii, jj)`` between nodes: between corners as the map keeps them,
    and from each query or staging point not docked to every later node not docked either."""
    n, V = len(nodes), len(fmap.corners)
    visible = np.setdiff1d(np.arange(n), docked)
    vi, vj = np.triu_indices(len(visible), 1)
    ii, jj = visible[vi], visible[vj]
    own = (ii < Q) | (ii >= Q + V) | (jj < Q) | (jj >= Q + V)
    ii, jj = ii[own], jj[own]
    ok = fmap.leg_ok(nodes[ii], nodes[jj])
    ci, cj = fmap.corner_legs
    return np.concatenate([ii[ok], ci + Q]), np.concatenate([jj[ok], cj + Q])


def _dijkstra(
    nodes: np.ndarray, ii: np.ndarray, jj: np.ndarray, Q: int
) -> tuple[np.ndarray, list[np.ndarray]]:
    """Shortest paths from each of the first ``Q`` of ``nodes: (n, 2)`` along the undirected
    straight legs ``ii[k] - jj[k]``: distances ``(Q, Q)`` [m] between them, and from each the
    previous node of every node on its tree (-1: none)."""
    n = len(nodes)
    a, b = np.minimum(ii, jj), np.maximum(ii, jj)
    keep = a != b
    a, b = a[keep], b[keep]
    pair = np.unique(a * n + b)  # a leg found twice is one edge
    a, b = pair // n, pair % n
    w = np.linalg.norm(nodes[a] - nodes[b], axis=1)  # zero-length legs stay edges
    graph = csr_matrix((w, (a, b)), shape=(n, n))
    d, prev = dijkstra(graph, directed=False, indices=np.arange(Q), return_predecessors=True)
    d = np.asarray(d).reshape(Q, n)
    prev = np.where(prev < 0, -1, prev).reshape(Q, n)
    return d[:, :Q].copy(), [prev[s] for s in range(Q)]


def polyline_clear(fmap: FloorMap, line: np.ndarray) -> bool:
    """Does the polyline ``(K, 2)`` stay out of every inflated obstacle?"""
    if len(line) < 2:
        return True
    core = fmap.blocked.buffer(-1e-5)
    return core.is_empty or not LineString(line).intersects(core)

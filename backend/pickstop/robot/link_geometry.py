"""The collision set of a link as coal sees it, in its joint frame, and distances to it.

pinocchio names a link's collision geometries ``<link>_<k>``; all sit on one joint of the reduced
arm model (0 = the fixed base). coal collides a mesh by its *surface* (triangles) and a primitive
(box, cylinder, sphere, capsule) as a *solid*: :class:`LinkShape` is exactly that set, except
that a dense mesh (thousands of triangles: a laser, an e-stop, a base shell) stands in as its
convex hull, a solid that holds it, so that screens built on it stay conservative and bounded.
Cut into small *elements* (sub-triangles, grid cells, padded centres) it feeds the sphere covers of
:mod:`pickstop.robot.spheres`; :func:`distance_grid` samples exact distances to it on a lattice.
"""

from __future__ import annotations

import fnmatch
import re
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import coal
import numpy as np

from pickstop.errors import RobotConfigError
from pickstop.robot.distance_kernel import ROW, mesh_distances, nearest_distances, winding_numbers
from pickstop.robot.model import RobotModel

SdfFn = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class CollisionLink:
    """The collision geometries of one URDF link, all on arm joint ``joint`` (0 = base)."""

    name: str
    joint: int
    geometry_ids: tuple[int, ...]  # indices into robot.geom_model.geometryObjects


def collision_links(robot: RobotModel) -> tuple[CollisionLink, ...]:
    """Group the reduced collision geometries by URDF link (name minus its ``_<k>`` suffix)."""
    ids: dict[str, list[int]] = defaultdict(list)
    joint: dict[str, int] = {}
    for gid, obj in enumerate(robot.geom_model.geometryObjects):
        name = re.sub(r"_\d+$", "", obj.name)
        ids[name].append(gid)
        if joint.setdefault(name, int(obj.parentJoint)) != obj.parentJoint:
            raise RobotConfigError(f"link {name!r} has geometries on two joints")
    return tuple(CollisionLink(n, joint[n], tuple(g)) for n, g in ids.items())


def arm_links(robot: RobotModel) -> list[Any]:
    """Collision links on moving arm bodies, the hand's included unless boxes stand in for
    them (``hand.geometry: boxes``; sorted by name)."""
    boxes = robot.config.hand.geometry == "boxes"
    return sorted(
        (
            link
            for link in collision_links(robot)
            if link.joint != 0 and not (boxes and is_hand_link(robot, link.name))
        ),
        key=lambda link: link.name,
    )


def is_hand_link(robot: RobotModel, name: str) -> bool:
    return any(fnmatch.fnmatch(name, p) for p in robot.config.hand.links)


class _Triangles:
    """A triangle soup ``(T, 3, 3)`` prepared for distance queries by matrix products, and as
    ``rows: (T, ROW)`` for the compiled kernel (:mod:`pickstop.robot.distance_kernel`)."""

    def __init__(self, tris: np.ndarray) -> None:
        self.tris = tris
        a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
        nrm = np.cross(b - a, c - a)
        length = np.linalg.norm(nrm, axis=1)
        self.flat = length <= 1e-12  # degenerate: only its edges count
        nh = np.where(self.flat[:, None], 0.0, nrm / np.where(self.flat, 1.0, length)[:, None])
        us, es, ms = (a, b, c), (b - a, c - b, a - c), []
        for e in es:
            m = np.cross(nh, e)  # in-plane normal of the edge, pointing inwards
            ml = np.linalg.norm(m, axis=1)
            ms.append(np.where((ml > 1e-12)[:, None], m / np.maximum(ml, 1e-12)[:, None], 0.0))
        # Columns: unit normal, 3 inward edge normals, 3 edge vectors, 3 edge origins.
        self.W = np.stack([nh, *ms, *es, *us], axis=0)  # (10, T, 3)
        self.Wt = np.ascontiguousarray(self.W.transpose(2, 0, 1))  # (3, 10, T)
        self.off = np.stack(
            [(nh * a).sum(1), *[(m * u).sum(1) for m, u in zip(ms, us, strict=True)]]
        )  # (4, T)
        self.ue = np.stack([(u * e).sum(1) for u, e in zip(us, es, strict=True)])  # (3, T)
        self.ee = np.stack([np.maximum((e * e).sum(1), 1e-300) for e in es])  # (3, T)
        self.uu = np.stack([(u * u).sum(1) for u in us])  # (3, T)
        self.centre = tris.mean(axis=1)
        self.radius = np.linalg.norm(tris - self.centre[:, None], axis=2).max(axis=1)
        # One row per triangle for distance_kernel (its columns); the pad also covers how far
        # the vertices stray from the computed plane, which the face distance measures to.
        stray = np.abs(np.einsum("tk,tvk->tv", nh, tris - a[:, None])).max(axis=1)
        vectors = self.W.transpose(1, 0, 2).reshape(-1, 30)  # (T, 30): 10 vectors' x, y, z
        pad = self.radius + stray
        scalars = [self.off.T, self.ue.T, self.ee.T, self.uu.T, self.flat[:, None]]
        ball = [self.centre, self.radius[:, None], pad[:, None]]
        self.rows = np.concatenate([vectors, *scalars, *ball], axis=1)
        assert self.rows.shape == (len(tris), ROW)

    def __len__(self) -> int:
        return len(self.tris)

    def bound(self, P: np.ndarray, cand: np.ndarray) -> np.ndarray:
        """``(N, K)`` cheap lower bound of the distance [m], 1-Lipschitz in the point.

        From the triangle's plane and edge half-planes (exact over its face and edges), and
        its bounding ball.
        """
        W = self.Wt[:, :4, cand].reshape(3, -1)
        G = (P @ W).reshape(len(P), 4, len(cand)) - self.off[:, cand]
        beyond = np.maximum(-G[:, 1:].min(axis=1), 0.0)
        slab = np.sqrt(G[:, 0] ** 2 + beyond**2)
        d = np.linalg.norm(P[:, None] - self.centre[cand][None], axis=2) - self.radius[cand]
        return np.maximum(slab, d - 1e-9)

    def exact(self, P: np.ndarray, cand: np.ndarray) -> np.ndarray:
        """``(N, K)`` exact distance [m] from points ``P: (N, 3)`` to triangles ``cand``:
        to the plane if the point projects inside the triangle, else to its nearest edge."""
        G = (P @ self.Wt[:, :, cand].reshape(3, -1)).reshape(len(P), 10, len(cand))
        s = G[:, 1:4] - self.off[1:, cand]
        inside = (s >= 0).all(axis=1) & ~self.flat[cand]
        face = np.where(inside, np.abs(G[:, 0] - self.off[0, cand]), np.inf)
        pp = (P * P).sum(axis=1)[:, None]
        d2 = np.full(face.shape, np.inf)
        for e in range(3):
            pe = G[:, 4 + e] - self.ue[e, cand]
            ee = self.ee[e, cand]
            u = np.clip(pe / ee, 0.0, 1.0)
            pu = pp + self.uu[e, cand] - 2 * G[:, 7 + e]
            d2 = np.minimum(d2, pu - 2 * u * pe + u * u * ee)
        return np.minimum(face, np.sqrt(np.maximum(d2, 0.0)))


def point_triangle_distance(P: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Euclidean distance ``(N, T)`` [m] from points ``P: (N, 3)`` to triangles ``(T, 3, 3)``."""
    ts = _Triangles(tris)
    everything = np.arange(len(ts))
    return np.concatenate(
        [ts.exact(P[s : s + 256], everything) for s in range(0, len(P), 256)]
    ).reshape(len(P), len(ts))


def winding_number(P: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Generalised winding number ``(N,)`` of points w.r.t. a triangle soup (~1 inside)."""
    out = np.empty(len(P))
    for s in range(0, len(P), 256):
        a, b, c = (tris[None, :, k] - P[s : s + 256, None] for k in range(3))
        la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
        det = np.einsum("mtk,mtk->mt", a, np.cross(b, c))
        den = (
            la * lb * lc
            + np.einsum("mtk,mtk->mt", a, b) * lc
            + np.einsum("mtk,mtk->mt", b, c) * la
            + np.einsum("mtk,mtk->mt", c, a) * lb
        )
        out[s : s + 256] = np.arctan2(det, den).sum(axis=1) / (2 * np.pi)
    return np.abs(out)


def _split_triangles(tris: np.ndarray, h: float) -> np.ndarray:
    """Bisect the longest edge of ``tris: (T, 3, 3)`` until every edge is <= ``h`` [m]."""
    done, todo = [], tris
    while len(todo):
        e = np.linalg.norm(todo[:, [1, 2, 0]] - todo, axis=2)  # edge k: vertex k -> k+1
        long = e.max(axis=1) > h
        done.append(todo[~long])
        t, k = todo[long], np.argmax(e[long], axis=1)
        # Rotate so the longest edge is 0 -> 1, then split it at its midpoint.
        order = np.stack([k, (k + 1) % 3, (k + 2) % 3], axis=1)
        t = np.take_along_axis(t, order[:, :, None], axis=1)
        m = 0.5 * (t[:, 0] + t[:, 1])
        todo = np.concatenate(
            [np.stack([t[:, 0], m, t[:, 2]], 1), np.stack([m, t[:, 1], t[:, 2]], 1)]
        )
    return np.concatenate(done)


_CORNERS = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=float)


def _cells(lo: np.ndarray, hi: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Grid cells partitioning ``[lo, hi]``: corners ``(C, 8, 3)`` and centres ``(C, 3)``."""
    n = np.maximum(1, np.ceil((hi - lo) / h)).astype(int)
    size = (hi - lo) / n
    idx = np.stack(np.meshgrid(*[np.arange(m) for m in n], indexing="ij"), -1).reshape(-1, 3)
    cmin = lo + idx * size
    return cmin[:, None] + _CORNERS[None] * size, cmin + 0.5 * size


@dataclass(frozen=True)
class Shape:
    """One coal geometry in the joint frame: a triangle surface or a solid with an SDF."""

    tris: np.ndarray | None  # (T, 3, 3) [m] for a mesh, else None
    sdf: SdfFn | None  # signed distance [m] of points (N, 3) for a solid, else None
    lo: np.ndarray  # (3,) AABB [m]
    hi: np.ndarray  # (3,)
    solid_elements: Callable[[float], tuple[np.ndarray, np.ndarray]] | None = None
    convex: bool = False  # a convex solid (box, sphere, cylinder, capsule)


def _solid(
    sdf_local: SdfFn,
    lo: np.ndarray,
    hi: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    kind: str,
    exact: bool = True,
) -> Shape:
    """A solid given in its own frame, placed by ``x_joint = R x + t``."""

    def sdf(x: np.ndarray) -> np.ndarray:
        return sdf_local((x - t) @ R)

    def elements(h: float) -> tuple[np.ndarray, np.ndarray]:
        if kind == "sphere":  # the sphere itself: its centre padded by its radius
            return t[None, None, :], np.array([hi[0]])
        corners, centres = _cells(lo, hi, h)
        half_diag = 0.5 * np.linalg.norm(corners[0, -1] - corners[0, 0])
        keep = sdf_local(centres) <= half_diag + 1e-12
        pts = corners[keep] @ R.T + t
        return pts, np.zeros(len(pts))

    corners = lo + _CORNERS * (hi - lo)
    world = corners @ R.T + t
    return Shape(None, sdf, world.min(axis=0), world.max(axis=0), elements, convex=exact)


def _box_sdf(half: np.ndarray) -> SdfFn:
    def sdf(x: np.ndarray) -> np.ndarray:
        q = np.abs(x) - half
        return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)

    return sdf


#: A mesh with more triangles than this is screened as its convex hull (a solid that holds
#: every point of it); the exact checks keep the mesh itself.
DENSE_TRIANGLES = 2000
#: A mesh with more triangles than this is refused (its link named) before any work on it.
MAX_TRIANGLES = 2_000_000
#: A hull with more facets than this is screened as its bounding box instead.
MAX_HULL_FACETS = 4096
#: A hull of more facets than this stands in as a simpler polytope: the hull of
#: :data:`HULL_POINTS` of its vertices (spread farthest first), every facet plane moved out
#: until it holds all of them. Its distance costs a tenth of the full hull's and it lies
#: within a millimetre or two of it on a smooth mesh.
HULL_FACETS = 400
HULL_POINTS = 160


def shape_of(geom: Any, placement: Any, name: str = "", dense: bool = False) -> Shape:
    """The :class:`Shape` of a coal geometry placed by a pinocchio ``SE3`` in the joint frame.

    A mesh of more than :data:`DENSE_TRIANGLES` triangles becomes its convex hull (a
    conservative stand-in for the screens: it contains the mesh); ``name`` names the geometry
    in errors; ``dense`` makes any mesh its hull (a link whose meshes are dense together).
    """
    R, t = np.asarray(placement.rotation, float), np.asarray(placement.translation, float)
    if isinstance(geom, coal.BVHModelBase):
        n = int(geom.num_tris)
        if n > MAX_TRIANGLES:
            raise RobotConfigError(
                f"collision mesh {name or '?'} has {n:,} triangles; PickStop handles at most "
                f"{MAX_TRIANGLES:,} per mesh: simplify it",
                field="urdf",
            )
        verts = np.asarray(geom.vertices(), dtype=float) @ R.T + t
        if dense or n > DENSE_TRIANGLES:
            return hull_shape(verts)
        tri = map(geom.tri_indices, range(n))
        idx = np.array([[tr[0], tr[1], tr[2]] for tr in tri])
        tris = verts[idx.reshape(-1, 3)]
        return Shape(tris, None, verts.min(axis=0), verts.max(axis=0))
    if isinstance(geom, coal.Sphere):
        r = float(geom.radius)
        return _solid(
            lambda x: np.linalg.norm(x, axis=1) - r, np.full(3, -r), np.full(3, r), R, t, "sphere"
        )
    if isinstance(geom, coal.Box):
        half = np.asarray(geom.halfSide, dtype=float)
        return _solid(_box_sdf(half), -half, half, R, t, "cells")
    if isinstance(geom, coal.Cylinder):
        r, hl = float(geom.radius), float(geom.halfLength)

        def cyl(x: np.ndarray) -> np.ndarray:
            q = np.stack([np.hypot(x[:, 0], x[:, 1]) - r, np.abs(x[:, 2]) - hl], 1)
            return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)

        return _solid(cyl, np.array([-r, -r, -hl]), np.array([r, r, hl]), R, t, "cells")
    if isinstance(geom, coal.Capsule):
        r, hl = float(geom.radius), float(geom.halfLength)

        def cap(x: np.ndarray) -> np.ndarray:
            z = np.clip(x[:, 2], -hl, hl)
            return np.linalg.norm(x - np.stack([0 * z, 0 * z, z], 1), axis=1) - r

        return _solid(cap, np.array([-r, -r, -hl - r]), np.array([r, r, hl + r]), R, t, "cells")
    if isinstance(geom, coal.Plane | coal.Halfspace):
        raise RobotConfigError(f"unbounded collision geometry {type(geom).__name__} in a link")
    # Any other bounded shape (cone, ellipsoid, convex): its local AABB as a solid box.
    geom.computeLocalAABB()
    lo, hi = np.asarray(geom.aabb_local.min_, float), np.asarray(geom.aabb_local.max_, float)
    c, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    box = _box_sdf(half)
    return _solid(lambda x: box(x - c), lo, hi, R, t, "cells", exact=False)


def hull_shape(points: np.ndarray) -> Shape:
    """A solid holding ``points: (N, 3)`` [m]: their convex hull, or (flat, or too many
    facets) their bounding box. Its signed distance is exact inside and a lower bound outside
    (the largest facet-plane distance), which is what the screens need."""
    from scipy.spatial import ConvexHull, QhullError

    lo, hi = points.min(axis=0), points.max(axis=0)
    try:
        hull = ConvexHull(points)
        eq = hull.equations  # (F, 4): n . x + d <= 0 inside, n outward unit
        if len(eq) > HULL_FACETS:
            eq = _simpler_hull(points[hull.vertices])
    except (QhullError, ValueError):
        eq = None
    if eq is None or len(eq) > MAX_HULL_FACETS:
        half = np.maximum(0.5 * (hi - lo), 1e-4)
        c = 0.5 * (lo + hi)
        return _solid(_box_sdf(half), -half, half, np.eye(3), c, "cells", exact=False)
    normals, offsets = np.ascontiguousarray(eq[:, :3]), eq[:, 3].copy()

    def sdf(x: np.ndarray) -> np.ndarray:
        out = np.empty(len(x))
        for s in range(0, len(x), 4096):
            out[s : s + 4096] = (x[s : s + 4096] @ normals.T + offsets).max(axis=1)
        return out

    return _solid(sdf, lo, hi, np.eye(3), np.zeros(3), "cells", exact=False)


def _simpler_hull(verts: np.ndarray) -> np.ndarray:
    """Facet planes ``(F, 4)`` of a polytope holding ``verts: (N, 3)`` (a hull's vertices)
    with about ``2 HULL_POINTS`` facets: the hull of a spread subset, each plane moved out to
    the farthest vertex along its normal."""
    from scipy.spatial import ConvexHull

    pick = [int(np.argmax(np.linalg.norm(verts - verts.mean(axis=0), axis=1)))]
    d = np.linalg.norm(verts - verts[pick[0]], axis=1)
    for _ in range(min(HULL_POINTS, len(verts)) - 1):  # farthest point first
        pick.append(int(np.argmax(d)))
        d = np.minimum(d, np.linalg.norm(verts - verts[pick[-1]], axis=1))
    eq = np.unique(ConvexHull(verts[pick]).equations.round(12), axis=0)
    eq[:, 3] = -(verts @ eq[:, :3].T).max(axis=0)  # n . v + d <= 0 for every vertex
    return eq


@dataclass(frozen=True)
class LinkShape:
    """The collision set of one link (union of its shapes) in its joint frame."""

    shapes: tuple[Shape, ...]
    lo: np.ndarray = field(init=False)
    hi: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "lo", np.min([s.lo for s in self.shapes], axis=0))
        object.__setattr__(self, "hi", np.max([s.hi for s in self.shapes], axis=0))

    @classmethod
    def of(cls, robot: RobotModel, geometry_ids: tuple[int, ...]) -> LinkShape:
        objs = [robot.geom_model.geometryObjects[g] for g in geometry_ids]
        tris = sum(
            int(o.geometry.num_tris) for o in objs if isinstance(o.geometry, coal.BVHModelBase)
        )
        dense = tris > DENSE_TRIANGLES  # the link's meshes together: each becomes its hull
        return cls(tuple(shape_of(o.geometry, o.placement, o.name, dense) for o in objs))

    def elements(self, h: float) -> tuple[np.ndarray, np.ndarray]:
        """Elements of size <= ~``h`` [m]: points ``(E, 8, 3)`` and pads ``(E,)`` [m]."""
        pts, pads = [], []
        for s in self.shapes:
            if s.tris is not None:
                p = _split_triangles(s.tris, h)
                pad = np.zeros(len(p))
            else:
                assert s.solid_elements is not None
                p, pad = s.solid_elements(h)
            pts.append(np.concatenate([p, np.repeat(p[:, :1], 8 - p.shape[1], axis=1)], axis=1))
            pads.append(pad)
        return np.concatenate(pts), np.concatenate(pads)

    def distance(self, P: np.ndarray) -> np.ndarray:
        """Distance ``(N,)`` [m] from points to the set (0 inside a solid)."""
        d = np.full(len(P), np.inf)
        for s in self.shapes:
            if s.tris is not None:
                d = np.minimum(d, point_triangle_distance(P, s.tris).min(axis=1))
            else:
                assert s.sdf is not None
                d = np.minimum(d, np.maximum(s.sdf(P), 0.0))
        return d

    def depth(self, P: np.ndarray) -> np.ndarray:
        """Depth ``(N,)`` [m] of points inside the link's solids or closed meshes (0 outside).

        Compiled (:mod:`pickstop.robot.distance_kernel`); :func:`winding_number` and
        :func:`point_triangle_distance` are the numpy references it is tested against."""
        d = np.zeros(len(P))
        P = np.ascontiguousarray(P, dtype=float)
        for s in self.shapes:
            if s.tris is not None:
                tris = np.ascontiguousarray(s.tris, dtype=float)
                wn = np.empty(len(P))
                winding_numbers(P, tris, wn)
                inside = np.flatnonzero(wn > 0.5)
                if len(inside):
                    near = np.empty(len(inside))
                    rows = _Triangles(tris).rows
                    nearest_distances(P[inside], rows, np.arange(len(rows)), near)
                    d[inside] = np.maximum(d[inside], near)
            else:
                assert s.sdf is not None
                d = np.maximum(d, -s.sdf(P))
        return d


def distance_grid(
    link: LinkShape, origin: np.ndarray, dims: tuple[int, int, int], h: float, cap: float = 0.1
) -> np.ndarray:
    """Lower bound ``dims`` [m] of the distance from lattice nodes ``origin + i h`` to ``link``.

    Exact up to ``cap`` [m]; beyond it a cheaper bound that is still >= ``cap``.
    """
    axes = [origin[k] + h * np.arange(dims[k]) for k in range(3)]
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    out = np.full(len(nodes), np.inf)
    for s in link.shapes:
        if s.sdf is not None:
            out = np.minimum(out, np.maximum(s.sdf(nodes), 0.0))
            continue
        assert s.tris is not None
        out = np.minimum(out, _mesh_distance(nodes.reshape(*dims, 3), s.tris, cap).ravel())
    return out.reshape(dims)


def _mesh_distance(nodes: np.ndarray, tris: np.ndarray, cap: float, bs: int = 6) -> np.ndarray:
    """:func:`mesh_distance_reference`, compiled
    (:func:`~pickstop.robot.distance_kernel.mesh_distances`)."""
    out = np.full(nodes.shape[:3], np.inf)  # no triangles: nothing is near
    if len(tris):
        mesh_distances(np.ascontiguousarray(nodes), _Triangles(tris).rows, cap, bs, out)
    return out


def mesh_distance_reference(
    nodes: np.ndarray, tris: np.ndarray, cap: float, bs: int = 6
) -> np.ndarray:
    """Distance from ``nodes: (nx, ny, nz, 3)`` to a triangle soup [m]: exact up to ``cap``,
    a lower bound beyond. Per block of ``bs^3`` nodes, only triangles that may be nearest
    (by a 1-Lipschitz bound taken at the block centre) are measured."""
    ts = _Triangles(tris)
    everything = np.arange(len(ts))
    out = np.empty(nodes.shape[:3])
    nx, ny, nz = nodes.shape[:3]
    for i in range(0, nx, bs):
        for j in range(0, ny, bs):
            for k in range(0, nz, bs):
                blk = nodes[i : i + bs, j : j + bs, k : k + bs]
                P = blk.reshape(-1, 3)
                cb = 0.5 * (P.min(axis=0) + P.max(axis=0))
                rb = float(np.linalg.norm(P - cb, axis=1).max())
                lb = ts.bound(cb[None], everything)[0] - rb  # holds for every node
                near = int(np.argmin(lb))
                ub = float(ts.exact(cb[None], np.array([near]))[0, 0]) + rb
                keep = lb <= min(ub, cap + 2 * rb)
                floor = float(lb[~keep].min()) if (~keep).any() else np.inf
                cand = np.flatnonzero(keep)
                val = np.full(len(P), floor)
                if len(cand):
                    val = np.minimum(val, ts.exact(P, cand).min(axis=1))
                out[i : i + bs, j : j + bs, k : k + bs] = val.reshape(blk.shape[:3])
    return out

"""Where the base itself fits: its footprint on the floor and its fixed upper body.

The robot config declares the base as a footprint (a circle or a polygon) up to a height; the
links fixed to the base above that height (TIAGo's torso column, its antennas) are checked
too, as their bounding boxes, so that a base under an overhang (a shelf, a table top without
legs) is never called free when its torso would touch it.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from pickstop.frames import rot2
from pickstop.regions.keep import Keep, KeepNothing
from pickstop.robot.model import RobotModel
from pickstop.scene.model import Scene
from pickstop.scene.world import Solid, scene_solids

QUAD_SEGS = 8  # segments per quarter circle of a buffered outline


@dataclass(frozen=True)
class UpperBody:
    """Boxes ``(N, 2, 3)`` (lo, hi) in the base frame [m] of the base-fixed links above the
    footprint's height, cut off below it (the footprint covers that part)."""

    boxes: np.ndarray
    top: float  # [m] highest point of the base body, footprint included
    radius: float  # [m] farthest horizontal reach of the base body from the base origin
    within_footprint: bool  # seen from above, inside the footprint's circle


def upper_body(robot: RobotModel) -> UpperBody:
    """The robot's base-fixed links above its footprint (made once per loaded robot and kept
    in its ``derived`` data)."""
    hit = robot.derived.upper_body
    if isinstance(hit, UpperBody):
        return hit
    from pickstop.robot.link_geometry import collision_links

    fp = robot.footprint
    boxes = []
    for link in collision_links(robot):
        if link.joint != 0:
            continue
        for gid in link.geometry_ids:
            obj = robot.geom_model.geometryObjects[gid]
            obj.geometry.computeLocalAABB()
            lo = np.asarray(obj.geometry.aabb_local.min_)
            hi = np.asarray(obj.geometry.aabb_local.max_)
            T_base_geom = obj.placement  # joint 0: the base frame
            c = T_base_geom.rotation @ ((lo + hi) / 2) + T_base_geom.translation
            h = np.abs(T_base_geom.rotation) @ ((hi - lo) / 2)
            if c[2] + h[2] > fp.height:
                boxes.append([np.maximum(c - h, [-np.inf, -np.inf, fp.height]), c + h])
    arr = np.array(boxes, float).reshape(-1, 2, 3)
    corners = np.abs(arr[:, :, :2]).max(axis=1) if len(arr) else np.zeros((0, 2))
    reach = float(max([0.0, *np.hypot(corners[:, 0], corners[:, 1])]))
    body = UpperBody(
        arr,
        float(max([fp.height, *arr[:, 1, 2]])),
        max(fp.bounding_radius, reach),
        fp.radius is not None and reach <= fp.radius,
    )
    robot.derived.upper_body = body
    return body


def footprint_free(
    scene: Scene,
    robot: RobotModel,
    centres: np.ndarray,
    yaw: float,
    solids: list[Solid] | None = None,
) -> np.ndarray:
    """``(M,)`` True where the base at ``centres: (M, 2)`` [m], ``yaw`` [rad] stands on the
    floor clear of every solid: its footprint clear of whatever reaches below the footprint's
    height (tables, pillars, racks), its upper body clear of whatever overhangs. ``solids``:
    the scene's (:func:`~pickstop.scene.world.scene_solids`), if made already."""
    return footprint_check(scene, robot, centres, yaw, solids)[0]


def footprint_check(
    scene: Scene,
    robot: RobotModel,
    centres: np.ndarray,
    yaw: float,
    solids: list[Solid] | None = None,
) -> tuple[np.ndarray, set[str]]:
    """:func:`footprint_free`, and the owners of overhanging solids that block a position
    whose footprint is clear (moving one of them may free it)."""
    r = robot.footprint.bounding_radius
    x, y = centres[:, 0], centres[:, 1]
    floor = shapely.box(*scene.floor.min, *scene.floor.max).buffer(-r)
    ok = shapely.contains_xy(floor, x, y) if not floor.is_empty else np.zeros(len(x), bool)
    solids = scene_solids(scene) if solids is None else solids
    ok &= ~blocked_by(robot, solids, centres, yaw, upper=False)
    idx = np.flatnonzero(ok)
    upper = _blocked_region(robot, solids, yaw, footprint=False, upper=True)
    at, piece = upper.query(x[idx], y[idx])
    ok[idx[at]] = False
    return ok, {upper.owners[k] for k in piece.tolist()}


def blocked_by(
    robot: RobotModel,
    solids: list[Solid],
    centres: np.ndarray,
    yaw: float,
    footprint: bool = True,
    upper: bool = True,
    keep: bool = True,
) -> np.ndarray:
    """``(M,)`` True where the base at ``centres: (M, 2)`` [m], ``yaw`` [rad] touches one of
    ``solids``: its footprint (``footprint``) or its upper body (``upper``). ``keep``: the
    blocked region is kept for the next call with these solids (False for a one-off test,
    so that it does not push out the regions of whole scenes)."""
    fp = robot.footprint
    x, y = centres[:, 0], centres[:, 1]
    blocked = _blocked_region(robot, solids, yaw, footprint, upper, keep)
    out = blocked.inside(x, y)
    if blocked.concave is not None:
        # A concave footprint: exact test per position near an obstacle.
        rot = np.asarray(fp.polygon) @ rot2(yaw).T
        near = np.flatnonzero(shapely.contains_xy(blocked.concave.buffer(fp.bounding_radius), x, y))
        for i in near:
            out[i] = shapely.Polygon(rot + centres[i]).intersects(blocked.concave)
    return out


@dataclass(frozen=True)
class Blocked:
    """Where the base at one yaw may not stand for some solids: convex pieces of base
    positions (closed; one or a few per solid, each with its bounds), and for a concave
    footprint the union of the outlines that reach below its height, tested per position."""

    pieces: tuple[BaseGeometry, ...]
    owners: tuple[str, ...]  # of the solid each piece is of
    concave: BaseGeometry | None
    bounds: np.ndarray  # (P, 4) [m] each piece's (xmin, ymin, xmax, ymax)

    @classmethod
    def of(cls, pieces: list[tuple[BaseGeometry, str]], concave: BaseGeometry | None) -> Blocked:
        geoms = [g for g, _ in pieces]
        bounds = shapely.bounds(geoms).reshape(-1, 4) if geoms else np.zeros((0, 4))
        return cls(tuple(geoms), tuple(o for _, o in pieces), concave, bounds)

    def query(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each (position, piece) where the base position ``(x[i], y[i])`` lies in the piece
        (its edge included): two ``(H,)`` int arrays. The positions are sorted by x once; a
        piece tests exactly only those within its bounds (O(P log M) besides the hits)."""
        if not self.pieces or not len(x):
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        order = np.argsort(x, kind="stable")
        xs = x[order]
        first = np.searchsorted(xs, self.bounds[:, 0], side="left")
        last = np.searchsorted(xs, self.bounds[:, 2], side="right")
        at: list[np.ndarray] = []
        piece: list[np.ndarray] = []
        for k in np.flatnonzero(last > first).tolist():
            cand = order[first[k] : last[k]]
            yc = y[cand]
            cand = cand[(yc >= self.bounds[k, 1]) & (yc <= self.bounds[k, 3])]
            if len(cand):
                cand = cand[shapely.intersects_xy(self.pieces[k], x[cand], y[cand])]
            if len(cand):
                at.append(cand)
                piece.append(np.full(len(cand), k, np.int64))
        if not at:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        return np.concatenate(at).astype(np.int64), np.concatenate(piece)

    def inside(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """``(M,)`` True where a base position ``(x, y)`` lies in a piece."""
        out = np.zeros(len(x), bool)
        out[self.query(x, y)[0]] = True
        return out


def _blocked_region(
    robot: RobotModel,
    solids: list[Solid],
    yaw: float,
    footprint: bool,
    upper: bool,
    keep: bool = True,
) -> Blocked:
    """Where the base at ``yaw`` may not stand for ``solids`` (:class:`Blocked`), kept per
    solids, yaw and body parts where the speed-ups keep them (:func:`_kept`; a point's test
    is then a lookup), from pieces kept per solid (a layout that moves one tray makes that
    tray's pieces alone anew)."""
    key = (_solids_key(solids), float(yaw), footprint, upper)
    memo = _kept(robot, "blocked_regions")
    hit = memo.get(key)
    if hit is not None:
        return hit  # type: ignore[no-any-return]
    fp = robot.footprint
    pieces: list[tuple[BaseGeometry | None, str]] = []
    concave = None
    low = [s for s in solids if s.aabb()[0][2] < fp.height]
    if footprint and low:
        convex = fp.radius is not None
        if not convex:
            outline = shapely.Polygon(np.asarray(fp.polygon) @ rot2(yaw).T)
            convex = outline.equals(outline.convex_hull)
        if convex:
            pieces += [(_piece(robot, s, yaw, "footprint"), s.owner) for s in low]
        else:
            concave = shapely.union_all([shapely.Polygon(floor_outline(s)) for s in low])
    if upper:
        body = upper_body(robot)
        high = (
            [s for s in solids if s.aabb()[0][2] >= fp.height] if body.within_footprint else solids
        )
        pieces += [(_piece(robot, s, yaw, "upper"), s.owner) for s in high]
    out = Blocked.of([(g, o) for g, o in pieces if g is not None], concave)
    if not keep:
        return out
    return memo.put(key, out)  # type: ignore[no-any-return]


def _piece(robot: RobotModel, solid: Solid, yaw: float, body: str) -> BaseGeometry | None:
    """The base positions at ``yaw`` where the ``body`` ("footprint": a circle, or a convex
    polygon; or "upper") touches ``solid`` (None: nowhere), kept where the speed-ups keep
    them (:func:`_kept`).

    A circle's are the solid's floor outline buffered by its radius (grown by the sagitta, so
    that the polygon covers the true rounded buffer); a convex polygon's, the Minkowski
    difference, the hull of the vertex differences (exact); the upper body's, those of each
    of its boxes that overlaps the solid in height (:func:`_upper_blocked`)."""
    key = (_solids_key([solid]), float(yaw), body)
    kept = _kept(robot, "blocked_pieces")
    return kept.get_or_make(key, lambda: _made_piece(robot, solid, yaw, body))


def _made_piece(robot: RobotModel, solid: Solid, yaw: float, body: str) -> BaseGeometry | None:
    fp = robot.footprint
    out: BaseGeometry | None
    if body == "upper":
        out = _upper_blocked(upper_body(robot), [solid], yaw)
    elif fp.radius is not None:
        grow = fp.radius / math.cos(math.pi / (4 * QUAD_SEGS)) + 1e-6
        out = shapely.Polygon(floor_outline(solid)).buffer(grow, quad_segs=QUAD_SEGS)
    else:
        rot = np.asarray(fp.polygon) @ rot2(yaw).T
        diff = (floor_outline(solid)[:-1, None, :] - rot[None, :, :]).reshape(-1, 2)
        out = shapely.MultiPoint(diff).convex_hull
    return out


def _kept(robot: RobotModel, name: str) -> Keep[Any, Any]:
    """Where the blocked regions or pieces of ``robot`` are kept: the :class:`Keep` the
    speed-ups hung on its ``derived`` data under ``name``, else nowhere."""
    keep = getattr(robot.derived, name)
    return keep if keep is not None else KeepNothing()


def _solids_key(solids: list[Solid]) -> str:
    """What a blocked region depends on of ``solids``: each one's bounding box (its pose and
    half extents; :func:`floor_outline` and the heights look at nothing else)."""
    h = hashlib.sha256()
    for s in solids:
        h.update(s.pose_digest())
    return h.hexdigest()


def _upper_blocked(body: UpperBody, solids: list[Solid], yaw: float) -> BaseGeometry | None:
    """Base positions where an upper-body box at ``yaw`` meets a solid it overlaps in height:
    per pair, the Minkowski difference of two convex outlines (hull of vertex differences)."""
    if not len(body.boxes):
        return None
    R = rot2(yaw)
    parts = []
    for solid in solids:
        lo, hi = solid.aabb()
        over = (body.boxes[:, 0, 2] < hi[2]) & (body.boxes[:, 1, 2] > lo[2])
        if not over.any():
            continue
        outline = floor_outline(solid)[:-1]
        for blo, bhi in body.boxes[over]:
            (x0, y0), (x1, y1) = blo[:2], bhi[:2]
            rect = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
            world = rect @ R.T  # the box's outline around a base at the origin
            diff = (outline[:, None, :] - world[None, :, :]).reshape(-1, 2)
            parts.append(shapely.MultiPoint(diff).convex_hull)
    return shapely.union_all(parts) if parts else None


def floor_outline(solid: Solid) -> np.ndarray:
    """Floor-plane outline of a solid (its bounding box corners projected, convex)."""
    T, h = solid.T_world_solid, solid.half
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
    pts = (corners @ T[:3, :3].T + T[:3, 3])[:, :2]
    return np.asarray(shapely.MultiPoint(pts).convex_hull.exterior.coords)


@dataclass(frozen=True)
class BodyPieces:
    """The base body seen from above as convex pieces in the base frame, each with the
    heights it spans: the footprint (below its height) and each upper-body box. A solid blocks
    a piece when their outlines meet and their heights overlap (as in :func:`blocked_by`)."""

    outlines: tuple[np.ndarray, ...]  # (K_i, 2) convex, in the base frame [m]
    z_lo: np.ndarray  # (P,) [m]; -inf for the footprint
    z_hi: np.ndarray  # (P,) [m]


def body_pieces(robot: RobotModel) -> BodyPieces:
    """The footprint (a circle as its circumscribed 32-gon, a concave polygon as triangles)
    and the upper body's boxes of ``robot``."""
    fp = robot.footprint
    if fp.radius is not None:
        n = 32
        r = fp.radius / math.cos(math.pi / n) + 1e-6  # circumscribes the circle
        a = np.arange(n) * 2 * math.pi / n
        pieces = [np.stack([r * np.cos(a), r * np.sin(a)], axis=1)]
    else:
        poly = shapely.Polygon(fp.polygon)
        if poly.equals(poly.convex_hull):
            pieces = [np.asarray(fp.polygon, float)]
        else:  # triangles of the polygon: their swept hulls cover exactly its sweep
            tris = shapely.constrained_delaunay_triangles(poly)
            pieces = [np.asarray(t.exterior.coords[:-1]) for t in tris.geoms]
    lo = [-math.inf] * len(pieces)
    hi = [fp.height] * len(pieces)
    for blo, bhi in upper_body(robot).boxes:
        (x0, y0), (x1, y1) = blo[:2], bhi[:2]
        pieces.append(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]))
        lo.append(float(blo[2]))
        hi.append(float(bhi[2]))
    return BodyPieces(tuple(pieces), np.array(lo), np.array(hi))


@dataclass(frozen=True)
class FloorSolids:
    """Solids' floor outlines with their height spans, for sweeping the body against."""

    outlines: list[BaseGeometry]
    owners: list[str]
    z_lo: np.ndarray  # (S,) [m]
    z_hi: np.ndarray  # (S,) [m]
    floor: BaseGeometry  # the floor rectangle: the body stays on it

    @classmethod
    def of(cls, scene: Scene, solids: list[Solid] | None = None) -> FloorSolids:
        solids = scene_solids(scene) if solids is None else solids
        boxes = [s.aabb() for s in solids]
        return cls(
            [shapely.Polygon(floor_outline(s)) for s in solids],
            [s.owner for s in solids],
            np.array([b[0][2] for b in boxes]).reshape(-1),
            np.array([b[1][2] for b in boxes]).reshape(-1),
            shapely.box(*scene.floor.min, *scene.floor.max),
        )


def sweep_blocked(
    body: BodyPieces, world: FloorSolids, a: np.ndarray, b: np.ndarray, yaw: float
) -> tuple[np.ndarray, list[set[str]]]:
    """Is the straight move of the base from ``a[i]`` to ``b[i]`` (each ``(M, 2)`` [m]) at a
    fixed ``yaw`` [rad] blocked? The area a convex piece sweeps is exactly the convex hull of
    the piece at both ends (the Minkowski sum of the segment and the piece); a leg is blocked
    where a piece's sweep meets a solid it overlaps in height, or leaves the floor. Returns
    ``(M,)`` blocked and, per leg, the owners of the solids met ("floor" for the edge)."""
    a, b = np.asarray(a, float).reshape(-1, 2), np.asarray(b, float).reshape(-1, 2)
    assert a.shape == b.shape, (a.shape, b.shape)
    M = len(a)
    out = np.zeros(M, bool)
    owners: list[set[str]] = [set() for _ in range(M)]
    if not M:
        return out, owners
    R = rot2(yaw)
    tree = shapely.STRtree(world.outlines) if world.outlines else None
    for outline, lo, hi in zip(body.outlines, body.z_lo, body.z_hi, strict=True):
        rot = outline @ R.T
        pts = np.concatenate([a[:, None, :] + rot[None], b[:, None, :] + rot[None]], axis=1)
        hulls = shapely.convex_hull(shapely.multipoints(pts))
        off = ~shapely.covers(world.floor, hulls)
        out |= off
        for i in np.flatnonzero(off):
            owners[i].add("floor")
        if tree is None:
            continue
        leg, sol = tree.query(hulls, predicate="intersects")
        keep = (world.z_lo[sol] < hi) & (world.z_hi[sol] > lo)
        for i, s in zip(leg[keep].tolist(), sol[keep].tolist(), strict=True):
            out[i] = True
            owners[i].add(world.owners[s])
    return out, owners

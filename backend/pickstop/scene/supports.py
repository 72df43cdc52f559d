"""What a tray stands on: the floor, a table or shelf top, a box obstacle's top face.

A tray rests on a support when its lowest point is at most :data:`SUPPORT_GAP` above the
support's top face (never below it: that is an intersection) and its outline in the floor
plane lies on the top faces at that height, reaching at most :data:`SUPPORT_OVERHANG` past
their edges. Faces of the same height side by side (two tables pushed together) carry a tray
together. A mesh obstacle carries a tray that lies within its bounding box (the mesh's shelves
are not told apart). :func:`support_problems` names every tray that floats or overhangs;
:func:`place_tray` finds, for a tray footprint at ``(x, y, yaw)``, the support under it, the
height that rests it there and whether it is free (the planner's drag and "add a copy").
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np
import shapely
import shapely.affinity
from shapely.geometry import Point, Polygon
from shapely.geometry.base import BaseGeometry

from pickstop.caching import Cache
from pickstop.scene.model import Mesh, Obstacle, Pose, Scene, Tray
from pickstop.scene.outline import (
    TOUCH,
    footprint,
    height,
    overlap_depth,
    tray_footprint,
    tray_z_range,
)

SUPPORT_GAP = 0.02  # [m] a tray's lowest point may stand this far above its support's top
SUPPORT_OVERHANG = 0.02  # [m] its outline may reach this far past the support's edges
SAME_HEIGHT = 1e-3  # [m] top faces this close in height carry a tray together
FLOOR = "floor"  # the support id of the floor


@dataclass(frozen=True)
class Surface:
    """A face that can carry trays: its id (an obstacle's, or ``"floor"``), its height [m]
    and its outline in the floor plane. ``low`` [m] is the lowest height it carries a tray at:
    its top for a floor, a box or a cylinder, the bounding box's bottom for a mesh."""

    id: str
    top: float
    outline: Polygon
    low: float

    @property
    def name(self) -> str:
        return "the floor" if self.id == FLOOR else f"the top of obstacle {self.id!r}"


@dataclass(frozen=True)
class Solid2:
    """An object as the tray checks see it: its id, kind, outline and height range [m]."""

    id: str
    kind: str  # "obstacle" or "tray"
    outline: BaseGeometry
    z0: float
    z1: float


@dataclass(frozen=True)
class Placement:
    """Where a tray footprint at ``(x, y, yaw)`` would stand: ``support`` (an obstacle id,
    ``"floor"``, or None: nothing is under it), ``z`` the tray pose's height [m] that rests it
    on that support (None without one), ``free``: it stands there, on the support within
    :data:`SUPPORT_OVERHANG`, inside the floor, without meeting another tray or a solid;
    ``problem`` says why not, naming what and how far [m]; ``top`` the support's top face
    height [m] (None without one)."""

    tray: str
    x: float
    y: float
    yaw: float
    z: float | None
    support: str | None
    free: bool
    problem: str | None = None
    top: float | None = None

    def pose(self) -> Pose:
        """The tray pose of this placement (``z`` 0 if nothing carries it)."""
        return Pose(x=self.x, y=self.y, z=self.z or 0.0, yaw=self.yaw)


def _mesh_bounds(path: str, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """The mesh file's local bounding box [m] at ``scale``, kept while the file is the same:
    keyed by the file's identity (its time and size), so a changed file is read again."""
    st = os.stat(path)
    key = (path, scale, st.st_mtime_ns, st.st_size)
    return _BOUNDS.get_or_make(key, lambda: _file_bounds(path, scale))


_BOUNDS: Cache[tuple[str, float, int, int], tuple[np.ndarray, np.ndarray]] = Cache(
    "scene.mesh_bounds", max_items=256
)


def _file_bounds(path: str, scale: float) -> tuple[np.ndarray, np.ndarray]:
    import coal

    mesh = coal.MeshLoader().load(path, np.full(3, scale))
    mesh.computeLocalAABB()
    return np.asarray(mesh.aabb_local.min_), np.asarray(mesh.aabb_local.max_)


def _mesh_surface(ob: Obstacle) -> Surface | None:
    """The bounding box of a mesh obstacle as a support (None if the file cannot be read)."""
    assert isinstance(ob.geometry, Mesh)
    try:
        lo, hi = _mesh_bounds(ob.geometry.path, ob.geometry.scale)
    except Exception:  # an unreadable mesh carries nothing (the file check names it)
        return None
    corners = np.array([(x, y) for x in (lo[0], hi[0]) for y in (lo[1], hi[1])])
    c, s = math.cos(ob.pose.yaw), math.sin(ob.pose.yaw)
    xy = corners @ np.array([[c, s], [-s, c]]) + (ob.pose.x, ob.pose.y)
    hull = shapely.MultiPoint([tuple(p) for p in xy]).convex_hull
    if not isinstance(hull, Polygon):
        return None
    return Surface(ob.id, ob.pose.z + float(hi[2]), hull, ob.pose.z + float(lo[2]))


def surfaces(scene: Scene) -> list[Surface]:
    """Every face of ``scene`` that can carry a tray: the floor, then each obstacle's top."""
    f = scene.floor
    out = [Surface(FLOOR, 0.0, shapely.box(f.min[0], f.min[1], f.max[0], f.max[1]), 0.0)]
    for ob in scene.obstacles:
        if isinstance(ob.geometry, Mesh):
            mesh = _mesh_surface(ob)
            if mesh is not None:
                out.append(mesh)
            continue
        outline, h = footprint(ob.geometry, ob.pose), height(ob.geometry)
        assert isinstance(outline, Polygon) and h is not None
        out.append(Surface(ob.id, ob.pose.z + h, outline, ob.pose.z + h))
    return out


def solids(scene: Scene, exclude: str | None = None) -> list[Solid2]:
    """Every obstacle (meshes aside: unknown until loaded) and tray of ``scene`` but the tray
    ``exclude``, as outlines with height ranges."""
    out = []
    for ob in scene.obstacles:
        outline, h = footprint(ob.geometry, ob.pose), height(ob.geometry)
        if outline is not None and h is not None:
            out.append(Solid2(ob.id, "obstacle", outline, ob.pose.z, ob.pose.z + h))
    for t in scene.trays:
        if t.id != exclude:
            out.append(Solid2(t.id, "tray", tray_footprint(t), *tray_z_range(t)))
    return out


# -- a tray as it stands -------------------------------------------------------------------------
def _carriers(faces: list[Surface], outline: BaseGeometry, z0: float, z1: float) -> list[Surface]:
    """The faces under ``outline`` (area > TOUCH) that could carry a tray whose height range
    is ``z0..z1``: below its top, and (a mesh) not wholly above its bottom."""
    out = []
    for s in faces:
        if s.top > z1 + TOUCH or s.low > z0 + TOUCH:
            continue
        if s.outline.intersects(outline) and s.outline.intersection(outline).area > TOUCH:
            out.append(s)
    return out


def _resting_height(s: Surface, z0: float) -> float:
    """The height [m] at which ``s`` meets a tray whose bottom is at ``z0``: its top, or for a
    mesh any height within its bounds."""
    return s.top if s.low == s.top else min(s.top, max(z0, s.low))


def resting_problem(faces: list[Surface], tray: Tray) -> str | None:
    """Why ``tray`` as placed does not rest on the ``faces`` (None if it does): floating,
    with how far above what; or overhanging, with how far past which edge. A tray sunk into a
    face is left to the intersection check."""
    outline = tray_footprint(tray)
    z0, z1 = tray_z_range(tray)
    under = _carriers(faces, outline, z0, z1)
    if not under:
        return f"tray {tray.id!r} stands on nothing: there is no support under it"
    heights = [_resting_height(s, z0) for s in under]
    h = max(heights)
    if h > z0 + TOUCH:
        return None  # it cuts into a face: an intersection, reported as such
    gap = z0 - h
    top = under[heights.index(h)]
    if gap > SUPPORT_GAP:
        return (
            f"tray {tray.id!r} stands on nothing: its bottom is {gap:.3f} m above {top.name} "
            f"(at most {SUPPORT_GAP} m)"
        )
    carrying = [s for s, hh in zip(under, heights, strict=True) if hh >= h - SAME_HEIGHT]
    past = overhang(outline, [s.outline for s in carrying])
    if past > SUPPORT_OVERHANG:
        names = " and ".join(s.name for s in carrying)
        return (
            f"tray {tray.id!r} overhangs the edge of {names} by {past:.3f} m "
            f"(at most {SUPPORT_OVERHANG} m): part of it stands on nothing"
        )
    return None


def overhang(outline: BaseGeometry, faces: list[Polygon]) -> float:
    """[m] How far the farthest corner of ``outline`` lies outside the union of ``faces``."""
    union = shapely.union_all(faces)
    coords = np.asarray(outline.exterior.coords)  # type: ignore[attr-defined]
    return float(max(union.distance(Point(x, y)) for x, y in coords))


def support_problems(scene: Scene) -> list[tuple[str, str]]:
    """(field, message) for every tray of ``scene`` that does not rest on a support."""
    faces = surfaces(scene)
    out = []
    for i, tray in enumerate(scene.trays):
        why = resting_problem(faces, tray)
        if why is not None:
            out.append((f"trays.{i}.pose", why))
    return out


def intersection_problem(tray: Tray, other: Solid2) -> str | None:
    """Why ``tray`` meets ``other`` (None if it does not), with how deep [m]: the least of
    the overlap in height and the shortest slide apart in the floor plane."""
    outline = tray_footprint(tray)
    z0, z1 = tray_z_range(tray)
    dz = min(z1, other.z1) - max(z0, other.z0)
    if dz <= TOUCH or not outline.intersects(other.outline):
        return None
    if outline.intersection(other.outline).area <= TOUCH:
        return None
    depth = min(dz, overlap_depth(outline, other.outline))
    return f"tray {tray.id!r} intersects {other.kind} {other.id!r} (by {depth:.3f} m)"


# -- a tray footprint anywhere: the support under it ---------------------------------------------
def moved(tray: Tray, x: float, y: float, yaw: float, z: float = 0.0) -> Tray:
    """``tray`` standing at ``(x, y, z)`` [m] turned to ``yaw`` [rad] (tilt and parts kept)."""
    return tray.model_copy(update={"pose": Pose(x=x, y=y, z=z, yaw=yaw)})


def place_tray(
    scene: Scene,
    tray: Tray | str,
    x: float,
    y: float,
    yaw: float,
    z_hint: float | None = None,
) -> Placement:
    """The support under ``tray`` with its footprint at ``(x, y)`` [m] turned to ``yaw``
    [rad], the pose height [m] that rests it there and whether it stands free.

    tray: a tray of ``scene`` (moved: its own old place does not count) or a tray not in it
    (a copy: every tray of the scene counts). Of the faces that can carry the footprint, a
    free one first, then the one nearest ``z_hint`` (the tray's pose height now: a tray
    dragged along a shelf stays on that shelf), else the highest.
    """
    t = scene.tray(tray) if isinstance(tray, str) else tray
    return _Placer.of(scene, t.id).place(t, x, y, yaw, z_hint)


@dataclass(frozen=True)
class _Placer:
    """The faces and solids of a scene once, for many placements of one tray."""

    faces: list[Surface]
    others: list[Solid2]
    tree: shapely.STRtree
    floor: Polygon

    @classmethod
    def of(cls, scene: Scene, tray_id: str) -> _Placer:
        faces = surfaces(scene)
        others = solids(scene, exclude=tray_id)
        tree = shapely.STRtree([o.outline for o in others])
        return cls(faces, others, tree, faces[0].outline)

    def place(self, tray: Tray, x: float, y: float, yaw: float, z_hint: float | None) -> Placement:
        flat = moved(tray, x, y, yaw)
        outline = tray_footprint(flat)
        z0, _ = tray_z_range(flat)  # the bottom below the pose, as turned and tilted
        options = []
        for group in _same_height(self.faces, outline):
            at = moved(tray, x, y, yaw, group[0].top - z0)
            past = overhang(outline, [s.outline for s in group])
            why = (
                f"tray {tray.id!r} would overhang the edge of {group[0].name} by {past:.3f} m "
                f"(at most {SUPPORT_OVERHANG} m)"
                if past > SUPPORT_OVERHANG
                else self.blocked(at, outline)
            )
            options.append((group[0], at, why))
        if not options:
            why = f"tray {tray.id!r} would stand on nothing at ({x:.3f}, {y:.3f})"
            return Placement(tray.id, x, y, yaw, None, None, False, why)

        def rank(o: tuple[Surface, Tray, str | None]) -> tuple[bool, float]:
            near = -o[1].pose.z if z_hint is None else abs(o[1].pose.z - z_hint)
            return (o[2] is not None, near)

        face, at, why = min(options, key=rank)
        return Placement(tray.id, x, y, yaw, at.pose.z, face.id, why is None, why, face.top)

    def blocked(self, tray: Tray, outline: BaseGeometry) -> str | None:
        """Why ``tray`` (placed) does not stand free: off the floor, or meeting a solid."""
        if not self.floor.buffer(TOUCH).contains(outline):
            return f"tray {tray.id!r} would not be inside the floor"
        for k in self.tree.query(outline).tolist():
            why = intersection_problem(tray, self.others[k])
            if why is not None:
                return why.replace("intersects", "would intersect", 1)
        return None


def _same_height(faces: list[Surface], outline: BaseGeometry) -> list[list[Surface]]:
    """The faces under ``outline`` grouped by height (exact faces of one height together; a
    mesh's bounding box on its own, at its top), the highest first."""
    under = [s for s in faces if s.outline.intersects(outline)]
    under = [s for s in under if s.outline.intersection(outline).area > TOUCH]
    groups: list[list[Surface]] = []
    for s in sorted(under, key=lambda s: -s.top):
        if groups and abs(groups[-1][0].top - s.top) <= SAME_HEIGHT and s.low == s.top:
            groups[-1].append(s)
        else:
            groups.append([s])
    return groups


def free_spot(
    scene: Scene,
    tray: Tray,
    support: str | None = None,
    near: tuple[float, float] | None = None,
    step: float = 0.025,
) -> Placement | None:
    """The free placement of ``tray`` (a tray not in ``scene``, e.g. a copy with a new id; its
    yaw kept) on ``support`` (default: the one it stands on in its pose) nearest ``near``
    (default: its pose) on a grid of ``step`` [m], or None if the support has no free spot."""
    placer = _Placer.of(scene, tray.id)
    z0, _ = tray_z_range(moved(tray, 0.0, 0.0, tray.pose.yaw))
    if support is None:  # the face under it whose resting height is nearest its own
        under = _same_height(placer.faces, tray_footprint(tray))
        if not under:
            return None
        support = min(under, key=lambda g: abs(g[0].top - z0 - tray.pose.z))[0].id
    face = next((s for s in placer.faces if s.id == support), None)
    if face is None:
        return None
    cx, cy = near if near is not None else (tray.pose.x, tray.pose.y)
    for x, y in spots(face.outline, tray, step, (cx, cy)):
        at = moved(tray, x, y, tray.pose.yaw, face.top - z0)
        if placer.blocked(at, tray_footprint(at)) is None:
            return Placement(tray.id, x, y, tray.pose.yaw, at.pose.z, face.id, True, top=face.top)
    return None


def spots(
    outline: Polygon, tray: Tray, step: float, near: tuple[float, float] | None = None
) -> list[tuple[float, float]]:
    """Centres [m] on a grid of ``step`` over ``outline`` where ``tray`` (its yaw and tilt
    kept) lies on it within :data:`SUPPORT_OVERHANG`, nearest ``near`` first (if given)."""
    at0 = tray_footprint(moved(tray, 0.0, 0.0, tray.pose.yaw))
    corners = np.asarray(at0.exterior.coords)[:-1]
    x0, y0, x1, y1 = outline.bounds
    xs = np.arange(x0 + step / 2, x1, step)
    ys = np.arange(y0 + step / 2, y1, step)
    if near is not None:  # the grid through ``near``, so the tray's own place is a spot
        xs = near[0] + step * np.arange(math.floor((x0 - near[0]) / step), (x1 - near[0]) / step)
        ys = near[1] + step * np.arange(math.floor((y0 - near[1]) / step), (y1 - near[1]) / step)
    gx, gy = (a.ravel() for a in np.meshgrid(xs, ys))
    grown = outline.buffer(SUPPORT_OVERHANG)
    shapely.prepare(grown)
    ok = np.ones(len(gx), bool)
    for cx, cy in corners:  # a convex face holds the outline where it holds its corners
        ok &= shapely.contains_xy(grown, gx + cx, gy + cy)
    pts = np.stack([gx[ok], gy[ok]], 1)
    if near is not None:
        pts = pts[np.argsort(np.hypot(*(pts - near).T), kind="stable")]
    return [(float(x), float(y)) for x, y in pts]


def tray_copy(scene: Scene, tray_id: str, step: float = 0.025) -> Tray | None:
    """A copy of the tray ``tray_id`` of ``scene`` on the nearest free spot of the support
    it stands on (None if there is none): new ids for it and its parts (``<id>_2``, ``_3``,
    ... the first unused), the same yaw, tilt and parts."""
    taken = {t.id for t in scene.trays} | {p.id for t in scene.trays for p in t.parts}
    original = scene.tray(tray_id)
    n = 2
    while f"{tray_id}_{n}" in taken or any(f"{p.id}_{n}" in taken for p in original.parts):
        n += 1
    parts = [p.model_copy(update={"id": f"{p.id}_{n}"}) for p in original.parts]
    copy = original.model_copy(update={"id": f"{tray_id}_{n}", "parts": parts})
    spot = free_spot(scene, copy, step=step)
    return None if spot is None else moved(copy, spot.x, spot.y, spot.yaw, spot.z or 0.0)


# -- every place a tray can stand ------------------------------------------------------------------
@dataclass(frozen=True)
class StandArea:
    """Where the centre of a tray (its yaw and tilt as they are) may go on one face: it lies on
    the face (within the overhang), inside the floor, clear of every other tray and solid.
    ``z`` [m]: the pose height that rests it there."""

    support: str
    top: float
    z: float
    area: BaseGeometry


def stand_areas(scene: Scene, tray: Tray, floor: bool = False) -> list[StandArea]:
    """The areas of every face of ``scene`` where ``tray`` (of the scene, or a copy) may
    stand, its own old place aside; the floor only if it stands on the floor now or
    ``floor``."""
    at0 = tray_footprint(moved(tray, 0.0, 0.0, tray.pose.yaw))
    corners = np.asarray(at0.exterior.coords)[:-1]
    z0, z1 = tray_z_range(moved(tray, 0.0, 0.0, tray.pose.yaw))
    placer = _Placer.of(scene, tray.id)
    here = placer.place(tray, tray.pose.x, tray.pose.y, tray.pose.yaw, tray.pose.z)
    inside = _within(placer.floor.buffer(TOUCH), corners)
    out = []
    for face in placer.faces:
        if face.id == FLOOR and not (floor or here.support == FLOOR):
            continue
        grown = face.outline.buffer(SUPPORT_OVERHANG)
        area = _within(grown, corners).intersection(inside)
        lo, hi = face.top, face.top + z1 - z0
        for other in placer.others:
            if min(hi, other.z1) - max(lo, other.z0) > TOUCH and not area.is_empty:
                area = area.difference(_minkowski(other.outline, -corners))
        if not area.is_empty:
            out.append(StandArea(face.id, face.top, face.top - z0, area))
    return out


def _within(outline: BaseGeometry, corners: np.ndarray) -> BaseGeometry:
    """The centres at which every corner (offsets ``corners: (K, 2)`` [m]) of a convex outline
    lies in ``outline`` (convex: then the outline lies in it)."""
    area = outline
    for cx, cy in corners:
        area = area.intersection(shapely.affinity.translate(outline, -cx, -cy))
    return area


def _minkowski(outline: BaseGeometry, offsets: np.ndarray) -> BaseGeometry:
    """The convex hull of ``outline`` swept by ``offsets: (K, 2)`` [m]: the centres at which a
    convex outline with corners ``-offsets`` meets it."""
    pts = np.asarray(outline.convex_hull.exterior.coords)[:-1]  # type: ignore[attr-defined]
    swept = (pts[:, None, :] + offsets[None, :, :]).reshape(-1, 2)
    return shapely.MultiPoint(swept).convex_hull

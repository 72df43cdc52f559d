"""Geometric validation of a scene: every problem with its field path."""

from __future__ import annotations

import hashlib
import threading
from collections import Counter, OrderedDict

import numpy as np
import shapely
from shapely.geometry import Point, Polygon
from shapely.geometry.base import BaseGeometry

from pickstop.frames import R_z, rot2
from pickstop.scene.model import Box, Cylinder, Mesh, Obstacle, Pose, Scene, Tray

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
    if tray.tilt is None:
        return rect(tray.pose.x, tray.pose.y, tray.pose.yaw, *tray.outer_size)
    hull = shapely.MultiPoint([(x, y) for x, y, _ in tray_corners(tray)]).convex_hull
    assert isinstance(hull, Polygon)
    return hull


def tray_z_range(tray: Tray) -> tuple[float, float]:
    zs = [z for _, _, z in tray_corners(tray)]
    return (min(zs), max(zs))


def _overlap(a: BaseGeometry, b: BaseGeometry) -> bool:
    return bool(a.intersects(b)) and a.intersection(b).area > TOUCH


def _dups(ids: list[str]) -> list[str]:
    return sorted(k for k, v in Counter(ids).items() if v > 1)


def _obstacle_z(ob: Obstacle) -> tuple[float, float] | None:
    h = height(ob.geometry)
    return None if h is None else (ob.pose.z, ob.pose.z + h)


#: The fields :func:`check_scene` reads: a change of sigma, the error model, the motion or
#: the names checks nothing anew.
CHECKED_FIELDS = frozenset(("floor", "trays", "obstacles", "task", "base_grid", "start", "goal"))


class CheckedScenes:
    """:func:`check_scene`, remembered for the last ``size`` geometries (a pure function of
    :data:`CHECKED_FIELDS`): a service checks the same layout for every sigma step."""

    def __init__(self, size: int = 64) -> None:
        self.size = size
        self._checked: OrderedDict[str, tuple[tuple[str, str], ...]] = OrderedDict()
        self._lock = threading.Lock()

    def __call__(self, scene: Scene) -> list[tuple[str, str]]:
        key = hashlib.sha256(
            scene.model_dump_json(include=set(CHECKED_FIELDS)).encode()
        ).hexdigest()
        with self._lock:
            hit = self._checked.get(key)
            if hit is not None:
                self._checked.move_to_end(key)
                return list(hit)
        problems = check_scene(scene)
        with self._lock:
            self._checked[key] = tuple(problems)
            while len(self._checked) > self.size:
                self._checked.popitem(last=False)
        return problems


def check_scene(scene: Scene) -> list[tuple[str, str]]:
    """The geometry's problems as (field, message): duplicate ids, trays off the floor or
    inside obstacles and each other, parts outside their tray, start or goal off the floor."""
    problems: list[tuple[str, str]] = []
    floor = shapely.box(
        scene.floor.min[0], scene.floor.min[1], scene.floor.max[0], scene.floor.max[1]
    )

    for d in _dups([t.id for t in scene.trays]):
        problems.append(("trays", f"duplicate tray id {d!r}"))
    for d in _dups([o.id for o in scene.obstacles]):
        problems.append(("obstacles", f"duplicate obstacle id {d!r}"))
    for d in _dups([p.id for t in scene.trays for p in t.parts]):
        problems.append(("trays", f"duplicate part id {d!r} (part ids are unique in a scene)"))
    tray_ids = {t.id for t in scene.trays}
    if scene.task is not None:
        if not scene.task:
            problems.append(("task", "the task needs at least one tray"))
        for i, tid in enumerate(scene.task):
            if tid not in tray_ids:
                problems.append((f"task.{i}", f"unknown tray {tid!r}"))
        for d in _dups(list(scene.task)):
            problems.append(("task", f"tray {d!r} listed twice"))
    ext = scene.grid_extent
    if scene.base_grid.extent is not None:
        nx = (ext.max[0] - ext.min[0]) / scene.base_grid.resolution
        ny = (ext.max[1] - ext.min[1]) / scene.base_grid.resolution
        if nx * ny > 4_000_000:
            problems.append(("base_grid", f"grid of {nx:.0f} x {ny:.0f} cells is over 4 million"))

    for i, tray in enumerate(scene.trays):
        where = f"trays.{i}"
        fp = tray_footprint(tray)
        if not floor.contains(fp):
            problems.append((f"{where}.pose", f"tray {tray.id!r} is not inside the floor"))
        # Parts are checked in the tray's own frame (the same whether or not it is tilted).
        inner = rect(0.0, 0.0, 0.0, *tray.inner_size)
        part_fps: list[tuple[int, BaseGeometry]] = []
        for k, part in enumerate(tray.parts):
            pfp = footprint(part.geometry, part.pose)
            if pfp is None:
                continue
            if not inner.buffer(TOUCH).contains(pfp):
                problems.append(
                    (f"{where}.parts.{k}.pose", f"part {part.id!r} is outside tray {tray.id!r}")
                )
            if part.pose.z < -TOUCH:
                problems.append(
                    (f"{where}.parts.{k}.pose.z", "a part cannot sink below its tray floor")
                )
            for j, other in part_fps:
                if _overlap(pfp, other):
                    problems.append(
                        (
                            f"{where}.parts.{k}",
                            f"part {part.id!r} overlaps part {tray.parts[j].id!r}",
                        )
                    )
            part_fps.append((k, pfp))
        z0, z1 = tray_z_range(tray)
        for ob in scene.obstacles:
            ofp = footprint(ob.geometry, ob.pose)
            oz = _obstacle_z(ob)
            if ofp is None or oz is None:
                continue
            if _overlap(fp, ofp) and min(z1, oz[1]) - max(z0, oz[0]) > TOUCH:
                problems.append((where, f"tray {tray.id!r} intersects obstacle {ob.id!r}"))
        for other in scene.trays[:i]:
            oz0, oz1 = tray_z_range(other)
            if _overlap(fp, tray_footprint(other)) and min(z1, oz1) - max(z0, oz0) > TOUCH:
                problems.append((where, f"tray {tray.id!r} intersects tray {other.id!r}"))
    for name in ("start", "goal"):
        bp = getattr(scene, name)
        if not floor.contains(Point(bp.x, bp.y)):
            problems.append((name, f"{name} ({bp.x}, {bp.y}) is not on the floor"))
    return problems

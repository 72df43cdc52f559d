"""Geometric validation of a scene: every problem with its field path."""

from __future__ import annotations

import hashlib
from collections import Counter

import shapely
from shapely.geometry import Point
from shapely.geometry.base import BaseGeometry

from pickstop.caching import Cache
from pickstop.scene.model import Scene, Tray
from pickstop.scene.orders import order_problems
from pickstop.scene.outline import (  # noqa: F401  (re-exported: the checks' geometry)
    TOUCH,
    footprint,
    height,
    overlap_depth,
    overlaps,
    rect,
    tray_corners,
    tray_footprint,
    tray_z_range,
)
from pickstop.scene.supports import (
    Solid2,
    Surface,
    intersection_problem,
    resting_problem,
    solids,
    surfaces,
)


def _dups(ids: list[str]) -> list[str]:
    return sorted(k for k, v in Counter(ids).items() if v > 1)


#: The fields :func:`check_scene` reads: a change of sigma, the error model, the motion or
#: the names checks nothing anew.
CHECKED_FIELDS = frozenset(
    ("floor", "trays", "obstacles", "task", "base_grid", "start", "goal", "orders", "zones")
)


class CheckedScenes:
    """:func:`check_scene`, remembered for the last ``size`` geometries (a pure function of
    :data:`CHECKED_FIELDS`): a service checks the same layout for every sigma step."""

    def __init__(self, size: int = 64) -> None:
        self._checked: Cache[str, tuple[tuple[str, str], ...]] = Cache(
            "checked_scenes", max_items=size
        )

    def __call__(self, scene: Scene) -> list[tuple[str, str]]:
        key = hashlib.sha256(
            scene.model_dump_json(include=set(CHECKED_FIELDS)).encode()
        ).hexdigest()
        return list(self._checked.get_or_make(key, lambda: tuple(check_scene(scene))))


def check_scene(scene: Scene) -> list[tuple[str, str]]:
    """The geometry's problems as (field, message): duplicate ids, trays off the floor,
    inside obstacles and each other (by how much), standing on nothing
    (:mod:`pickstop.scene.supports`), parts outside their tray, start or goal off the floor."""
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

    faces = surfaces(scene)
    others = solids(scene)
    n_obstacles = sum(o.kind == "obstacle" for o in others)
    for i, tray in enumerate(scene.trays):
        # each pair of trays once: the obstacles, then the trays before this one
        problems += _tray_problems(floor, faces, others[: n_obstacles + i], i, tray)
    problems += order_problems(scene, scene.orders or [])
    problems += _zone_problems(scene)
    for name in ("start", "goal"):
        bp = getattr(scene, name)
        if not floor.contains(Point(bp.x, bp.y)):
            problems.append((name, f"{name} ({bp.x}, {bp.y}) is not on the floor"))
    return problems


def _tray_problems(
    floor: BaseGeometry, faces: list[Surface], others: list[Solid2], i: int, tray: Tray
) -> list[tuple[str, str]]:
    """The problems of ``scene.trays[i]``: off the floor, its parts, what it meets (of
    ``others``) and, if none of that, what it stands on."""
    where = f"trays.{i}"
    out = _part_problems(where, tray)
    if not floor.contains(tray_footprint(tray)):
        return [(f"{where}.pose", f"tray {tray.id!r} is not inside the floor"), *out]
    hits = [why for o in others if (why := intersection_problem(tray, o)) is not None]
    out += [(where, why) for why in hits]
    if not hits and (why := resting_problem(faces, tray)) is not None:
        out.append((f"{where}.pose", why))
    return out


def _part_problems(where: str, tray: Tray) -> list[tuple[str, str]]:
    """Parts outside their tray, sunk below its floor or overlapping each other (checked in
    the tray's own frame: the same whether or not it is tilted)."""
    out: list[tuple[str, str]] = []
    inner = rect(0.0, 0.0, 0.0, *tray.inner_size)
    part_fps: list[tuple[int, BaseGeometry]] = []
    for k, part in enumerate(tray.parts):
        pfp = footprint(part.geometry, part.pose)
        if pfp is None:
            continue
        if not inner.buffer(TOUCH).contains(pfp):
            out.append((f"{where}.parts.{k}.pose", f"part {part.id!r} is outside tray {tray.id!r}"))
        if part.pose.z < -TOUCH:
            out.append((f"{where}.parts.{k}.pose.z", "a part cannot sink below its tray floor"))
        for j, other in part_fps:
            if overlaps(pfp, other):
                msg = f"part {part.id!r} overlaps part {tray.parts[j].id!r}"
                out.append((f"{where}.parts.{k}", msg))
        part_fps.append((k, pfp))
    return out


def _zone_problems(scene: Scene) -> list[tuple[str, str]]:
    """Zones whose outline is no simple polygon of some area, or that admit unknown trays."""
    out: list[tuple[str, str]] = []
    trays = {t.id for t in scene.trays}
    for d in _dups([z.id for z in scene.zones or []]):
        out.append(("zones", f"duplicate zone id {d!r}"))
    for i, zone in enumerate(scene.zones or []):
        poly = shapely.Polygon(zone.outline)
        if not poly.is_valid or poly.area < 1e-6:
            out.append((f"zones.{i}.outline", f"zone {zone.id!r}: the outline must be a simple "
                        "polygon with an area (no edge crossing another)"))  # fmt: skip
        for j, t in enumerate(zone.trays or []):
            if t not in trays:
                out.append((f"zones.{i}.trays.{j}", f"zone {zone.id!r}: unknown tray {t!r}"))
    return out

"""Edits of the scene document the planner makes: pure functions of the document.

Each edit changes the plain JSON document in place (the planner holds it under its lock) and
raises :class:`EditError` when the edit would leave an invalid scene, the document unchanged.
"""

from __future__ import annotations

import copy
import math
from typing import Any

import shapely.affinity
from shapely.geometry import Polygon, box

from pickstop.scene import defaults

COPY_GAP = 0.05  # between a copied tray and any other tray [m]
COPY_TRIES = 4  # rings of places tried for a copy


class EditError(ValueError):
    """An edit the scene cannot take; the message says why, for the engineer."""


def snapped(value: float, ref: float, step: float) -> float:
    """``value`` moved to the nearest ``ref + k * step`` [m]: a tray dragged by whole base
    cells keeps its place on the base grid, so the regions reuse what was computed before."""
    return ref + round((value - ref) / step) * step


def grid_step(doc: dict[str, Any]) -> float:
    """The scene's base grid cell [m]: the snap that lets the regions be reused."""
    return float(doc.get("base_grid", {}).get("resolution", defaults.GRID_RESOLUTION))


def move(
    doc: dict[str, Any],
    kind: str,
    oid: str,
    x: float,
    y: float,
    yaw: float,
    snap: bool = True,
    step: float | None = None,
    yaw_step: float = 0.0,
) -> dict[str, Any] | None:
    """Set the pose of tray or obstacle ``oid`` (``kind``: "trays" or "obstacles") in ``doc``
    to ``(x, y)`` [m] and ``yaw`` [rad], its height kept. With ``snap``: the position moves
    by whole ``step`` [m] from where it stood (default: a tray by whole base cells, an
    obstacle freely; 0: freely) and the yaw to a multiple of ``yaw_step`` [rad] (0: freely).
    Returns the new pose (None if there is no such item)."""
    for item in doc.get(kind, []):
        if item["id"] == oid:
            pose = item.setdefault("pose", {})
            if snap:
                s = (grid_step(doc) if kind == "trays" else 0.0) if step is None else step
                if s > 0:
                    x = snapped(x, float(pose.get("x", 0.0)), s)
                    y = snapped(y, float(pose.get("y", 0.0)), s)
                if yaw_step > 0:
                    yaw = snapped(yaw, 0.0, yaw_step)
            pose["x"], pose["y"], pose["yaw"] = float(x), float(y), float(yaw)
            return dict(pose)
    return None


def place(
    doc: dict[str, Any], kind: str, oid: str, x: float, y: float, yaw: float, z: float
) -> dict[str, Any]:
    """Put item ``oid`` exactly at ``(x, y, z)`` [m] turned by ``yaw`` [rad] (typed numbers:
    no snap). Returns the new pose; EditError if there is no such item or a number is not
    finite."""
    for name, v in (("x", x), ("y", y), ("yaw", yaw), ("z", z)):
        if not math.isfinite(v):
            raise EditError(f"{name} must be a finite number, got {v}")
    pose = move(doc, kind, oid, x, y, yaw, snap=False)
    if pose is None:
        raise EditError(f"no {kind[:-1]} {oid!r} in the scene")
    item = next(i for i in doc[kind] if i["id"] == oid)
    item["pose"]["z"] = float(z)
    return dict(item["pose"])


def pose_of(doc: dict[str, Any], kind: str, oid: str) -> dict[str, Any] | None:
    """The pose of tray or obstacle ``oid`` (``kind``: "trays" or "obstacles"), None if none."""
    for item in doc.get(kind, []):
        if item["id"] == oid:
            return dict(item.get("pose", {}))
    return None


def display_name(doc: dict[str, Any], oid: str) -> str:
    """What the engineer calls tray or obstacle ``oid``: a tray's name, else its id."""
    for t in doc.get("trays", []):
        if t["id"] == oid:
            return str(t.get("name") or oid)
    return oid


def move_label(before: dict[str, Any], after: dict[str, Any], kind: str, oid: str) -> str:
    """The undo step of a drag of ``oid`` from document ``before`` to ``after``: "move",
    "turn" or "move and turn" with the item's name."""
    p0, p1 = pose_of(before, kind, oid) or {}, pose_of(after, kind, oid) or {}
    moved = any(p0.get(k, 0.0) != p1.get(k, 0.0) for k in ("x", "y", "z"))
    turned = p0.get("yaw", 0.0) != p1.get("yaw", 0.0)
    verb = "move and turn" if moved and turned else "turn" if turned else "move"
    return f"{verb} {display_name(after, oid)}"


def tray(doc: dict[str, Any], tid: str) -> dict[str, Any]:
    """The tray ``tid`` of ``doc`` (EditError if there is none)."""
    for t in doc["trays"]:
        if t["id"] == tid:
            return t
    raise EditError(f"no tray {tid!r} in the scene")


def task_of(doc: dict[str, Any]) -> list[str]:
    """The trays the task needs, in the document's order (all of them when it names none)."""
    task = doc.get("task")
    return [t["id"] for t in doc["trays"] if task is None or t["id"] in task]


def set_needed(doc: dict[str, Any], tid: str, needed: bool) -> None:
    """Add tray ``tid`` to the task or take it out; the task keeps the trays' order."""
    tray(doc, tid)
    keep = set(task_of(doc)) - {tid} | ({tid} if needed else set())
    doc["task"] = [t["id"] for t in doc["trays"] if t["id"] in keep]


def rename_tray(doc: dict[str, Any], tid: str, name: str) -> None:
    tray(doc, tid)["name"] = name


def _footprint(t: dict[str, Any], dx: float = 0.0, dy: float = 0.0) -> Polygon:
    """The tray's outer rectangle on the floor [m], moved by ``(dx, dy)``."""
    wall = float(t.get("wall_thickness", defaults.TRAY_WALL_THICKNESS))
    ox, oy = (float(v) + 2 * wall for v in t["inner_size"])
    p = t["pose"]
    rect = shapely.affinity.rotate(box(-ox / 2, -oy / 2, ox / 2, oy / 2), float(p.get("yaw", 0.0)),
                                   origin=(0, 0), use_radians=True)  # fmt: skip
    return shapely.affinity.translate(
        rect, float(p.get("x", 0.0)) + dx, float(p.get("y", 0.0)) + dy
    )


def free_offset(doc: dict[str, Any], t: dict[str, Any]) -> tuple[float, float]:
    """Where a copy of tray ``t`` fits beside it: the first of +x, -x, +y, -y, then twice as
    far, ... (steps of its outer size and ``COPY_GAP``) whose footprint keeps ``COPY_GAP``
    from every tray's; +x when none does within ``COPY_TRIES`` rings (the API then names the
    collision). Footprints are the outer rectangles on the floor: a first guess, the API's
    scene check is the truth."""
    fp = _footprint(t)
    (x0, y0, x1, y1), others = fp.bounds, [_footprint(o) for o in doc["trays"]]
    sx, sy = x1 - x0 + COPY_GAP, y1 - y0 + COPY_GAP
    for k in range(1, COPY_TRIES + 1):
        for dx, dy in ((k * sx, 0.0), (-k * sx, 0.0), (0.0, k * sy), (0.0, -k * sy)):
            moved = _footprint(t, dx, dy).buffer(COPY_GAP)
            if not any(moved.intersects(o) for o in others):
                return dx, dy
    return sx, 0.0


def copy_tray(
    doc: dict[str, Any], tid: str, name: str = "", placed: dict[str, Any] | None = None
) -> str:
    """Add a copy of tray ``tid`` (parts included, their ids made unique as ``<part>_<k>``)
    under the first free id ``<tid>_<k>`` (k >= 2) and named ``"<name or tid> <k>"``; a task
    that lists its trays lists the copy too. Where: ``placed``, the copy the API put on a free
    spot of the same support (its pose is taken), else beside the original where its footprint
    meets no other tray (:func:`free_offset`, a first guess the scene check may refuse).
    Returns the copy's id."""
    new = copy.deepcopy(tray(doc, tid))
    ids = {t["id"] for t in doc["trays"]}
    k = 2
    while f"{tid}_{k}" in ids:
        k += 1
    new["id"], new["name"] = f"{tid}_{k}", f"{name or tid} {k}"
    part_ids = {p["id"] for t in doc["trays"] for p in t.get("parts", [])}
    for part in new.get("parts", []):
        j = k
        while f"{part['id']}_{j}" in part_ids:
            j += 1
        part["id"] = f"{part['id']}_{j}"
        part_ids.add(part["id"])
    if placed is not None:
        new["pose"] = dict(placed["pose"])
    else:
        dx, dy = free_offset(doc, new)
        new["pose"]["x"] = float(new["pose"].get("x", 0.0)) + dx
        new["pose"]["y"] = float(new["pose"].get("y", 0.0)) + dy
    doc["trays"].append(new)
    if doc.get("task") is not None:
        doc["task"].append(new["id"])
    return str(new["id"])


def remove_tray(doc: dict[str, Any], tid: str) -> None:
    """Remove tray ``tid`` (and take it out of the task); a scene keeps at least one tray."""
    tray(doc, tid)
    if len(doc["trays"]) == 1:
        raise EditError("A scene needs at least one tray.")
    doc["trays"] = [t for t in doc["trays"] if t["id"] != tid]
    if doc.get("task") is not None:
        doc["task"] = [t for t in doc["task"] if t != tid]

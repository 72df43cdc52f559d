"""Edits of the scene document the planner makes: pure functions of the document."""

from __future__ import annotations

from typing import Any


def snapped(value: float, ref: float, step: float) -> float:
    """``value`` moved to the nearest ``ref + k * step`` [m]: a tray dragged by whole base
    cells keeps its place on the base grid, so the regions reuse what was computed before."""
    return ref + round((value - ref) / step) * step


def move(
    doc: dict[str, Any], kind: str, oid: str, x: float, y: float, yaw: float, snap: bool = True
) -> dict[str, Any] | None:
    """Set the pose of tray or obstacle ``oid`` (``kind``: "trays" or "obstacles") in ``doc``
    to ``(x, y)`` [m] and ``yaw`` [rad], its height kept; a tray's position snapped to whole
    base cells from where it stood. Returns the new pose (None if there is no such item)."""
    res = float(doc.get("base_grid", {}).get("resolution", 0.025))
    for item in doc.get(kind, []):
        if item["id"] == oid:
            pose = item.setdefault("pose", {})
            if snap and kind == "trays":
                x = snapped(x, float(pose.get("x", 0.0)), res)
                y = snapped(y, float(pose.get("y", 0.0)), res)
            pose["x"], pose["y"], pose["yaw"] = float(x), float(y), float(yaw)
            return dict(pose)
    return None

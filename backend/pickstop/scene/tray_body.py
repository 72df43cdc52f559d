"""A tray's body, its floor and four walls, as boxes in the tray's own frame.

One home for the tray's shape: the collision world (:func:`pickstop.scene.world.tray_body_solids`)
checks these boxes and the planner UI draws them. The tray frame is the inner floor's centre,
x along ``inner_size[0]``, z along the floor's normal. Pure arithmetic, no pydantic or coal.
"""

from __future__ import annotations

from dataclasses import dataclass

from pickstop.scene.defaults import TRAY_FLOOR_THICKNESS, TRAY_WALL_HEIGHT, TRAY_WALL_THICKNESS

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class BodyBox:
    """One box of a tray's body: ``size`` full extents and ``centre`` in the tray frame [m]."""

    name: str  # "floor", "wall0" .. "wall3"
    size: Vec3
    centre: Vec3


def tray_body_boxes(
    inner_size: tuple[float, float],
    wall_thickness: float = TRAY_WALL_THICKNESS,
    wall_height: float = TRAY_WALL_HEIGHT,
    floor_thickness: float = TRAY_FLOOR_THICKNESS,
) -> list[BodyBox]:
    """The floor (left out when ``floor_thickness`` is 0) and the walls at +x, -x, +y, -y.

    inner_size: the inner floor's extents along x and y [m]. The walls stand on the floor's
    underside and rise ``wall_height`` above the inner floor; the x walls span the outer
    width, the y walls fit between them.
    """
    ix, iy = float(inner_size[0]), float(inner_size[1])
    t, h, f = float(wall_thickness), float(wall_height), float(floor_thickness)
    ox, oy = ix + 2 * t, iy + 2 * t
    out = []
    if f > 0:
        out.append(BodyBox("floor", (ox, oy, f), (0.0, 0.0, -f / 2)))
    zc, hz = (h - f) / 2, h + f
    walls = (
        ((ix + t) / 2, 0.0, t, oy),
        (-(ix + t) / 2, 0.0, t, oy),
        (0.0, (iy + t) / 2, ix, t),
        (0.0, -(iy + t) / 2, ix, t),
    )
    for k, (dx, dy, sx, sy) in enumerate(walls):
        out.append(BodyBox(f"wall{k}", (sx, sy, hz), (dx, dy, zc)))
    return out

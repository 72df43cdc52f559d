"""What a scene looks like: a pure function from a scene document to the shapes drawn.

:func:`scene_drawing` reads the plain JSON document (as the API stores it) with the format's
own defaults (:mod:`pickstop.scene.defaults`) and the tray body's one geometry
(:mod:`pickstop.scene.tray_body`), so every box is drawn where the backend checks it. The
planner puts the result into viser nodes; nothing here touches a browser.

Frames: a tray or obstacle hangs below a movable root (its gizmo) at its pose (x, y, z, yaw);
a tray's body is turned by its tilt below that root; each shape's ``position`` is its centre
in its parent frame [m], ``wxyz`` its rotation.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

from pickstop.frames import Quat, axis_quat, yaw_quat
from pickstop.scene import defaults
from pickstop.scene.tray_body import tray_body_boxes

RGB = tuple[int, int, int]
Vec3 = tuple[float, float, float]
IDENTITY: Quat = (1.0, 0.0, 0.0, 0.0)

PALETTE: list[RGB] = list(defaults.TRAY_PALETTE)
OBSTACLE: RGB = (120, 110, 100)
PART: RGB = (200, 200, 210)
START: RGB = (30, 30, 30)
GOAL: RGB = (250, 250, 250)
MARKER_RADIUS = 0.08  # start and goal spheres [m]
LABEL_ABOVE_WALLS = 0.09  # a tray's name floats this far above its walls [m]


@dataclass(frozen=True)
class Shape:
    """A box (``dims`` = full extents x, y, z) or an upright cylinder (``dims`` = radius,
    height) centred at ``position`` [m] in its parent frame."""

    name: str  # the node's path below the item's root, e.g. "body/wall0"
    kind: Literal["box", "cylinder"]
    dims: tuple[float, ...]
    position: Vec3
    wxyz: Quat
    colour: RGB


@dataclass(frozen=True)
class Item:
    """A tray or an obstacle: a movable root at its pose and the shapes below it."""

    kind: Literal["trays", "obstacles"]
    id: str
    position: Vec3  # the pose's (x, y, z) [m]
    wxyz: Quat  # the pose's yaw
    body_wxyz: Quat | None  # a tray's tilt below the root (frame "body"); None: no frame
    shapes: list[Shape]
    label: tuple[str, Vec3] | None = None  # text and its position in the root frame


@dataclass(frozen=True)
class Marker:
    """The start or the goal of the route: a sphere with its name."""

    name: str
    position: Vec3
    colour: RGB


@dataclass(frozen=True)
class SceneDrawing:
    floor_size: tuple[float, float]  # extents along x, y [m]
    floor_centre: Vec3
    items: list[Item]
    markers: list[Marker]
    robot_pose: tuple[float, float, float]  # (x, y, yaw) where the robot starts [m, rad]
    colours: dict[str, RGB]  # each tray's colour, also its region's in a plan
    undrawn: list[str] = field(default_factory=list)  # shapes the planner cannot draw (meshes)


def tray_colour(index: int, tray: Mapping[str, Any]) -> RGB:
    """The tray's ``color`` ("#rrggbb"), else the palette's ``index``-th colour."""
    c = tray.get("color")
    if isinstance(c, str) and c.startswith("#") and len(c) == 7:
        return (int(c[1:3], 16), int(c[3:5], 16), int(c[5:7], 16))
    return PALETTE[index % len(PALETTE)]


def tray_colours(doc: Mapping[str, Any]) -> dict[str, RGB]:
    return {t["id"]: tray_colour(i, t) for i, t in enumerate(doc["trays"])}


def tilt_quat(tilt: Mapping[str, Any] | None) -> Quat:
    """wxyz of a tray's tilt about its own x or y axis (identity without one)."""
    if not tilt:
        return IDENTITY
    return axis_quat("x" if tilt["axis"] == "x" else "y", float(tilt["angle"]))


def _pose(p: Mapping[str, Any]) -> tuple[Vec3, Quat]:
    """A document pose (a coordinate left out is 0) as position and yaw quaternion."""
    xyz = (float(p.get("x", 0.0)), float(p.get("y", 0.0)), float(p.get("z", 0.0)))
    return xyz, yaw_quat(float(p.get("yaw", 0.0)))


def _shape(name: str, g: Mapping[str, Any], bottom: Mapping[str, Any], colour: RGB) -> Shape | None:
    """The shape of a box or cylinder whose frame is its bottom centre ``bottom`` (a pose);
    None for a mesh (its file lives beside the scene on the server)."""
    (x, y, z), q = _pose(bottom)
    if g["shape"] == "box":
        sx, sy, sz = (float(v) for v in g["size"])
        return Shape(name, "box", (sx, sy, sz), (x, y, z + sz / 2), q, colour)
    if g["shape"] == "cylinder":
        r, h = float(g["radius"]), float(g["height"])
        return Shape(name, "cylinder", (r, h), (x, y, z + h / 2), q, colour)
    return None


def tray_item(index: int, tray: Mapping[str, Any], undrawn: list[str] | None = None) -> Item:
    """Tray ``index`` of the document: its body boxes and parts below its tilt, its label."""
    colour = tray_colour(index, tray)
    wall_height = float(tray.get("wall_height", defaults.TRAY_WALL_HEIGHT))
    boxes = tray_body_boxes(
        tuple(tray["inner_size"]),
        float(tray.get("wall_thickness", defaults.TRAY_WALL_THICKNESS)),
        wall_height,
        float(tray.get("floor_thickness", defaults.TRAY_FLOOR_THICKNESS)),
    )
    shapes = [Shape(f"body/{b.name}", "box", b.size, b.centre, IDENTITY, colour) for b in boxes]
    for part in tray.get("parts", []):
        s = _shape(f"body/parts/{part['id']}", part["geometry"], part.get("pose", {}), PART)
        if s is not None:
            shapes.append(s)
        elif undrawn is not None:
            undrawn.append(f"part {part['id']} of tray {tray['id']}")
    position, wxyz = _pose(tray["pose"])
    label = (tray.get("name") or tray["id"], (0.0, 0.0, wall_height + LABEL_ABOVE_WALLS))
    return Item("trays", tray["id"], position, wxyz, tilt_quat(tray.get("tilt")), shapes, label)


def obstacle_item(ob: Mapping[str, Any], undrawn: list[str] | None = None) -> Item:
    position, wxyz = _pose(ob["pose"])
    s = _shape("body", ob["geometry"], {}, OBSTACLE)
    if s is None and undrawn is not None:
        undrawn.append(f"obstacle {ob['id']}")
    return Item("obstacles", ob["id"], position, wxyz, None, [s] if s else [])


def scene_drawing(doc: Mapping[str, Any]) -> SceneDrawing:
    """Everything the scene puts on screen, from the scene document ``doc``."""
    (x0, y0), (x1, y1) = doc["floor"]["min"], doc["floor"]["max"]
    undrawn: list[str] = []
    items = [obstacle_item(ob, undrawn) for ob in doc.get("obstacles", [])]
    items += [tray_item(i, t, undrawn) for i, t in enumerate(doc["trays"])]
    markers = [
        Marker(name, (float(doc[name]["x"]), float(doc[name]["y"]), MARKER_RADIUS), colour)
        for name, colour in (("start", START), ("goal", GOAL))
    ]
    s = doc["start"]
    return SceneDrawing(
        floor_size=(x1 - x0, y1 - y0),
        floor_centre=((x0 + x1) / 2, (y0 + y1) / 2, 0.0),
        items=items,
        markers=markers,
        robot_pose=(float(s["x"]), float(s["y"]), float(s.get("yaw", 0.0))),
        colours=tray_colours(doc),
        undrawn=undrawn,
    )


def initial_sigma(doc: Mapping[str, Any]) -> float:
    """The sigma the scene asks for [m] (the format's default when it names none)."""
    return float(doc.get("sigma", defaults.SIGMA))

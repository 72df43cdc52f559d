"""The scene's nodes in the viser scene, kept equal to a scene document by small updates.

:meth:`SceneLayer.sync` compares the drawing of a document (:func:`scene_view.scene_drawing`)
with what is on screen and changes only what differs: a moved item's root gets its new pose,
a renamed tray's label its new text, an item whose shapes changed (or that came or went) is
drawn anew or removed. Nothing else is sent: with a software renderer a scene rebuilt from
scratch costs hundreds of milliseconds a frame, and an undo must not cost that.

Each tray or obstacle hangs below a root frame at its pose (``/trays/<id>``,
``/obstacles/<id>``); the gizmo that moves the selected one lives elsewhere
(:mod:`pickstop_ui.selection`). A tray that does not stand (:meth:`SceneLayer.mark`) is drawn
red and translucent, its label saying why, until it is marked standing again.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

import numpy as np
import viser

from pickstop.frames import yaw_quat
from pickstop_ui.declutter import quat_matrix
from pickstop_ui.resting import INVALID, INVALID_OPACITY
from pickstop_ui.scene_view import Item, Marker, SceneDrawing, scene_drawing

log = logging.getLogger("pickstop.ui")


@dataclass
class ItemNodes:
    """What is drawn of one item: its root, its label, its shapes' nodes and the item it was
    drawn from."""

    root: Any
    label: Any | None
    item: Item
    shapes: list[Any]


def _structure(item: Item) -> tuple[Any, ...]:
    """What cannot change in place: the shapes and the tilt (pose and label text can)."""
    return (item.kind, item.body_wxyz, tuple(item.shapes), item.label is None)


class SceneLayer:
    """Scene nodes of trays, obstacles, start and goal for one planner window."""

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self.items: dict[tuple[str, str], ItemNodes] = {}
        self.markers: dict[str, Any] = {}
        self.marker_labels: dict[str, tuple[Any, Any]] = {}  # name -> (marker, its label)
        self.invalid: dict[tuple[str, str], str] = {}  # items drawn as not standing -> why

    # -- whole scene ------------------------------------------------------------------------------
    def sync(self, doc: dict[str, Any]) -> SceneDrawing:
        """Make the scene's nodes show ``doc``; returns its drawing."""
        d = scene_drawing(doc)
        wanted = {(i.kind, i.id): i for i in d.items}
        with self.server.atomic():
            for key in list(self.items.keys() - wanted.keys()):
                self.items.pop(key).root.remove()
            for key, item in wanted.items():
                have = self.items.get(key)
                if have is not None and _structure(have.item) != _structure(item):
                    have.root.remove()
                    have = None
                if have is None:
                    self.items[key] = self._add(item)
                else:
                    self._update(have, item)
            for m in d.markers:
                self._marker(m)
        if d.undrawn:
            log.warning("not drawn (mesh shapes): %s", ", ".join(d.undrawn))
        return d

    def drawn_items(self) -> list[Item]:
        """The items as drawn now."""
        return [n.item for n in self.items.values()]

    def labels(self) -> list[tuple[str, Any, tuple[float, float, float]]]:
        """Every item's and marker's label: ``(key, handle, anchor)``, the anchor in the world
        [m] (the label's position turned and moved with its item's root)."""
        out = []
        for (kind, oid), nodes in self.items.items():
            if nodes.label is not None:
                R = quat_matrix(nodes.root.wxyz)
                p = np.asarray(nodes.root.position) + R @ np.asarray(nodes.label.position)
                out.append((f"{kind}/{oid}", nodes.label, tuple(map(float, p))))
        for name, (h, label) in self.marker_labels.items():
            p = np.asarray(h.position) + np.asarray(label.position)
            out.append((name, label, tuple(map(float, p))))
        return out

    def root(self, kind: str, oid: str) -> Any | None:
        nodes = self.items.get((kind, oid))
        return None if nodes is None else nodes.root

    def place(self, kind: str, oid: str, x: float, y: float, z: float, yaw: float) -> None:
        """Put item ``oid``'s root at ``(x, y, z)`` [m] turned by ``yaw`` [rad] at once (a
        drag under way: its document pose is set too, by the caller)."""
        nodes = self.items.get((kind, oid))
        if nodes is not None:
            nodes.root.position = np.array([x, y, z])
            nodes.root.wxyz = np.array(yaw_quat(yaw))

    def mark(self, kind: str, oid: str, why: str | None) -> None:
        """Draw item ``oid`` as not standing, for ``why`` (red, translucent, its label saying
        why), or (``why`` None) as it is."""
        key = (kind, oid)
        if self.invalid.get(key) == why:
            return
        if why is None:
            self.invalid.pop(key, None)
        else:
            self.invalid[key] = why
        nodes = self.items.get(key)
        if nodes is not None:
            with self.server.atomic():
                self._look(nodes)

    def _look(self, nodes: ItemNodes) -> None:
        """The shapes' colours and the label's text as the item's standing says."""
        item = nodes.item
        why = self.invalid.get((item.kind, item.id))
        for h, s in zip(nodes.shapes, item.shapes, strict=True):
            colour, opacity = (s.colour, None) if why is None else (INVALID, INVALID_OPACITY)
            if tuple(h.color) != colour:
                h.color = colour
            if h.opacity != opacity:
                h.opacity = opacity
        if nodes.label is not None and item.label is not None:
            text = item.label[0] if why is None else f"⚠ {item.label[0]}: {why}"
            if nodes.label.text != text:
                nodes.label.text = text

    # -- one item ---------------------------------------------------------------------------------
    def _add(self, item: Item) -> ItemNodes:
        sc, root_name = self.server.scene, f"/{item.kind}/{item.id}"
        root = sc.add_frame(root_name, show_axes=False, position=item.position, wxyz=item.wxyz)
        if item.body_wxyz is not None:
            sc.add_frame(f"{root_name}/body", show_axes=False, wxyz=item.body_wxyz)
        shapes: list[Any] = []
        for s in item.shapes:
            h: Any
            name = f"{root_name}/{s.name}"
            if s.kind == "box":
                h = sc.add_box(name, dimensions=s.dims, color=s.colour, position=s.position,
                               wxyz=s.wxyz)  # fmt: skip
            else:
                r, height = s.dims
                h = sc.add_cylinder(name, radius=r, height=height, color=s.colour,
                                    position=s.position, wxyz=s.wxyz)  # fmt: skip
            shapes.append(h)
        label = None
        if item.label is not None:
            label = sc.add_label(f"{root_name}/label", item.label[0], position=item.label[1],
                                 anchor="bottom-center")  # fmt: skip
        nodes = ItemNodes(root, label, item, shapes)
        if (item.kind, item.id) in self.invalid:
            self._look(nodes)
        return nodes

    def _update(self, nodes: ItemNodes, item: Item) -> None:
        old, root = nodes.item, nodes.root
        # The root's own pose, not the item last drawn: a drag moves the root meanwhile.
        if not (
            np.array_equal(root.position, item.position) and np.array_equal(root.wxyz, item.wxyz)
        ):
            root.position = np.asarray(item.position, float)
            root.wxyz = np.asarray(item.wxyz, float)
        if nodes.label is not None and item.label is not None and old.label != item.label:
            nodes.label.text = item.label[0]
            nodes.label.position = np.asarray(item.label[1], float)
        nodes.item = item
        self._look(nodes)

    def _marker(self, m: Marker) -> None:
        h = self.markers.get(m.name)
        if h is None:
            sc = self.server.scene
            h = self.markers[m.name] = sc.add_icosphere(
                f"/{m.name}", radius=m.position[2], color=m.colour, position=m.position
            )
            label = sc.add_label(f"/{m.name}/label", m.name, position=(0, 0, 0.2),
                                 anchor="bottom-center")  # fmt: skip
            self.marker_labels[m.name] = (h, label)
        elif tuple(h.position) != m.position:
            h.position = np.asarray(m.position, float)

"""Select, then edit: one gizmo, on the selected tray or obstacle only.

A click on an item selects it (:mod:`pickstop_ui.picking` finds which); a click on empty
floor, Esc or *Deselect* clears the selection. Only the selected item carries the gizmo, drawn
at a constant size on screen with large handles, so a gesture that starts over any other item
(a pan, an orbit) moves the camera and nothing else. The gizmo is a node of its own under
``/helpers`` (never in an export); while it is dragged, the item's root follows it (the
planner sets the root's pose from each update).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import viser

from pickstop.frames import quat_yaw, yaw_quat

GIZMO = "/helpers/gizmo"
GIZMO_PX = 150  # length of the gizmo's arrows on screen [px]
GIZMO_LINE = 5.0  # width of its lines [px]

Key = tuple[str, str]  # (kind, id): ("trays", "tray_4") or ("obstacles", "table_b")
#: Called with the item, the gizmo's (x, y, z) [m] and yaw [rad], and whether the drag ended.
DragSink = Callable[[Key, tuple[float, float, float], float, bool], None]


class Selection:
    """The selected item of one planner window and its gizmo."""

    def __init__(self, server: viser.ViserServer, on_drag: DragSink) -> None:
        self.key: Key | None = None
        self.on_drag = on_drag
        self.gizmo = server.scene.add_transform_controls(
            GIZMO, scale=GIZMO_PX, line_width=GIZMO_LINE, fixed=True,
            active_axes=(True, True, False), depth_test=False, visible=False,
        )  # fmt: skip
        self.gizmo.on_update(self._dragged)

    def select(self, key: Key, pose: dict[str, Any]) -> None:
        """Put the gizmo on item ``key`` standing at document pose ``pose``."""
        self.key = key
        self.place(pose)
        self.gizmo.visible = True

    def clear(self) -> None:
        self.key = None
        self.gizmo.visible = False

    def place(self, pose: dict[str, Any]) -> None:
        """Set the gizmo to ``pose`` (x, y, z [m], yaw [rad]); a pose set here moves no item:
        only a drag in the browser reports back."""
        self.gizmo.position = np.array(
            [float(pose.get("x", 0.0)), float(pose.get("y", 0.0)), float(pose.get("z", 0.0))]
        )
        self.gizmo.wxyz = np.array(yaw_quat(float(pose.get("yaw", 0.0))))

    async def _dragged(self, event: Any) -> None:
        """On the event loop, so the phases come in order (a thread pool may run an update
        after the end); the sink must be quick."""
        key = self.key
        if key is None or event.phase == "start":
            return
        p = self.gizmo.position
        pos = (float(p[0]), float(p[1]), float(p[2]))
        self.on_drag(key, pos, quat_yaw(self.gizmo.wxyz), event.phase == "end")

"""The measure tool: the distance between two picked points, drawn and told.

While the tool is on, a click in the 3D view picks a point (on an item's top or side where the
ray meets its box, else on the floor; :func:`pickstop_ui.picking.hit_point`); two points give
a line with its length. A third click starts a new measurement. Its nodes live under
``/helpers/measure`` (never in an export) and are made once, then moved.
"""

from __future__ import annotations

import math

import numpy as np
import viser

ROOT = "/helpers/measure"
COLOUR = (255, 0, 170)
Vec3 = tuple[float, float, float]


def distance_text(a: Vec3, b: Vec3) -> str:
    """The distance between ``a`` and ``b`` [m] with its components and the floor distance."""
    dx, dy, dz = (b[k] - a[k] for k in range(3))
    d, flat = math.dist(a, b), math.hypot(dx, dy)
    return (f"**Distance: {d:.3f} m** (on the floor {flat:.3f} m; Δx {dx:+.3f}, Δy {dy:+.3f}, "
            f"Δz {dz:+.3f} m) from ({a[0]:.3f}, {a[1]:.3f}, {a[2]:.3f}) to ({b[0]:.3f}, "
            f"{b[1]:.3f}, {b[2]:.3f})")  # fmt: skip


class MeasureTool:
    """Picked points and their drawing for one planner window."""

    def __init__(self, server: viser.ViserServer) -> None:
        sc = server.scene
        self.on = False
        self.points: list[Vec3] = []
        self._dots = [sc.add_icosphere(f"{ROOT}/p{k}", radius=0.025, color=COLOUR,
                                       visible=False) for k in range(2)]  # fmt: skip
        far = np.zeros((1, 2, 3), np.float32) - 10.0
        self._line = sc.add_line_segments(f"{ROOT}/line", far, colors=COLOUR, thickness=4.0,
                                          visible=False)  # fmt: skip
        self._label = sc.add_label(f"{ROOT}/label", "", visible=False, anchor="bottom-center")

    def add(self, p: Vec3) -> str:
        """Pick point ``p`` [m]; returns what the panel says."""
        if len(self.points) >= 2:
            self.points = []
        self.points.append(p)
        self._draw()
        if len(self.points) == 1:
            return f"First point ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m: click the second."
        return distance_text(self.points[0], self.points[1])

    def clear(self) -> None:
        self.points = []
        self._draw()

    def _draw(self) -> None:
        for k, dot in enumerate(self._dots):
            if k < len(self.points):
                dot.position = np.asarray(self.points[k])
            dot.visible = k < len(self.points)
        two = len(self.points) == 2
        if two:
            a, b = np.asarray(self.points[0]), np.asarray(self.points[1])
            self._line.points = np.array([[a, b]], np.float32)
            self._label.text = f"{np.linalg.norm(b - a):.3f} m"
            self._label.position = (a + b) / 2 + np.array([0.0, 0.0, 0.05])
        self._line.visible = self._label.visible = two

    def hide_all(self, hidden: bool) -> None:
        """Hide every node (an export), or show what the points call for again."""
        if hidden:
            for h in (*self._dots, self._line, self._label):
                h.visible = False
        else:
            self._draw()

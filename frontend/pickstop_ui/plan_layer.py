"""The plan's nodes in the viser scene, made once and then updated in place.

Every redraw sets the arrays and colours of the nodes already there (regions, outlines,
circles, centres, route, stop labels, ghost robots): with a software renderer, removing and
adding nodes costs hundreds of milliseconds a frame. The ghosts' meshes are sent once, when a
ghost is first needed; later plans only move them and set their joints.
"""

from __future__ import annotations

import threading
from typing import Any

import numpy as np
import viser

from pickstop.frames import yaw_quat
from pickstop_ui.plan_view import MAX_LABELS, PlanDrawing

_NOWHERE = np.zeros((1, 2, 3), np.float32) - 10.0  # a placeholder segment below the floor
#: The ghosts and the robot share one URDF whose joint values each pose sets, then reads.
_FK = threading.Lock()
#: The ghosts' colour (RGBA): the collision meshes, translucent.
GHOST_COLOUR = (0.55, 0.6, 0.95, 0.5)
#: The robot at the start: the same meshes, opaque and darker.
ROBOT_COLOUR = (0.35, 0.4, 0.75)


def robot_urdf(server: viser.ViserServer, urdf: Any, root: str, colour: tuple[float, ...]) -> Any:
    """The robot's collision meshes under ``root`` in ``colour`` (RGB, or RGBA translucent):
    far fewer triangles than the visual ones, so a browser without a GPU keeps up."""
    from viser.extras import ViserUrdf

    return ViserUrdf(server, urdf, root_node_name=root, load_meshes=False,
                     load_collision_meshes=True, collision_mesh_color_override=colour)  # fmt: skip


def pose(robot: Any, cfg: np.ndarray) -> None:
    """Set ``robot``'s (a ViserUrdf's) actuated joints to ``cfg`` (forward kinematics of
    every link; one pose at a time, the URDF being shared)."""
    with _FK:
        robot.update_cfg(cfg)


def _set(h: Any, **props: Any) -> None:
    """Assign only the properties that changed: each assignment is a message to every
    browser, and each message costs the page a render."""
    for name, value in props.items():
        old = getattr(h, name)
        if isinstance(value, np.ndarray) or isinstance(old, np.ndarray):
            old_a, new_a = np.asarray(old), np.asarray(value)
            if old_a.shape == new_a.shape and np.array_equal(old_a, new_a.astype(old_a.dtype)):
                continue
        elif old == value:
            continue
        setattr(h, name, value)


class PlanLayer:
    """Scene nodes under ``/plan`` and ``/ghosts`` for one planner window."""

    def __init__(self, server: viser.ViserServer, urdf: Any = None) -> None:
        self.server = server
        self.urdf = urdf
        self.show_ghosts = False  # they cover the circles: shown when asked for
        self._regions: dict[str, Any] = {}
        self._lines: dict[str, Any] = {}
        self._centres: Any = None
        self._labels: list[Any] = []
        self.ghosts: list[tuple[Any, Any]] = []  # (frame, ViserUrdf)
        self._cfgs: list[np.ndarray | None] = []  # each ghost's joints as last set
        self._n_ghosts = 0
        self._joints: list[str] | None = None

    # -- one kind of node each ------------------------------------------------------------------
    def _region(self, tid: str, v: np.ndarray, f: np.ndarray, colour: Any, opacity: float) -> None:
        h = self._regions.get(tid)
        if not len(f):
            if h is not None:
                h.visible = False
            return
        if h is None:
            self._regions[tid] = self.server.scene.add_mesh_simple(
                f"/plan/regions/{tid}", v, f, color=colour, opacity=opacity, side="double",
                cast_shadow=False, receive_shadow=False,
            )  # fmt: skip
            return
        _set(h, vertices=v, faces=f, color=tuple(colour), opacity=opacity, visible=True)

    def _segments(self, name: str, pts: np.ndarray, colour: Any, width: float) -> None:
        h = self._lines.get(name)
        empty = not len(pts)
        pts = _NOWHERE if empty else pts
        colours = np.broadcast_to(np.asarray(colour, np.uint8), (*pts.shape[:2], 3)).copy()
        if h is None:
            h = self._lines[name] = self.server.scene.add_line_segments(
                name, pts, colors=colours, thickness=width
            )
        else:
            _set(h, points=pts, colors=colours, thickness=width)
        _set(h, visible=not empty)

    def _points(self, pts: np.ndarray, colours: np.ndarray) -> None:
        empty = not len(pts)
        if empty:
            pts, colours = np.array([[0, 0, -1]], np.float32), np.zeros((1, 3), np.uint8)
        if self._centres is None:
            self._centres = self.server.scene.add_point_cloud(
                "/plan/circles/centres", pts, colors=colours, point_size=0.04
            )
        else:
            _set(self._centres, points=pts, colors=colours)
        _set(self._centres, visible=not empty)

    def _label(self, k: int, text: str | None, pos: tuple[float, float, float]) -> None:
        while len(self._labels) <= k:
            i = len(self._labels)
            self._labels.append(
                self.server.scene.add_label(f"/plan/route/stop{i}", "", position=(0, 0, -5))
            )
        h = self._labels[k]
        if text is None:
            _set(h, text="", visible=False)
            return
        _set(h, text=text, position=np.asarray(pos, float), visible=True)

    def labels(self) -> list[tuple[str, Any]]:
        """The stop labels in use: ``(key, handle)``, the handle's position in the world."""
        return [(f"stop{k}", h) for k, h in enumerate(self._labels) if h.text]

    # -- the whole plan ---------------------------------------------------------------------------
    def show(self, d: PlanDrawing) -> None:
        """Draw ``d`` into the existing nodes (created on first use), in one atomic update."""
        st = d.style
        with self.server.atomic():
            for tid, (v, f, colour) in d.regions.items():
                self._region(tid, v, f, colour, st.region_opacity)
            for tid in self._regions.keys() - d.regions.keys():
                self._regions[tid].visible = False
            self._segments("/plan/outlines/intersections", d.outlines, st.outline, 0.012)
            self._segments("/plan/circles/kept", d.circles_kept, st.kept, 0.012)
            self._segments("/plan/circles/rejected", d.circles_rejected, st.rejected, 0.008)
            self._points(d.centres, d.centre_colours)
            self._segments("/plan/route/line", d.route, st.route, 0.025)
            for k in range(max(len(d.labels), len(self._labels))):
                text, pos = d.labels[k] if k < len(d.labels) else (None, (0.0, 0.0, 0.0))
                if k < MAX_LABELS:
                    self._label(k, text, pos)
            self.place_ghosts(d if st.ghosts else None)

    def place_ghosts(self, d: PlanDrawing | None) -> None:
        """Ghost robots at the drawing's stops (None: hide them all)."""
        ghosts = [] if d is None else d.ghosts
        if self.urdf is not None:
            while len(self.ghosts) < len(ghosts):
                self._add_ghost()
        for k, (frame, urdf) in enumerate(self.ghosts):
            if k >= len(ghosts):
                _set(frame, visible=False)
                continue
            g = ghosts[k]
            _set(frame, position=np.array([g.x, g.y, 0.0]), wxyz=np.array(yaw_quat(g.yaw)))
            _set(frame, visible=self.show_ghosts)
            old = self._cfgs[k]
            if g.cfg is not None and (old is None or not np.array_equal(old, g.cfg)):
                pose(urdf, g.cfg)  # forward kinematics of every link: only on a change
                self._cfgs[k] = np.array(g.cfg)
        self._n_ghosts = len(ghosts)

    def ghosts_visible(self, visible: bool) -> None:
        self.show_ghosts = visible
        for k, (frame, _) in enumerate(self.ghosts):
            frame.visible = visible and k < self._n_ghosts

    def actuated_joints(self) -> list[str] | None:
        """The URDF's actuated joints, in the order ghosts take them (None without a robot);
        known once a ghost exists, so the first call makes one, hidden."""
        if self.urdf is None:
            return None
        if self._joints is None:
            if not self.ghosts:
                self._add_ghost()
                self.ghosts[0][0].visible = False
            self._joints = list(self.ghosts[0][1].get_actuated_joint_names())
        return self._joints

    def _add_ghost(self) -> None:
        k = len(self.ghosts)
        frame = self.server.scene.add_frame(f"/ghosts/{k}", show_axes=False)
        frame.visible = self.show_ghosts
        ghost = robot_urdf(self.server, self.urdf, f"/ghosts/{k}", GHOST_COLOUR)
        self.ghosts.append((frame, ghost))
        self._cfgs.append(None)

    def forget(self) -> None:
        """The scene was reset: every node is gone."""
        self._regions, self._lines, self._centres, self._labels = {}, {}, None, []
        self.ghosts, self._cfgs, self._n_ghosts = [], [], 0

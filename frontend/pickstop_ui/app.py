"""The 3D planner: a viser application over the REST API.

The scene (tables, trays with parts, obstacles, start and goal, the robot) is drawn from the
stored scene; trays and obstacles are dragged on the floor (x, y and yaw), a tray's height
following the support under it as the API places it (:mod:`pickstop_ui.placer`,
:mod:`pickstop_ui.resting`): a tray that would not stand is drawn so and not planned.
Every change of sigma, rule, task or layout asks the API for a new plan (not stored) and
draws it: each tray's base region as a translucent patch in its colour, the intersections'
outlines, the inscribed circles (dashed red where sigma rejects them, with the reason), the
chosen stops with a ghost robot in its witness configuration, and the route with its
direction. A quick plan without Monte Carlo is drawn first, then the success rates follow.

This module is the wiring only: viser handles and callbacks. What is drawn comes from pure
functions of the scene (:mod:`pickstop_ui.scene_view`) and of the plan
(:mod:`pickstop_ui.plan_view`, put into nodes by :mod:`pickstop_ui.plan_layer`), the panel's
words from :mod:`pickstop_ui.panel`, edits from :mod:`pickstop_ui.edits`, and the plans from the
re-plan worker (:mod:`pickstop_ui.replan`). While a tray or an obstacle is being dragged,
previews follow it, drawn and said to be previews; the exact plan replaces them on release.
While the engineer edits, a browser without a GPU draws at draft resolution
(:mod:`pickstop_ui.draft`), at full resolution again once the success rates are in.
"""

from __future__ import annotations

import contextlib
import copy
import json
import logging
import math
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
import viser

from pickstop.frames import yaw_quat
from pickstop.sequence.plan_model import Plan
from pickstop_ui import edits, panel
from pickstop_ui.client import ApiProblem, PickStopClient, StoredScene
from pickstop_ui.declutter import Label, screen_points, visible
from pickstop_ui.draft import DRAFT_SCALE, DraftResolution
from pickstop_ui.exports import compose_png, figure_lines
from pickstop_ui.guidance_layer import GuidanceFetcher, GuidanceLayer, GuidanceRequest
from pickstop_ui.guidance_view import guidance_drawing, legend
from pickstop_ui.history import History
from pickstop_ui.hover import hover_data, names_of
from pickstop_ui.measure import MeasureTool
from pickstop_ui.orders import TASK, mix_summary, order_ids, with_order
from pickstop_ui.overlay import Overlay, parse_layout
from pickstop_ui.picking import hit_point, item_box, pick
from pickstop_ui.placer import Ask, Placer
from pickstop_ui.plan_layer import ROBOT_COLOUR, PlanLayer, pose, robot_urdf
from pickstop_ui.plan_view import joint_cfg, plan_drawing, playback, style_of
from pickstop_ui.replan import MC_SAMPLES, Replanner, Request
from pickstop_ui.resting import (
    Rest,
    Standing,
    follow,
    names_of_items,
    still_placed,
    support_line,
)
from pickstop_ui.robot_model import fetch_robot, scene_robot_name
from pickstop_ui.scene_layer import SceneLayer
from pickstop_ui.scene_view import initial_sigma, tray_colours
from pickstop_ui.selection import Key, Selection
from pickstop_ui.suggest import Suggester
from pickstop_ui.views import PRESETS, CameraPose, Viewport, preset

log = logging.getLogger("pickstop.ui")

#: The sigma slider's range ends here [m]: the widest stops of the example scenes reach
#: about 0.3 m, and a layout beyond this is infeasible for any real base.
SIGMA_MAX = 0.5
RENDER = (1280, 720)  # the PNG's render of the 3D view, width and height [px]
VIEW_LABELS = {"top": "Top", "front": "Front", "iso": "Iso", "fit": "Fit all"}


class LocalServer(viser.ViserServer):
    """A viser server that opens no share tunnel: the layout stays in the plant whatever a
    page asks (the panel has no share control either)."""

    def request_share_url(self, verbose: bool = True) -> str | None:
        log.warning("a share URL was requested and refused: the planner serves locally only")
        return None


def needed_label(tid: str, names: dict[str, str]) -> str:
    """The task tick of tray ``tid``: its name, with its id where the name differs."""
    name = names.get(tid, tid)
    return f"needed: {name} ({tid})" if name != tid else f"needed: {tid}"


@dataclass
class PlannerState:
    """What one planner window shows; shared by every browser tab connected to it."""

    stored: StoredScene
    doc: dict[str, Any]
    plan: Plan | None = None
    plan_id: str | None = None
    error: str | None = None
    seq: int = 0
    drawn_seq: int = 0
    last_ms: float = 0.0
    exact_ms: float | None = None  # the last exact plan, request to drawn [ms]
    mc_ms: float | None = None  # the last Monte Carlo, request to drawn [ms]
    mc_t0: float = 0.0  # when the running Monte Carlo started [s, perf_counter]
    busy: bool = False
    history: History | None = None  # the edits, for undo and redo (made with the state)

    def __post_init__(self) -> None:
        if self.history is None:
            self.history = History.start(self.doc)


class PlannerApp:
    def __init__(
        self,
        client: PickStopClient,
        scene_id: str,
        host: str = "127.0.0.1",
        port: int = 8080,
        draw_robot: bool = True,
        flat_lighting: bool = True,
        draft_scale: float = DRAFT_SCALE,
    ) -> None:
        """``flat_lighting``: light the scene with one hemisphere light (the default) rather
        than the environment map, which costs a software renderer (a browser without a GPU)
        about half of every frame and gives shinier colours. ``draft_scale``: the pixel ratio
        (a fraction of the device's) at which such a browser draws while the engineer edits
        (from a change until its success rates are drawn); 1: full resolution throughout."""
        self.api = client
        self.flat_lighting = flat_lighting
        self.draft_scale = draft_scale
        stored = client.scene(scene_id)
        # The scene's own robot, from the API (URDF, meshes, locked and pre-grasp joints).
        self.robot = fetch_robot(client, scene_robot_name(stored.doc)) if draw_robot else None
        self._urdf = self.robot.urdf if self.robot is not None else None
        self._locked = self.robot.joint_values if self.robot is not None else {}
        self.state = PlannerState(stored, copy.deepcopy(stored.doc))
        self.standing = Standing.start(stored.doc)  # which trays do not stand (lock held)
        self.rests: dict[str, Rest] = {}  # each tray's last placement answer
        self._gen = 0  # the document's edit generation: older placement answers are dropped
        self.server = LocalServer(host=host, port=port, label="PickStop", verbose=False)
        self.port = self.server.get_port()
        self._lock = threading.Lock()
        self._tray_ui: dict[str, Any] = {}
        self._stored_key: str | None = None  # the document and options of state.plan_id
        self._mix_gen = 0  # the newest mix asked for (an older answer is not shown)
        self._playing = threading.Lock()  # held while the route plays
        self._draw_scene()
        self.layer = PlanLayer(self.server, self._urdf)
        self._build_gui()
        self.server.on_client_connect(self._on_connect)
        self.server.on_client_disconnect(lambda c: self.viewports.pop(c.client_id, None))
        self.replanner = Replanner(client, self, self._lock)
        self.guidance = GuidanceLayer(self.server)
        self.guidance_ms: float | None = None  # the last tray selected to its zones drawn [ms]
        self.guide = GuidanceFetcher(client, self._guidance_ready)
        self.placer = Placer(client, self._placed)
        self.request("open")

    # -- lifecycle ---------------------------------------------------------------------------
    def close(self) -> None:
        self.placer.close()
        self.guide.close()
        self.replanner.close()
        self.server.stop()

    def _on_connect(self, client: viser.ClientHandle) -> None:
        client.camera.up_direction = (0.0, 0.0, 1.0)
        self.show_view(client, "iso")
        client.camera.on_update(lambda _: self._declutter())

    # -- labels and hover ------------------------------------------------------------------------
    def _declutter(self) -> None:
        """Show only labels that do not overlap as the first browser's camera sees them
        (markers first, then trays, then stops); a hidden one still tells on hover."""
        clients = list(self.server.get_clients().values())
        if not clients:
            return
        client = clients[0]
        cam = client.camera
        vp = self.viewports.get(client.client_id) or Viewport.default()
        entries = [(h, Label(k, str(h.text), a, 1.0 if k.startswith("trays/") else 2.0))
                   for k, h, a in self.scene.labels()]  # fmt: skip
        entries += [(h, Label(k, str(h.text), tuple(map(float, h.position)), 0.0))
                    for k, h in self.layer.labels()]  # fmt: skip
        if not entries:
            return
        labels = [lab for _, lab in entries]
        anchors = np.array([lab.anchor for lab in labels])
        px, ahead = screen_points(cam.position, cam.wxyz, cam.fov, (vp.width, vp.height), anchors)
        show = visible(labels, px, ahead, vp.height)
        with self.server.atomic():
            for h, lab in entries:
                if h.visible != show[lab.key]:
                    h.visible = show[lab.key]

    def _tell(self) -> None:
        """What the page tells on hover: the working document's items, and the plan drawn."""
        with self._lock:
            data = hover_data(self.state.plan, self.state.doc)
        self.overlay.show(data)

    # -- views -------------------------------------------------------------------------------
    def show_view(self, client: viser.ClientHandle, name: str) -> CameraPose:
        """Point ``client``'s camera with preset ``name`` (:data:`views.PRESETS`), framing the
        whole scene beside the panel as the page last reported it."""
        vp = self.viewports.get(client.client_id) or Viewport.default()
        cam = client.camera
        current = np.asarray(cam.look_at) - np.asarray(cam.position)
        with self._lock:
            pose = preset(name, self.state.doc, vp, current if name == "fit" else None)
        with client.atomic():
            cam.fov = pose.fov
            cam.up_direction = pose.up
            cam.position = pose.position
            cam.look_at = pose.look_at
        return pose

    def _layout(self, event: Any) -> None:
        """The page reported where the panel is: the first report reframes the first view."""
        got = parse_layout(str(event.target.value))
        if got is None or event.client is None:
            return
        first = event.client.client_id not in self.viewports
        w, h, left = got
        self.viewports[event.client.client_id] = Viewport(w, h, left)
        if first:
            self.show_view(event.client, "iso")

    # -- the scene ---------------------------------------------------------------------------
    def _draw_scene(self) -> None:
        sc = self.server.scene
        sc.set_up_direction("+z")
        # No shadow pass: it doubles the cost of every frame in a browser without a GPU.
        sc.configure_default_lights(enabled=True, cast_shadow=False)
        if self.flat_lighting:
            sc.configure_environment_map(None)
            sc.add_light_hemisphere("/lights/flat", ground_color=(170, 170, 170), intensity=2.0)
        self.scene = SceneLayer(self.server)
        d = self.scene.sync(self.state.doc)
        self.selection = Selection(self.server, self._dragged)
        sc.on_click()(self._clicked)
        w, h = d.floor_size
        sc.add_grid("/floor", width=w, height=h, cell_size=0.5, position=d.floor_centre)
        if self.robot is not None:
            self._draw_robot(*d.robot_pose)

    def _draw_robot(self, x: float, y: float, yaw: float) -> None:
        """The robot at ``(x, y, yaw)`` [m, rad] as it is: the collision meshes the ghosts
        show, opaque, the arm in its travel posture."""
        assert self.robot is not None
        self._robot_frame = self.server.scene.add_frame(
            "/robot", show_axes=False, position=(x, y, 0.0), wxyz=yaw_quat(yaw)
        )
        self._robot = robot_urdf(self.server, self._urdf, "/robot", ROBOT_COLOUR)
        self._robot_pose(self.robot.arm_joints, self.robot.travel_theta(self.robot.arm_joints))

    def _robot_pose(self, joints: list[str], theta: list[float]) -> None:
        """The drawn robot's arm at ``theta`` (for ``joints``) [rad or m], the rest locked."""
        names = list(self._robot.get_actuated_joint_names())
        self._robot_cfg = joint_cfg(names, joints, theta, None, self._locked)
        pose(self._robot, self._robot_cfg)

    def _clicked(self, event: Any) -> None:
        """A click in the 3D view selects the item under it, or clears the selection."""
        with self._lock:
            boxes = [b for b in map(item_box, self.scene.drawn_items()) if b is not None]
        if self.measure.on:
            p = hit_point(boxes, event.ray_origin, event.ray_direction)
            if p is not None:
                self.measure_md.content = self.measure.add(p)
            return
        hit = pick(boxes, event.ray_origin, event.ray_direction)
        if hit is None:
            self.deselect()
        else:
            self.select((hit.kind, hit.id))

    def select(self, key: Key) -> None:
        """Put the gizmo on tray or obstacle ``key`` (kind, id)."""
        with self._lock:
            pose = edits.pose_of(self.state.doc, *key)
        if pose is None:
            return
        self.selection.select(key, pose)
        self._selection_changed()

    def deselect(self) -> None:
        self.selection.clear()
        self._selection_changed()

    def _selection_changed(self) -> None:
        key = self.selection.key
        with self._lock:
            name = None if key is None else edits.display_name(self.state.doc, key[1])
        self.selected_md.content = panel.selected_line(key, name)
        self.remove_sel.disabled = key is None or key[0] != "trays"
        with self._lock:
            pose = None if key is None else edits.pose_of(self.state.doc, *key)
            rest = None if key is None else self.rests.get(key[1])
            names = names_of_items(self.state.doc)
        self._readout(pose)
        tray = key is not None and key[0] == "trays"
        self.support_md.content = support_line(rest, names) if tray else ""
        if tray and rest is None and key is not None:
            self._check_one(key[1])
        self._ask_guidance()

    # -- placement guidance -------------------------------------------------------------------
    def _ask_guidance(self) -> None:
        """The selected tray's zones are asked for (off this thread); none shown otherwise."""
        key = self.selection.key
        if key is None or key[0] != "trays":
            self.guide.clear()
            self.guidance.hide()
            self.guidance_md.content = ""
            return
        with self._lock:
            doc = with_order(self.state.doc, self.order.value)
            why = self.standing.verdict(names_of_items(doc))
        if why is not None:  # the API checks the layout first: it would refuse it
            self.guide.clear()
            self.guidance.hide()
            self.guidance_md.content = f"*No guidance while a tray does not stand ({why}).*"
            return
        self.guide.submit(doc, key[1], float(self.sigma.value))
        self.guidance_md.content = f"*Guidance for {key[1]}: asking…*"

    def _guidance_ready(self, req: GuidanceRequest, answer: Any) -> None:
        """The fetcher's answer (on its thread): drawn if its tray is still selected."""
        if self.selection.key != ("trays", req.tray) or not self.guide.current(req):
            return
        if isinstance(answer, ApiProblem):
            self.guidance.hide()
            self.guidance_md.content = f"⚠ Guidance: {answer.title}: {answer.detail}"
            return
        z = float(edits.tray(req.scene, req.tray)["pose"].get("z", 0.0))
        self.guidance.show(guidance_drawing(answer, z))
        self.guidance_md.content = legend(answer)
        self.guidance_ms = (time.perf_counter() - req.t0) * 1e3

    # -- layout suggestions ---------------------------------------------------------------------
    def _layout_request(self) -> tuple[dict[str, Any], list[str] | None, dict[str, Any]]:
        """What a suggestion is asked for: the document, the selected tray (None: every tray
        the orders need) and the plan options."""
        key = self.selection.key
        with self._lock:
            doc = copy.deepcopy(self.state.doc)
        movable = [key[1]] if key is not None and key[0] == "trays" else None
        return doc, movable, self.options(0)

    def _accept_layout(self, scene: dict[str, Any], label: str) -> None:
        """A suggestion's moved scene becomes the working document as one undoable step."""
        with self._lock:
            self.state.doc = copy.deepcopy(scene)
            self._record(label)
        self._show_doc()
        self.request(f"accepted {label}")

    def _dragged(self, key: Key, pos: tuple[float, float, float], yaw: float, final: bool) -> None:
        """The gizmo moved: keep x, y (a tray's in whole base cells) and yaw; the item follows
        at once. An obstacle keeps its height, a preview is planned while the drag goes on,
        the exact plan when it ends (then the move is one undoable step). A tray's height
        follows the support under it, as the API places it (:meth:`_placed`, off this loop)."""
        kind, oid = key
        steps = {"step": max(float(self.snap.value), 0.0),
                 "yaw_step": math.radians(max(float(self.turn_snap.value), 0.0))}  # fmt: skip
        with self._lock:
            pose = edits.move(self.state.doc, kind, oid, pos[0], pos[1], yaw, **steps)
            if pose is not None and final and kind != "trays":
                self._record(edits.move_label(self.state.history.doc(), self.state.doc, kind, oid))
            ask = None if kind != "trays" else self.standing.ask_doc(self.state.doc)
            gen, rest = self._gen, self.rests.get(oid)
        if pose is None:
            return
        z = float(pose.get("z", 0.0))
        self.scene.place(kind, oid, pose["x"], pose["y"], z, pose["yaw"])
        self._readout(pose)
        if ask is not None:
            if final and rest is not None and (rest.x, rest.y, rest.yaw) == (
                pose["x"], pose["y"], pose["yaw"]):  # fmt: skip
                self._commit(rest, "")  # the release's pose is placed already
            else:
                self.placer.submit(oid, ask, pose["x"], pose["y"], pose["yaw"], z,
                                   "commit" if final else "drag", gen)  # fmt: skip
            return
        if final:
            self.selection.place(pose)
            self._ask_guidance()
        self.request(f"moved {oid}" if final else f"dragging {oid}", preview=not final)

    # -- what trays stand on ---------------------------------------------------------------------
    def _placed(self, ask: Ask, answer: dict[str, Any] | ApiProblem) -> None:
        """The API placed a tray (on the placer's thread): a dragged tray follows the support
        under it, drawn red with the reason where it would float or overlap (and no preview
        pretends a plan of it); a released or typed pose becomes one undoable step; a check
        says whether a tray stands."""
        with self._lock:
            if ask.gen != self._gen:  # an undo or another edit came meanwhile
                return
            names = names_of_items(self.state.doc)
        if isinstance(answer, ApiProblem):
            if answer.status == 0:  # the API cannot be reached: the plan request will say so
                log.warning("placement of %s: %s", ask.tray, answer)
                return
            answer = {"tray": ask.tray, "x": ask.x, "y": ask.y, "yaw": ask.yaw, "z": None,
                      "support": None, "free": False, "problem": answer.detail}  # fmt: skip
        rest = follow(answer, ask.z_hint, names)
        if ask.kind == "commit":
            self._commit(rest, ask.label)
            return
        with self._lock:
            pose = edits.pose_of(self.state.doc, "trays", ask.tray)
            if pose is None:
                return
            self.rests[ask.tray] = rest
            preview = None
            if ask.kind == "check":
                self.standing = self.standing.told(ask.tray, rest.why, pose)
            else:
                self.standing = self.standing.told(ask.tray, rest.why)
                pose = edits.place(self.state.doc, "trays", ask.tray, pose["x"], pose["y"],
                                   pose["yaw"], rest.z)  # fmt: skip
                preview = copy.deepcopy(self.state.doc)
                edits.place(preview, "trays", ask.tray, rest.x, rest.y, rest.yaw, rest.z)
        self._show_rest(ask.tray, rest)
        if ask.kind == "drag":
            self.scene.place("trays", ask.tray, pose["x"], pose["y"], rest.z, pose["yaw"])
            self._readout(pose)
            self.request(f"dragging {ask.tray}", preview=True, doc=preview)
        elif self.standing.problems or self.state.error is not None:
            self.request(f"checked {ask.tray}")

    def _commit(self, rest: Rest, label: str) -> None:
        """A released or typed tray pose, its height following its support, is one undoable
        step (kept where it does not stand, drawn so and not planned: Undo takes it back)."""
        tid = rest.tray
        with self._lock:
            try:
                pose = edits.place(self.state.doc, "trays", tid, rest.x, rest.y, rest.yaw, rest.z)
            except edits.EditError:  # removed meanwhile
                return
            self.rests[tid] = rest
            self.standing = self.standing.told(tid, rest.why, pose)
            self._gen += 1  # a drag's answer still on its way is older than this step
            before = self.state.history.doc()
            self._record(label or edits.move_label(before, self.state.doc, "trays", tid))
        self.scene.place("trays", tid, rest.x, rest.y, rest.z, rest.yaw)
        self._show_rest(tid, rest)
        if self.selection.key == ("trays", tid):
            self.selection.place(pose)
            self._readout(pose)
            self._ask_guidance()
        self._tell()
        self.request(f"moved {tid}")

    def _show_rest(self, tid: str, rest: Rest | None) -> None:
        """Tray ``tid`` drawn as standing or not, and the panel's support line if selected."""
        self.scene.mark("trays", tid, None if rest is None else rest.why)
        if self.selection.key == ("trays", tid):
            with self._lock:
                names = names_of_items(self.state.doc)
            self.support_md.content = support_line(rest, names)

    def _check_trays(self) -> None:
        """After an undo, redo or other edit of the document: older placement answers are
        dropped, and each tray not at a pose known to stand is asked about (off this thread);
        a tray back where it stood stands."""
        with self._lock:
            self._gen += 1
            doc = self.state.doc
            self.standing = self.standing.settle(doc)
            problems = dict(self.standing.problems)
            unknown = self.standing.unknown(doc)
            poses = {t["id"]: t.get("pose", {}) for t in doc["trays"]}
            self.rests = still_placed(self.rests, doc)
        for tid in poses:
            self.scene.mark("trays", tid, problems.get(tid))
        for tid in unknown:
            self._check_one(tid)

    def _check_one(self, tid: str) -> None:
        """Ask what tray ``tid`` stands on where it is (the panel's support line)."""
        with self._lock:
            pose = edits.pose_of(self.state.doc, "trays", tid)
            ask = self.standing.ask_doc(self.state.doc)
            gen = self._gen
        if pose is not None:
            self.placer.submit(tid, ask, float(pose.get("x", 0.0)), float(pose.get("y", 0.0)),
                               float(pose.get("yaw", 0.0)), float(pose.get("z", 0.0)), "check",
                               gen)  # fmt: skip

    def _unplanned(self, why: str) -> None:
        """The layout is not planned while a tray does not stand: the panel says which and
        why, the last plan stays greyed out."""
        problem = ApiProblem(0, "A tray does not stand", why)
        with self._lock:
            self.state.error, self.state.busy = why, False
            self.state.drawn_seq = self.state.seq
        self.status.content = f"**Status:** no plan — ⚠ {why}"
        self.summary.content = panel.failure_summary(problem)
        plan = self.state.plan
        if plan is not None:
            with self._lock:
                doc = copy.deepcopy(self.state.doc)
            self.layer.show(plan_drawing(plan, tray_colours(doc), style_of(plan, True),
                                         names=names_of(doc)))  # fmt: skip
        self.draft.set(False)

    # -- undo and redo ---------------------------------------------------------------------------
    def _record(self, label: str) -> None:
        """The working document as it is now is one undoable step ``label`` (lock held)."""
        st = self.state
        st.history = st.history.record(label, st.doc)
        self._history_changed()

    def _travel(self, how: str) -> None:
        """Undo, redo or revert to saved (``how``): the document, the scene, the panel and
        the plan follow."""
        with self._lock:
            h = self.state.history
            label = {"undo": h.undo_label, "redo": h.redo_label}.get(how, "revert to saved")
            new = {"undo": h.undo, "redo": h.redo, "revert": h.revert}[how]()
            if new is h:
                return
            self.state.history, self.state.doc = new, new.doc()
            self._history_changed()
        self._show_doc()
        self.request(f"{how} {label}")

    def _show_doc(self) -> None:
        """Draw the working document: the scene's nodes, the gizmo and the trays' panel."""
        self.scene.sync(self.state.doc)
        self._check_trays()
        key = self.selection.key
        pose = None if key is None else edits.pose_of(self.state.doc, *key)
        if key is not None and pose is None:
            self.deselect()
        elif key is not None and pose is not None:
            self.selection.place(pose)
            self._selection_changed()
        self._sync_tray_gui()
        self._tell()
        self._declutter()

    def _history_changed(self) -> None:
        """The undo and redo buttons and the scene's line say what they would do."""
        h = self.state.history
        self.undo_btn.disabled, self.redo_btn.disabled = h.undo_label is None, h.redo_label is None
        self.undo_btn.label = f"Undo {h.undo_label}" if h.undo_label else "Undo"
        self.redo_btn.label = f"Redo {h.redo_label}" if h.redo_label else "Redo"
        self.revert_btn.disabled = not h.dirty
        self.saved.content = panel.scene_revision(self.state.stored, dirty=h.dirty)

    # -- the panel ---------------------------------------------------------------------------
    def _build_gui(self) -> None:
        gui, st = self.server.gui, self.state
        gui.configure_theme(
            control_width="large", dark_mode=False, show_logo=False, show_share_button=False
        )
        self.draft = DraftResolution(self.server, self.draft_scale)
        self.overlay = Overlay(self.server)
        self.viewports: dict[int, Viewport] = {}
        self.overlay.layout.on_update(self._layout)
        self.status = gui.add_markdown("**Status:** loading")
        self._build_history_gui()
        view = gui.add_button_group("View", [VIEW_LABELS[p] for p in PRESETS])
        by_label = {v: k for k, v in VIEW_LABELS.items()}
        view.on_click(lambda e: e.client is not None and self.show_view(
            e.client, by_label[e.target.value]))  # fmt: skip
        self.summary = gui.add_markdown("")
        with gui.add_folder("Planning"):
            self.sigma = gui.add_slider("sigma [m]", min=0.0, max=SIGMA_MAX, step=0.005,
                                        initial_value=initial_sigma(st.doc))  # fmt: skip
            self.rule = gui.add_dropdown("rule", ("sigma", "success"), initial_value="sigma")
            self.target = gui.add_slider(
                "target success", min=0.6, max=0.99, step=0.01, initial_value=0.95
            )
            self.objective = gui.add_dropdown(
                "objective", ("stops", "time", "expected-time"), initial_value="stops"
            )
            self.placement = gui.add_dropdown(
                "stop at", ("centre", "success"), initial_value="centre",
                hint="centre: each stop at its circle's centre (the paper); success: where "
                "its success estimate is highest inside its intersection",
            )  # fmt: skip
            ids = order_ids(st.doc)
            self.order = gui.add_dropdown(
                "order", (TASK, *ids), initial_value=TASK, visible=bool(ids),
                hint="the plan drawn: the task's or an order's",
            )  # fmt: skip
            self.mix_md = gui.add_markdown("")
            # The ghosts stand on their stops' circles: off until asked for.
            self.show_robots = gui.add_checkbox(
                "ghost robots at stops", self.layer.show_ghosts,
                hint="the robot at each stop in its witness posture (it covers the circles)",
            )  # fmt: skip
            self.show_robots.on_update(lambda _: self.layer.ghosts_visible(self.show_robots.value))
        for h in (self.sigma, self.rule, self.target, self.objective, self.placement,
                  self.order):  # fmt: skip
            h.on_update(lambda e: self.request(f"{e.target.label} changed"))
        self._build_selection_gui()
        self.suggest = Suggester(self.server, self.api, self._layout_request, self._accept_layout)
        self.trays_folder = gui.add_folder("Trays")
        self._build_tray_gui()
        with gui.add_folder("Scene"):
            gui.add_button("Save scene", icon=viser.Icon.DEVICE_FLOPPY).on_click(
                lambda _: self._save()
            )
            self.revert_btn = gui.add_button("Revert to saved", icon=viser.Icon.RESTORE,
                                             disabled=True)  # fmt: skip
            self.revert_btn.on_click(lambda _: self._travel("revert"))
            self.saved = gui.add_markdown(panel.scene_revision(st.stored))
        with gui.add_folder("Plan"):
            self.play_btn = gui.add_button(
                "Play route", hint="drive the route, the arm in its travel posture; reach for "
                "each part at its stop and fold back",
            )  # fmt: skip
            self.play_btn.on_click(lambda _: self._play())
            self.robot_md = gui.add_markdown(panel.travel_line(self.robot))
            gui.add_button("Download report").on_click(self._download_report)
            gui.add_button("Download stops CSV").on_click(self._download_stops)
            gui.add_button("Download plan JSON").on_click(self._export)
            gui.add_button("Download PNG snapshot").on_click(self._snapshot)
            self.link = gui.add_markdown("")
        from pickstop_ui.fleet_view import FleetView

        self.fleet = FleetView(self.server, self.api, self._store_plan)
        self.stops_md = gui.add_markdown("")

    def _build_history_gui(self) -> None:
        """Undo and redo: two buttons and their keys (Ctrl+Z, Ctrl+Shift+Z or Ctrl+Y)."""
        gui = self.server.gui
        self.undo_btn = gui.add_button("Undo", icon=viser.Icon.ARROW_BACK_UP, disabled=True,
                                       hint="Ctrl+Z")  # fmt: skip
        self.redo_btn = gui.add_button("Redo", icon=viser.Icon.ARROW_FORWARD_UP, disabled=True,
                                       hint="Ctrl+Shift+Z or Ctrl+Y")  # fmt: skip
        self.undo_btn.on_click(lambda _: self._travel("undo"))
        self.redo_btn.on_click(lambda _: self._travel("redo"))
        for label, key, modifier, how in (
            ("Undo", "Z", "cmd/ctrl", "undo"),
            ("Redo", "Z", "cmd/ctrl+shift", "redo"),
            ("Redo", "Y", "cmd/ctrl", "redo"),
        ):
            cmd = gui.add_command(label, hotkey=key, modifier=modifier)  # type: ignore[arg-type]
            cmd.on_trigger(lambda _, how=how: self._travel(how))

    def _build_selection_gui(self) -> None:
        """The selected item's folder: what it is, its pose as numbers (shown live while it is
        dragged, typed and applied with Enter or *Apply*), the snap steps, Deselect (Esc),
        Remove (Delete), and the measure tool."""
        gui, doc = self.server.gui, self.state.doc
        with gui.add_folder("Selected"):
            self.selected_md = gui.add_markdown(panel.selected_line(None, None))
            self.guidance_md = gui.add_markdown("")  # the selected tray's zones' legend
            with gui.add_form(None) as form:
                self.num = {
                    "x": gui.add_number("x [m]", 0.0, step=0.001, disabled=True),
                    "y": gui.add_number("y [m]", 0.0, step=0.001, disabled=True),
                    "yaw": gui.add_number("yaw [°]", 0.0, step=0.1, disabled=True),
                    "z": gui.add_number("z [m]", 0.0, step=0.001, disabled=True,
                                        hint="height of the item's base; a tray's follows the "
                                        "top of what it stands on"),
                }  # fmt: skip
                self.support_md = gui.add_markdown("")  # what the selected tray stands on
                self.apply_btn = gui.add_button("Apply", icon=viser.Icon.CHECK, disabled=True,
                                                hint="or Enter in a field")  # fmt: skip
            self.apply_btn.on_click(lambda _: form.submit())
            form.on_submit(lambda _: self._typed())
            self.snap = gui.add_number(
                "snap [m]", edits.grid_step(doc), min=0.0, max=1.0, step=0.005,
                hint="drags move by whole steps (0: free); the base grid's cell lets the "
                "regions be reused",
            )  # fmt: skip
            self.turn_snap = gui.add_number("turn snap [°]", 5.0, min=0.0, max=90.0, step=0.5,
                                            hint="turns go by whole steps; 0: free")  # fmt: skip
            gui.add_button("Deselect", icon=viser.Icon.X, hint="Esc").on_click(
                lambda _: self.deselect()
            )
            self.remove_sel = gui.add_button(
                "Remove selected tray", icon=viser.Icon.TRASH, disabled=True,
                hint="Delete; Undo brings it back",
            )  # fmt: skip
            self.remove_sel.on_click(lambda _: self._remove_selected())
        with gui.add_folder("Measure"):
            self.measure_btn = gui.add_button("Measure a distance", icon=viser.Icon.RULER_MEASURE)
            self.measure_btn.on_click(lambda _: self._toggle_measure())
            self.measure_md = gui.add_markdown("")
        self.measure = MeasureTool(self.server)
        gui.add_command("Deselect", hotkey="escape").on_trigger(lambda _: self._escape())
        gui.add_command("Remove selected tray", hotkey="delete").on_trigger(
            lambda _: self._remove_selected()
        )

    def _escape(self) -> None:
        """Esc: leave the measure tool if it is on, else clear the selection."""
        if self.measure.on:
            self._toggle_measure()
        else:
            self.deselect()

    def _toggle_measure(self) -> None:
        m = self.measure
        m.on = not m.on
        m.clear()
        self.measure_btn.label = "Stop measuring" if m.on else "Measure a distance"
        self.measure_md.content = panel.MEASURE_HELP if m.on else ""

    def _typed(self) -> None:
        """The pose typed in the panel, applied exactly to the selected item (one step)."""
        key = self.selection.key
        if key is None:
            return
        x, y, z = (float(self.num[k].value) for k in ("x", "y", "z"))
        yaw = math.radians(float(self.num["yaw"].value))
        if key[0] == "trays":  # its height follows the support under the typed place
            if not all(map(math.isfinite, (x, y, yaw))):
                self._notify("x, y and yaw must be finite numbers", error=True)
                return
            with self._lock:
                ask = self.standing.ask_doc(self.state.doc)
                label = f"place {edits.display_name(self.state.doc, key[1])}"
                z = float((edits.pose_of(self.state.doc, *key) or {}).get("z", 0.0))
                gen = self._gen
            self.placer.submit(key[1], ask, x, y, yaw, z, "commit", gen, label)
            return
        try:
            with self._lock:
                pose = edits.place(self.state.doc, *key, x, y, yaw, z)
                self._record(f"place {edits.display_name(self.state.doc, key[1])}")
        except edits.EditError as e:
            self._notify(str(e), error=True)
            return
        self._show_doc()
        self._readout(pose)
        self.request(f"placed {key[1]}")

    def _readout(self, pose: dict[str, Any] | None) -> None:
        """The numbers show ``pose`` (None: nothing selected, the fields off); a tray's z is
        read only: it follows the support under it."""
        tray = self.selection.key is not None and self.selection.key[0] == "trays"
        for name, h in self.num.items():
            h.disabled = pose is None or (tray and name == "z")
            if pose is not None:
                v = float(pose.get(name, 0.0))
                h.value = round(math.degrees(v), 2) if name == "yaw" else round(v, 4)
        self.apply_btn.disabled = pose is None

    def _remove_selected(self) -> None:
        key = self.selection.key
        if key is None or key[0] != "trays":
            return
        self.deselect()
        self._edit(edits.remove_tray, key[1], cause="remove")

    def _sync_tray_gui(self) -> None:
        """The trays' panel shows the working document: rebuilt when trays came or went, else
        its ticks and the name field set in place."""
        doc = self.state.doc
        ids = [t["id"] for t in doc["trays"]]
        if [k.removeprefix("cb:") for k in self._tray_ui if k.startswith("cb:")] != ids:
            self._build_tray_gui()
            return
        task, names = set(edits.task_of(doc)), names_of(doc)
        for tid in ids:
            cb = self._tray_ui[f"cb:{tid}"]
            cb.value = tid in task
            if cb.label != needed_label(tid, names):
                cb.label = needed_label(tid, names)
        sel = self._tray_ui["sel"]
        self._tray_ui["name"].value = self._tray_name(sel.value)

    def _build_tray_gui(self) -> None:
        for h in self._tray_ui.values():
            h.remove()
        gui, doc = self.server.gui, self.state.doc
        task, ids = set(edits.task_of(doc)), tuple(t["id"] for t in doc["trays"])
        self._tray_ui = {}
        with self.trays_folder:
            names = names_of(doc)
            for tid in ids:
                cb = gui.add_checkbox(needed_label(tid, names), tid in task)
                self._tray_ui[f"cb:{tid}"] = cb
                cb.on_update(lambda e, tid=tid: e.client is not None and self._edit(
                    edits.set_needed, tid, e.target.value, cause="task"))  # fmt: skip
            sel = gui.add_dropdown("tray", ids, initial_value=ids[0])
            name = gui.add_text("name", doc["trays"][0].get("name", ""))
            sel.on_update(lambda _: setattr(name, "value", self._tray_name(sel.value)))
            for label, edit, named in (
                ("Rename", edits.rename_tray, True),
                ("Add a copy", edits.copy_tray, True),
                ("Remove", edits.remove_tray, False),
            ):
                b = self._tray_ui[label] = gui.add_button(label)
                b.on_click(self._tray_button(edit, sel, name if named else None))
            self._tray_ui.update(sel=sel, name=name)

    def _tray_button(self, edit: Callable[..., Any], sel: Any, name: Any) -> Callable[[Any], None]:
        """A click applies ``edit`` to the selected tray (and the name field's text, if given)."""
        cause = edit.__name__.removesuffix("_tray")

        def click(_: Any) -> None:
            args: tuple[Any, ...] = () if name is None else (name.value,)
            if edit is edits.copy_tray:
                placed = self._free_spot(sel.value)
                if placed is None:
                    return
                args = (*args, placed)
            self._edit(edit, sel.value, *args, cause=cause)

        return click

    def _free_spot(self, tid: str) -> dict[str, Any] | None:
        """The API's copy of tray ``tid`` on a free spot of its support (None, told, if the
        support is full or the API cannot answer)."""
        with self._lock:
            doc = copy.deepcopy(self.state.doc)
        try:
            placed = self.api.copy_tray(doc, tid)
        except ApiProblem as e:
            self._notify(f"No copy: {e}", error=True)
            return None
        if placed is None:
            self._notify(
                f"No free spot for a copy of {edits.display_name(doc, tid)} on its support."
            )
        return placed

    def _tray_name(self, tid: str) -> str:
        with self._lock:
            return str(edits.tray(self.state.doc, tid).get("name", ""))

    def _edit(self, edit: Callable[..., Any], tid: str, *args: Any, cause: str) -> None:
        """Apply a pure document edit to tray ``tid`` as one undoable step, draw what changed
        and re-plan; an edit the scene cannot take is told and changes nothing."""
        try:
            with self._lock:
                name = edits.display_name(self.state.doc, tid)
                edit(self.state.doc, tid, *args)
                self._record(f"{cause} {name}")
        except edits.EditError as e:
            self._notify(str(e))
            return
        self._show_doc()
        if cause == "remove":
            self._notify(f"Removed {name}. Undo (Ctrl+Z) brings it back.")
        self.request(f"{cause} {tid}")

    def _notify(self, text: str, error: bool = False) -> None:
        for c in self.server.get_clients().values():
            c.add_notification(
                "PickStop", text, color="red" if error else "blue", auto_close_seconds=6.0
            )

    # -- planning ----------------------------------------------------------------------------
    def options(self, samples: int) -> dict[str, Any]:
        return {
            "sigma": float(self.sigma.value),
            "rule": self.rule.value,
            "target": float(self.target.value),
            "objective": self.objective.value,
            "placement": self.placement.value,
            "samples": samples,
        }

    def request(self, cause: str, preview: bool = False, doc: dict[str, Any] | None = None) -> None:
        """Plan the document as it is now, or ``doc`` (the newest request wins, see
        :mod:`replan`); while a tray does not stand, nothing is planned and the panel says so."""
        with self._lock:
            why = self.standing.verdict(names_of_items(self.state.doc))
        if why is not None:
            self._unplanned(why)
            return
        self.draft.set(True)  # before the plan's update, so its frame is a quick one
        with self._lock:
            doc = with_order(self.state.doc if doc is None else doc, self.order.value)
        req = self.replanner.submit(doc, self.options(0), cause, preview)
        with self._lock:  # two callbacks may submit at once: the newest number stays
            self.state.seq, self.state.busy = max(self.state.seq, req.seq), True
        if not preview:
            self.status.content = panel.waiting_line(cause)

    # The re-plan worker's sink (called on its thread).
    def plan_ready(self, req: Request, plan: Plan, final: bool) -> None:
        st = self.state
        with self._lock:
            why = self.standing.verdict(names_of_items(st.doc))
        if why is not None:  # a tray stopped standing since it was asked: not this plan
            self._unplanned(why)
            return
        if final:
            st.mc_ms = (time.perf_counter() - st.mc_t0) * 1e3
        names = names_of(st.doc)
        drawing = plan_drawing(plan, tray_colours(req.scene), style_of(plan),
                               self.layer.actuated_joints(), self._locked, names)  # fmt: skip
        self.layer.show(drawing)
        if final:  # the engineer paused: full resolution again, after the plan's update
            self.draft.set(False)
        st.plan, st.error, st.drawn_seq, st.busy = plan, None, req.seq, not final
        st.last_ms = (time.perf_counter() - req.t0) * 1e3
        if plan.verified and not final:
            st.exact_ms = st.last_ms
        self.status.content = panel.plan_status(
            plan, final, req.seq, st.last_ms, st.exact_ms, st.mc_ms
        )
        self.summary.content = panel.summary(plan, final)
        self.stops_md.content = panel.stops_list(plan, names)
        self._tell()
        self._declutter()
        if final and order_ids(req.scene):
            self._mix_gen += 1
            args = (self._mix_gen, req.scene, self.options(MC_SAMPLES))
            threading.Thread(target=self._mix, args=args, daemon=True).start()

    def _mix(self, gen: int, doc: dict[str, Any], options: dict[str, Any]) -> None:
        """Every order planned on the layout drawn (on a thread): the mix's weighted figures
        in the panel, unless a newer plan has come meanwhile."""
        self.mix_md.content = "⏳ *mix of the orders…*"
        try:
            text = mix_summary(self.api.mix(doc, options))
        except ApiProblem as e:
            text = f"⚠ Mix: {e.title}: {e.detail}"
        if gen == self._mix_gen:
            self.mix_md.content = text

    def plan_failed(self, req: Request, problem: ApiProblem) -> None:
        with self._lock:
            self.state.error, self.state.busy = f"{problem.title}: {problem.detail}", False
        self.status.content = panel.failure_status(problem)
        self.summary.content = panel.failure_summary(problem)
        # The last valid plan stays on screen in one stale colour; its ghosts go.
        plan = self.state.plan
        if plan is not None:
            self.layer.show(plan_drawing(plan, tray_colours(req.scene), style_of(plan, True),
                                         names=names_of(self.state.doc)))  # fmt: skip
            self._declutter()
        else:
            self.layer.place_ghosts(None)
        self.draft.set(False)

    def success_rates_started(self, req: Request) -> None:
        self.state.mc_t0 = time.perf_counter()

    def success_rates_failed(self, req: Request, problem: ApiProblem) -> None:
        self.state.busy = False
        self.status.content = panel.success_rates_failed(self.status.content, problem)
        self.draft.set(False)

    # -- saving and exporting -------------------------------------------------------------------
    def _save(self) -> None:
        st = self.state
        with self._lock:
            why = self.standing.verdict(names_of_items(st.doc))
        if why is not None:
            self.saved.content = f"⚠ **Not saved:** a tray does not stand: {why}"
            self._notify(self.saved.content, error=True)
            return
        try:
            new = self.api.save_scene(st.stored.id, st.doc, st.stored.etag)
        except ApiProblem as e:
            self.saved.content = panel.save_problem(e)
            self._notify(self.saved.content, error=True)
            return
        with self._lock:
            st.stored, st.history = new, st.history.mark_saved()
            self._history_changed()
        self.saved.content = panel.scene_revision(new, saved=True)

    def _store_plan(self) -> str | None:
        """Store the plan of the document as it is now (once: the same document and options
        give the stored plan's id again) and link it in the panel."""
        st = self.state
        if st.plan is None:
            return None
        opts = self.options(MC_SAMPLES)
        doc = with_order(st.doc, self.order.value)
        key = json.dumps([doc, opts], sort_keys=True)
        if st.plan_id is not None and key == self._stored_key:
            return st.plan_id
        res = self.api.plan(doc, opts, store=True)
        st.plan_id, self._stored_key = res.id, key
        self.link.content = f"Plan in the REST API: [{res.id}]({self.api.plan_url(res.id or '')})"
        return res.id

    def _download(
        self, event: Any, name: Callable[[str], str], body: Callable[[str], bytes]
    ) -> None:
        """Store the plan, then send ``body(plan_id)`` as the file ``name(plan_id)``."""
        if event.client is None:
            return
        try:
            pid = self._store_plan()
            if pid is None:
                self._notify("No plan to download yet.", error=True)
                return
            data = body(pid)
        except ApiProblem as e:
            self._notify(f"{e.title}: {e.detail}", error=True)
            return
        event.client.send_file_download(name(pid), data, save_immediately=True)

    def _download_report(self, event: Any) -> None:
        self._download(event, lambda pid: f"pickstop-report-{pid}.html", self.api.report)

    def _download_stops(self, event: Any) -> None:
        self._download(event, lambda pid: f"pickstop-stops-{pid}.csv", self.api.stops_csv)

    def _export(self, event: Any) -> None:
        plan = self.state.plan
        body = json.dumps(plan.model_dump(mode="json"), indent=1).encode() if plan else b""
        self._download(event, lambda _: "plan.json", lambda _: body)

    def _snapshot(self, event: Any) -> None:
        """The 3D view without gizmos, under a title, beside the figures and a legend."""
        with self._helpers_hidden():
            img = event.client.get_render(height=RENDER[1], width=RENDER[0],
                                          transport_format="png")  # fmt: skip
        st = self.state
        title = f"PickStop: {st.doc.get('name') or st.stored.id}"
        body = compose_png(np.asarray(img), title, figure_lines(st.plan))
        event.client.send_file_download("pickstop.png", body, save_immediately=True)

    @contextlib.contextmanager
    def _helpers_hidden(self) -> Iterator[None]:
        """The gizmo and other helpers hidden (an export shows the layout only)."""
        shown = self.selection.gizmo.visible
        self.selection.gizmo.visible = False
        self.measure.hide_all(True)
        try:
            yield
        finally:
            self.selection.gizmo.visible = shown and self.selection.key is not None
            self.measure.hide_all(False)

    def _play(self) -> None:
        """Play the route on a thread (a second click while it plays does nothing)."""
        if not self._playing.acquire(blocking=False):
            return
        self.play_btn.disabled = True

        def play() -> None:
            try:
                self._playback()
            finally:
                self.play_btn.disabled = False
                self._playing.release()

        threading.Thread(target=play, daemon=True).start()

    def _playback(self, rest: float = 1.0) -> None:
        """Drive the robot along the route in its travel posture, reaching for each part at
        each stop (:func:`playback`); after ``rest`` [s] at the goal, back to the start."""
        plan, robot = self.state.plan, self.robot
        if plan is None or robot is None or getattr(self, "_robot", None) is None:
            return
        frame = self._robot_frame
        for step in playback(plan, robot.travel_theta(plan.joints)):
            frame.position, frame.wxyz = (step.x, step.y, 0.0), yaw_quat(step.yaw)
            if step.theta is not None:
                self._robot_pose(plan.joints, step.theta)
            time.sleep(step.hold)
        time.sleep(rest)
        with self._lock:
            x, y, yaw = (float(self.state.doc["start"].get(k, 0.0)) for k in ("x", "y", "yaw"))
        frame.position, frame.wxyz = (x, y, 0.0), yaw_quat(yaw)


def run(
    api_url: str,
    scene_id: str,
    api_key: str | None,
    host: str,
    port: int,
    flat_lighting: bool = True,
    draft_scale: float | None = None,
) -> PlannerApp:
    """The planner of a stored scene; ``draft_scale`` None: :data:`DRAFT_SCALE`."""
    client = PickStopClient(api_url, api_key)
    return PlannerApp(
        client, scene_id, host=host, port=port, flat_lighting=flat_lighting,
        draft_scale=DRAFT_SCALE if draft_scale is None else draft_scale,
    )  # fmt: skip

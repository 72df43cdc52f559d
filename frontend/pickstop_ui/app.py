"""The 3D planner: a viser application over the REST API.

The scene (tables, trays with parts, obstacles, start and goal, the robot) is drawn from the
stored scene; trays and obstacles are dragged on the floor (x, y and yaw only). Every change of
sigma, rule, task or layout asks the API for a new plan (not stored) and draws it: each tray's
base region as a translucent patch in its colour, the intersections' outlines, the inscribed
circles (dashed red where sigma rejects them, with the reason), the chosen stops with a ghost
robot in its witness configuration, and the route with its direction. A quick plan without
Monte Carlo is drawn first, then the success rates follow.

While a tray or an obstacle is being dragged, previews follow it (known regions carried with
the tray, nothing verified), drawn in the preview style (:mod:`pickstop_ui.plan_view`) and
said so in the panel; the exact plan replaces the preview on release. Drawings update the
existing scene nodes in place (:mod:`pickstop_ui.plan_layer`).
"""

from __future__ import annotations

import copy
import io
import json
import logging
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import viser

from pickstop.frames import quat_yaw, yaw_quat
from pickstop.sequence.plan_model import Plan
from pickstop_ui import edits
from pickstop_ui.client import ApiProblem, PickStopClient, StoredScene
from pickstop_ui.geometry import (
    polyline_at,
    tilt_quat,
    tray_boxes,
)
from pickstop_ui.plan_layer import PlanLayer
from pickstop_ui.plan_view import joint_cfg, plan_drawing, status_line, style_of
from pickstop_ui.robot_model import fetch_robot, scene_robot_name

log = logging.getLogger("pickstop.ui")

#: The sigma slider's range ends here [m]: the widest stops of the example scenes reach
#: about 0.3 m, and a layout beyond this is infeasible for any real base.
SIGMA_MAX = 0.5

PALETTE = [
    (230, 25, 75),
    (60, 180, 75),
    (0, 130, 200),
    (245, 130, 48),
    (145, 30, 180),
    (70, 240, 240),
    (240, 50, 230),
    (210, 245, 60),
    (0, 128, 128),
    (170, 110, 40),
    (128, 0, 0),
    (0, 0, 128),
]
MC_SAMPLES = 300
MC_QUIET = 0.4  # [s] without a newer request before the Monte Carlo starts


def tray_colour(index: int, tray: dict[str, Any]) -> tuple[int, int, int]:
    c = tray.get("color")
    if isinstance(c, str) and c.startswith("#") and len(c) == 7:
        return (int(c[1:3], 16), int(c[3:5], 16), int(c[5:7], 16))
    return PALETTE[index % len(PALETTE)]


@dataclass
class _Request:
    seq: int
    scene: dict[str, Any]
    options: dict[str, Any]
    t0: float
    cause: str
    preview: bool = False  # a drag is under way: a quick unverified plan


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
    busy: bool = False
    dirty: bool = False  # edited since the last save
    history: list[dict[str, Any]] = field(default_factory=list)


class PlannerApp:
    def __init__(
        self,
        client: PickStopClient,
        scene_id: str,
        host: str = "127.0.0.1",
        port: int = 8080,
        draw_robot: bool = True,
    ) -> None:
        self.api = client
        stored = client.scene(scene_id)
        # The scene's own robot, from the API (URDF, meshes, locked and pre-grasp joints).
        robot = fetch_robot(client, scene_robot_name(stored.doc)) if draw_robot else None
        self.state = PlannerState(stored, copy.deepcopy(stored.doc))
        self.server = viser.ViserServer(host=host, port=port, label="PickStop", verbose=False)
        self.port = self.server.get_port()
        self._lock = threading.Lock()
        self._pending: _Request | None = None
        self._wake = threading.Event()
        self._stop = False
        self.robot = robot
        self._urdf = robot.urdf if robot is not None else None
        self._locked = robot.joint_values if robot is not None else {}
        self._tray_ui: dict[str, Any] = {}
        self._draw_scene()
        self.layer = PlanLayer(self.server, self._urdf)
        self._urdf_joints: list[str] = []
        self._build_gui()
        self.server.on_client_connect(self._on_connect)
        self._worker = threading.Thread(target=self._plan_loop, name="pickstop-ui", daemon=True)
        self._worker.start()
        self.request("open")

    # -- lifecycle ---------------------------------------------------------------------------
    def close(self) -> None:
        self._stop = True
        self._wake.set()
        self.server.stop()

    def _on_connect(self, client: viser.ClientHandle) -> None:
        fl = self.state.doc["floor"]
        cx = 0.5 * (fl["min"][0] + fl["max"][0])
        cy = 0.5 * (fl["min"][1] + fl["max"][1])
        span = max(fl["max"][0] - fl["min"][0], fl["max"][1] - fl["min"][1])
        client.camera.up_direction = (0.0, 0.0, 1.0)
        # The panel covers the right of the window: look a little right of the centre.
        client.camera.position = (cx + 0.12 * span, cy - 0.45 * span, 0.6 * span)
        client.camera.look_at = (cx + 0.12 * span, cy + 0.1 * span, 0.0)

    # -- the scene ---------------------------------------------------------------------------
    def _draw_scene(self) -> None:
        sc, doc = self.server.scene, self.state.doc
        fl = doc["floor"]
        w, h = fl["max"][0] - fl["min"][0], fl["max"][1] - fl["min"][1]
        sc.set_up_direction("+z")
        # No shadow pass: it doubles the cost of every frame in a browser without a GPU.
        sc.configure_default_lights(enabled=True, cast_shadow=False)
        sc.add_grid(
            "/floor",
            width=w,
            height=h,
            cell_size=0.5,
            position=(fl["min"][0] + w / 2, fl["min"][1] + h / 2, 0.0),
        )
        for ob in doc.get("obstacles", []):
            self._draw_obstacle(ob)
        for i, tray in enumerate(doc["trays"]):
            self._draw_tray(i, tray)
        for name in ("start", "goal"):
            p = doc[name]
            sc.add_icosphere(
                f"/{name}",
                radius=0.08,
                color=(30, 30, 30) if name == "start" else (250, 250, 250),
                position=(p["x"], p["y"], 0.08),
            )
            sc.add_label(f"/{name}/label", name, position=(0, 0, 0.2))
        if self._urdf is not None:
            from viser.extras import ViserUrdf

            s = doc["start"]
            sc.add_frame(
                "/robot",
                show_axes=False,
                position=(s["x"], s["y"], 0.0),
                wxyz=yaw_quat(s.get("yaw", 0.0)),
            )
            self._robot = ViserUrdf(self.server, self._urdf, root_node_name="/robot")

    def _draw_obstacle(self, ob: dict[str, Any]) -> None:
        sc, g, p = self.server.scene, ob["geometry"], ob["pose"]
        ctl = sc.add_transform_controls(
            f"/obstacles/{ob['id']}",
            scale=0.4,
            active_axes=(True, True, False),
            position=(p.get("x", 0.0), p.get("y", 0.0), p.get("z", 0.0)),
            wxyz=yaw_quat(p.get("yaw", 0.0)),
            depth_test=False,
            opacity=0.8,
        )
        if g["shape"] == "box":
            sx, sy, sz = g["size"]
            sc.add_box(
                f"/obstacles/{ob['id']}/body",
                dimensions=(sx, sy, sz),
                color=(120, 110, 100),
                position=(0, 0, sz / 2),
            )
        elif g["shape"] == "cylinder":
            sc.add_cylinder(
                f"/obstacles/{ob['id']}/body",
                radius=g["radius"],
                height=g["height"],
                color=(120, 110, 100),
                position=(0, 0, g["height"] / 2),
            )

        @ctl.on_update
        def _(event: Any) -> None:  # previews while dragging, the exact plan on release
            self._moved("obstacles", ob["id"], ctl, final=event.phase == "end")

    def _draw_tray(self, index: int, tray: dict[str, Any]) -> None:
        sc, p = self.server.scene, tray["pose"]
        colour = tray_colour(index, tray)
        root = f"/trays/{tray['id']}"
        ctl = sc.add_transform_controls(
            root,
            scale=0.3,
            active_axes=(True, True, False),
            depth_test=False,
            position=(p.get("x", 0.0), p.get("y", 0.0), p.get("z", 0.0)),
            wxyz=yaw_quat(p.get("yaw", 0.0)),
        )
        # Floor, walls and parts hang below a frame turned by the tray's tilt (a flow rack's
        # slanted shelf), so they lie as the backend checks them.
        body = f"{root}/body"
        sc.add_frame(body, show_axes=False, wxyz=tilt_quat(tray.get("tilt")))
        for name, dims, centre in tray_boxes(tray):
            sc.add_box(f"{body}/{name}", dimensions=dims, color=colour, position=centre)
        for part in tray.get("parts", []):
            g, pp = part["geometry"], part.get("pose", {})
            pos = (pp.get("x", 0.0), pp.get("y", 0.0), pp.get("z", 0.0))
            name = f"{body}/parts/{part['id']}"
            if g["shape"] == "box":
                sc.add_box(
                    name,
                    dimensions=tuple(g["size"]),
                    color=(200, 200, 210),
                    position=(pos[0], pos[1], pos[2] + g["size"][2] / 2),
                    wxyz=yaw_quat(pp.get("yaw", 0.0)),
                )
            elif g["shape"] == "cylinder":
                sc.add_cylinder(
                    name,
                    radius=g["radius"],
                    height=g["height"],
                    color=(200, 200, 210),
                    position=(pos[0], pos[1], pos[2] + g["height"] / 2),
                )
        above = tray.get("wall_height", 0.06) + 0.09
        sc.add_label(f"{root}/label", tray.get("name") or tray["id"], position=(0, 0, above))

        @ctl.on_update
        def _(event: Any) -> None:
            self._moved("trays", tray["id"], ctl, final=event.phase == "end")

    def _moved(self, kind: str, oid: str, ctl: Any, final: bool = True) -> None:
        """The gizmo moved: keep x, y (a tray's in whole base cells) and yaw, the height as it
        was; a preview while the drag goes on, the exact plan when it ends."""
        x, y, yaw = float(ctl.position[0]), float(ctl.position[1]), quat_yaw(ctl.wxyz)
        with self._lock:
            pose = edits.move(self.state.doc, kind, oid, x, y, yaw)
            self.state.dirty = True
        if pose is None:
            return
        if final:
            ctl.position = (pose["x"], pose["y"], pose.get("z", 0.0))
            ctl.wxyz = yaw_quat(pose["yaw"])
        self.request(f"moved {oid}" if final else f"dragging {oid}", preview=not final)

    def _redraw_layout(self) -> None:
        self.server.scene.reset()
        self.layer.forget()
        self._draw_scene()

    # -- the panel ---------------------------------------------------------------------------
    def _build_gui(self) -> None:
        gui, doc = self.server.gui, self.state.doc
        gui.configure_theme(control_width="large", dark_mode=False, show_logo=False)
        self.status = gui.add_markdown("**Status:** loading")
        self.summary = gui.add_markdown("")
        with gui.add_folder("Planning"):
            self.sigma = gui.add_slider(
                "sigma [m]",
                min=0.0,
                max=SIGMA_MAX,
                step=0.005,
                initial_value=float(doc.get("sigma", 0.1)),
            )
            self.rule = gui.add_dropdown("rule", ("sigma", "success"), initial_value="sigma")
            self.target = gui.add_slider(
                "target success", min=0.6, max=0.99, step=0.01, initial_value=0.95
            )
            self.objective = gui.add_dropdown("objective", ("stops", "time"), initial_value="stops")
            # The robots stand on their stops' circles; hide them to see the circles whole.
            self.show_robots = gui.add_checkbox("robots at stops", True)
            self.show_robots.on_update(lambda _: self.layer.ghosts_visible(self.show_robots.value))

        for h in (self.sigma, self.rule, self.target, self.objective):
            h.on_update(self._changed)
        self.trays_folder = gui.add_folder("Trays")
        self._build_tray_gui()
        with gui.add_folder("Scene"):
            self.save = gui.add_button("Save scene")
            self.save.on_click(lambda _: self._save())
            self.saved = gui.add_markdown(
                f"Scene `{self.state.stored.id}`, revision {self.state.stored.revision}"
            )
        with gui.add_folder("Plan"):
            self.play = gui.add_button("Play route")
            self.play.on_click(self._play_clicked)
            self.export = gui.add_button("Download plan JSON")
            self.export.on_click(self._export)
            self.snap = gui.add_button("Download PNG snapshot")
            self.snap.on_click(self._snapshot)
            self.link = gui.add_markdown("")
        from pickstop_ui.fleet_view import FleetView

        self.fleet = FleetView(self.server, self.api, self._store_plan)
        self.stops_md = gui.add_markdown("")

    def _play_clicked(self, _: Any) -> None:
        threading.Thread(target=self._playback, daemon=True).start()

    def _changed(self, event: Any) -> None:
        self.request(f"{event.target.label} changed")

    def _build_tray_gui(self) -> None:
        for h in self._tray_ui.values():
            h.remove()
        self._tray_ui = {}
        doc = self.state.doc
        task = set(doc.get("task") or [t["id"] for t in doc["trays"]])
        with self.trays_folder:
            for t in doc["trays"]:
                cb = self.server.gui.add_checkbox(f"needed: {t['id']}", t["id"] in task)
                cb.on_update(self._task_toggled)
                self._tray_ui[f"cb:{t['id']}"] = cb
            ids = tuple(t["id"] for t in doc["trays"])
            sel = self.server.gui.add_dropdown("tray", ids, initial_value=ids[0])
            name = self.server.gui.add_text("name", doc["trays"][0].get("name", ""))
            sel.on_update(lambda _: setattr(name, "value", self._tray(sel.value).get("name", "")))
            rename = self.server.gui.add_button("Rename")
            add = self.server.gui.add_button("Add a copy")
            remove = self.server.gui.add_button("Remove")
            rename.on_click(lambda _: self._edit_tray("rename", sel.value, name.value))
            add.on_click(lambda _: self._edit_tray("add", sel.value, name.value))
            remove.on_click(lambda _: self._edit_tray("remove", sel.value, name.value))
            self._tray_ui.update(sel=sel, name=name, rename=rename, add=add, remove=remove)

    def _tray(self, tid: str) -> dict[str, Any]:
        return next(t for t in self.state.doc["trays"] if t["id"] == tid)

    def _task_toggled(self, event: Any) -> None:
        self._set_task(event.target.label.removeprefix("needed: "), bool(event.target.value))

    def _set_task(self, tid: str, needed: bool) -> None:
        with self._lock:
            doc = self.state.doc
            task = doc.get("task") or [t["id"] for t in doc["trays"]]
            task = [t for t in task if t != tid] + ([tid] if needed else [])
            doc["task"] = [t["id"] for t in doc["trays"] if t["id"] in task]
            self.state.dirty = True
        self.request(f"task {tid}")

    def _edit_tray(self, what: str, tid: str, name: str) -> None:
        with self._lock:
            doc = self.state.doc
            if what == "rename":
                self._tray(tid)["name"] = name
            elif what == "add":
                new = copy.deepcopy(self._tray(tid))
                k = 2
                while any(t["id"] == f"{tid}_{k}" for t in doc["trays"]):
                    k += 1
                new["id"], new["name"] = f"{tid}_{k}", f"{name or tid} {k}"
                new["pose"]["x"] = new["pose"].get("x", 0.0) + 0.5
                doc["trays"].append(new)
                if doc.get("task") is not None:
                    doc["task"].append(new["id"])
            elif what == "remove":
                if len(doc["trays"]) == 1:
                    self._notify("A scene needs at least one tray.")
                    return
                doc["trays"] = [t for t in doc["trays"] if t["id"] != tid]
                if doc.get("task") is not None:
                    doc["task"] = [t for t in doc["task"] if t != tid]
            self.state.dirty = True
        self._redraw_layout()
        self._build_tray_gui()
        self.request(f"{what} {tid}")

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
            "samples": samples,
        }

    def request(self, cause: str, preview: bool = False) -> None:
        """Plan the document as it is now; a newer request replaces a pending one, so while
        a plan is computed or drawn the frames in between are skipped."""
        with self._lock:
            self.state.seq += 1
            self._pending = _Request(
                self.state.seq,
                copy.deepcopy(self.state.doc),
                self.options(0),
                time.perf_counter(),
                cause,
                preview,
            )
            self.state.busy = True
        if not preview:
            self.status.content = f"**Status:** ⏳ exact plan… ({cause})"
        self._wake.set()

    def _plan_loop(self) -> None:
        while not self._stop:
            self._wake.wait()
            self._wake.clear()
            with self._lock:
                req, self._pending = self._pending, None
            if req is None or self._stop:
                continue
            try:
                res = self.api.plan(req.scene, req.options, preview=req.preview)
            except ApiProblem as e:
                self._failed(req, e)
                continue
            except Exception as e:  # the API is down or answered nonsense
                self._failed(req, ApiProblem(0, "API unreachable", str(e)))
                continue
            if self._newer(req):
                continue
            self._draw_plan(req, res.plan, final=False)
            if req.preview:
                continue
            # Then the success rates (Monte Carlo), once the engineer has paused: while a
            # slider or a tray is still moving, a running Monte Carlo would hold up the next
            # quick plan.
            if self._wake.wait(MC_QUIET) or self._newer(req):
                continue
            t_mc = time.perf_counter()
            self._panel_status(req, "plan drawn", "success rates (Monte Carlo)")
            try:
                mc = self.api.plan(req.scene, {**req.options, "samples": MC_SAMPLES})
            except ApiProblem:
                continue
            if not self._newer(req):
                self.state.mc_ms = (time.perf_counter() - t_mc) * 1e3
                self._draw_plan(req, mc.plan, final=True)

    def _newer(self, req: _Request) -> bool:
        with self._lock:
            return self._pending is not None or self.state.seq != req.seq

    def _failed(self, req: _Request, e: ApiProblem) -> None:
        if self._newer(req):
            return
        with self._lock:
            self.state.error = f"{e.title}: {e.detail}"
            self.state.busy = False
        what = f" (field `{e.field}`)" if e.field else ""
        self.status.content = f"**Status:** ⚠ {e.title}{what}"
        self.summary.content = (
            f"**{e.title}.** {e.detail}\n\n*The last valid plan is shown greyed out.*"
        )
        self._grey_out()

    def _grey_out(self) -> None:
        """The last valid plan stays on screen in one stale colour; its ghosts go."""
        plan = self.state.plan
        if plan is not None:
            self.layer.show(plan_drawing(plan, self._colours(self.state.doc), style_of(plan, True)))
        else:
            self.layer.place_ghosts(None)

    # -- drawing a plan ------------------------------------------------------------------------
    def _colours(self, doc: dict[str, Any]) -> dict[str, tuple[int, int, int]]:
        return {t["id"]: tray_colour(i, t) for i, t in enumerate(doc["trays"])}

    def _draw_plan(self, req: _Request, plan: Plan, final: bool) -> None:
        joints = self._joint_names()
        drawing = plan_drawing(plan, self._colours(req.scene), style_of(plan), joints, self._locked)
        self.layer.show(drawing)
        self.state.plan, self.state.error, self.state.drawn_seq = plan, None, req.seq
        self.state.busy = not final
        self.state.last_ms = (time.perf_counter() - req.t0) * 1e3
        if plan.verified and not final:
            self.state.exact_ms = self.state.last_ms
        self._panel(plan, req, final)

    def _joint_names(self) -> list[str] | None:
        """The URDF's actuated joints (known once a ghost exists), None without a robot."""
        if self._urdf is None:
            return None
        if not self._urdf_joints:
            from viser.extras import ViserUrdf

            if not self.layer.ghosts:
                self.layer._add_ghost()
                self.layer.ghosts[0][0].visible = False
            ghost: ViserUrdf = self.layer.ghosts[0][1]
            self._urdf_joints = list(ghost.get_actuated_joint_names())
        return self._urdf_joints

    def _cfg(
        self,
        urdf: Any,
        joints: list[str],
        theta: list[float],
        hand: dict[str, float] | None = None,
    ) -> np.ndarray:
        """The URDF's actuated joint values for a witness (:func:`plan_view.joint_cfg`)."""
        return joint_cfg(list(urdf.get_actuated_joint_names()), joints, theta, hand, self._locked)

    def _panel_status(self, req: _Request, phase: str, busy: str | None) -> None:
        st = self.state
        self.status.content = status_line(phase, req.seq, st.last_ms, st.exact_ms, busy)

    def _panel(self, plan: Plan, req: _Request, final: bool) -> None:
        t, n = plan.totals, plan.naive
        if not final:
            succ = "computing…"
        elif t.success is None or t.success_interval is None:
            succ = "—"
        else:
            lo, hi = t.success_interval
            succ = f"{t.success:.1%} (95% interval {lo:.1%} to {hi:.1%})"
        if not plan.verified:
            succ = "— (preview)"
            phase = "preview (not verified)"
        else:
            phase = "ready" if final else "plan drawn"
        mc = f" · last Monte Carlo {self.state.mc_ms:.0f} ms" if self.state.mc_ms else ""
        busy = None if final or not plan.verified else "success rates (Monte Carlo)"
        self._panel_status(req, phase, busy)
        if final:
            self.status.content += mc
        rejected = [c for c in plan.candidates if c.status == "rejected"]
        head = (
            ["**PREVIEW — not verified:** regions carried with the moved tray; the exact plan "
             "follows on release.", ""]
            if not plan.verified
            else []
        )  # fmt: skip
        self.summary.content = "\n".join(
            [
                *head,
                f"**σ = {plan.parameters.sigma:.3f} m**, rule *{plan.parameters.rule}*",
                f"- Stops: **{t.stops}** (naive {len(n.stops)})",
                f"- Route: **{t.route_length:.2f} m**",
                f"- Time: **{t.time.total:.1f} s** (naive {n.time.total:.1f} s, saving "
                f"**{n.saving_fraction:.1%}**)",
                f"- Success: {succ}",
                f"- Candidates: {len(plan.candidates)}, rejected {len(rejected)}",
            ]
        )
        lines = []
        for s in plan.stops:
            ok = "" if s.success is None else f" · {s.success.rate:.1%}"
            lines.append(
                f"{s.index + 1}. ({s.x:.2f}, {s.y:.2f}) → {', '.join(s.trays)} · "
                f"r = {s.inscribed_radius:.3f} m{ok}"
            )
        why = sorted({c.reason for c in rejected if c.reason})[:4]
        if why:
            lines.append("\n**Rejected candidates:**")
            lines += [f"- {w}" for w in why]
        self.stops_md.content = "**Stops**\n\n" + "\n".join(lines)

    # -- saving and exporting -------------------------------------------------------------------
    def _save(self) -> None:
        st = self.state
        try:
            new = self.api.save_scene(st.stored.id, st.doc, st.stored.etag)
        except ApiProblem as e:
            if e.status == 412:
                self.saved.content = (
                    "⚠ **Save conflict:** the scene was changed by someone "
                    "else since you opened it. Nothing was overwritten; reload "
                    "to see their version."
                )
            else:
                self.saved.content = f"⚠ **Not saved:** {e.title}: {e.detail}"
            self._notify(self.saved.content, error=True)
            return
        st.stored, st.dirty = new, False
        self.saved.content = f"Saved: scene `{new.id}`, revision {new.revision}"

    def _store_plan(self) -> str | None:
        st = self.state
        if st.plan is None:
            return None
        res = self.api.plan(st.doc, self.options(MC_SAMPLES), store=True)
        st.plan_id = res.id
        url = self.api.plan_url(res.id or "")
        self.link.content = f"Plan in the REST API: [{res.id}]({url})"
        return res.id

    def _export(self, event: Any) -> None:
        client = event.client
        try:
            self._store_plan()
        except ApiProblem as e:
            self._notify(f"{e.title}: {e.detail}", error=True)
            return
        if self.state.plan is not None:
            body = json.dumps(self.state.plan.model_dump(mode="json"), indent=1).encode()
            client.send_file_download("plan.json", body)

    def _snapshot(self, event: Any) -> None:
        client = event.client
        import imageio.v3 as iio

        img = client.get_render(height=720, width=1280, transport_format="png")
        buf = io.BytesIO()
        iio.imwrite(buf, img, extension=".png")
        client.send_file_download("pickstop.png", buf.getvalue())

    def _playback(self) -> None:
        """Drive the robot along the route and reach for each part at each stop."""
        plan, robot = self.state.plan, getattr(self, "_robot", None)
        if plan is None or robot is None:
            return
        frame = self.server.scene.add_frame("/robot", show_axes=False)
        speed, dt = 1.5, 1 / 30
        for k, leg in enumerate(plan.legs):
            line = np.asarray(leg.polyline)
            length = float(np.sum(np.hypot(*np.diff(line, axis=0).T))) if len(line) > 1 else 0.0
            s = 0.0
            while s <= length:
                p, heading = polyline_at(line, s)
                frame.position, frame.wxyz = (p[0], p[1], 0.0), yaw_quat(heading)
                s += speed * dt
                time.sleep(dt)
            if k < len(plan.stops):
                stop = plan.stops[k]
                frame.position, frame.wxyz = (stop.x, stop.y, 0.0), yaw_quat(stop.yaw)
                for w in stop.witnesses:
                    robot.update_cfg(self._cfg(robot, plan.joints, w.theta))
                    time.sleep(0.6)
                robot.update_cfg(self._cfg(robot, plan.joints, [0.0] * len(plan.joints)))


def run(api_url: str, scene_id: str, api_key: str | None, host: str, port: int) -> PlannerApp:
    client = PickStopClient(api_url, api_key)
    return PlannerApp(client, scene_id, host=host, port=port)

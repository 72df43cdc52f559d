"""*Suggest layout* in the planner: a layout job for the selected tray (or every tray the
orders need), its progress, the best suggestion as ghost trays with its gain, Accept / Dismiss.

The job is posted and followed on a thread of its own; *Cancel* stops it in the API. Accept
hands the suggestion's moved scene to the planner, which takes it as one undoable step.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

import viser

from pickstop.frames import yaw_quat
from pickstop_ui.client import ApiProblem
from pickstop_ui.layout_view import Ghost, best, gain_text, ghosts, layout_body, parse_turns

log = logging.getLogger("pickstop.ui")

POLL = 0.25  # [s] between looks at the job
GHOST = (120, 120, 255)


class Suggester:
    """The *Layout* folder and its job. ``request()`` gives (document copy, movable trays or
    None, plan options); ``accept(scene, label)`` applies a moved scene as one step."""

    def __init__(
        self,
        server: viser.ViserServer,
        client: Any,
        request: Callable[[], tuple[dict[str, Any], list[str] | None, dict[str, Any]]],
        accept: Callable[[dict[str, Any], str], None],
    ) -> None:
        self.server, self.client, self._request, self._accept = server, client, request, accept
        self.job_id: str | None = None
        self.layout: dict[str, Any] | None = None
        self._ghosts: dict[str, Any] = {}
        self._gen = 0  # bumped by every new ask or dismiss: older threads stop drawing
        gui = server.gui
        with gui.add_folder("Layout"):
            self.step = gui.add_number("slot step [m]", 0.1, min=0.025, max=1.0, step=0.005)
            self.turns = gui.add_text("turns [°]", "0, 90, 180, 270")
            self.shortlist = gui.add_number("shortlist", 12, min=1, max=64, step=1)
            self.samples = gui.add_number(
                "samples", 300, min=0, max=20000, step=50,
                hint="Monte Carlo samples of the verified plans",
            )  # fmt: skip
            self.ask_btn = gui.add_button("Suggest layout", icon=viser.Icon.BULB)
            self.cancel_btn = gui.add_button("Cancel search", icon=viser.Icon.X, disabled=True)
            self.progress = gui.add_progress_bar(0.0, visible=False)
            self.text = gui.add_markdown("")
            self.accept_btn = gui.add_button("Accept", icon=viser.Icon.CHECK, disabled=True)
            self.dismiss_btn = gui.add_button("Dismiss", icon=viser.Icon.X, disabled=True)
        self.ask_btn.on_click(lambda _: self.ask())
        self.cancel_btn.on_click(lambda _: self.cancel())
        self.accept_btn.on_click(lambda _: self.accept())
        self.dismiss_btn.on_click(lambda _: self.dismiss())

    def ask(self) -> None:
        """Post the job for the document as it is now; followed on a thread."""
        try:
            turns = parse_turns(self.turns.value)
        except ValueError as e:
            self.text.content = f"⚠ {e}"
            return
        doc, movable, options = self._request()
        options = {**options, "samples": int(self.samples.value)}
        body = layout_body(doc, movable, options, float(self.step.value), turns,
                           int(self.shortlist.value))  # fmt: skip
        self.dismiss()
        gen = self._gen
        what = ", ".join(movable) if movable else "the orders' trays"
        self.text.content = f"⏳ Searching where {what} could go…"
        self.ask_btn.disabled, self.cancel_btn.disabled = True, False
        self.progress.value, self.progress.visible = 0.0, True
        threading.Thread(target=self._follow, args=(gen, body), daemon=True,
                         name="pickstop-layout").start()  # fmt: skip

    def _follow(self, gen: int, body: dict[str, Any]) -> None:
        try:
            job = self.client.submit_layout(body)
            self.job_id = job["id"]
            while job["state"] in ("queued", "running") and gen == self._gen:
                time.sleep(POLL)
                job = self.client.job(job["id"])
                self.progress.value = round(100 * float(job["progress"]), 1)
        except ApiProblem as e:
            self._finish(gen, None, f"⚠ {e.title}: {e.detail}")
            return
        except Exception as e:  # the API is down or answered nonsense
            self._finish(gen, None, f"⚠ API unreachable: {e}")
            return
        if job["state"] != "done":
            self._finish(gen, None, f"Search {job['state']}. {job.get('error') or ''}".strip())
            return
        self._finish(gen, job["result"], gain_text(job["result"]))

    def _finish(self, gen: int, layout: dict[str, Any] | None, text: str) -> None:
        if gen != self._gen:
            return
        self.job_id = None
        self.ask_btn.disabled, self.cancel_btn.disabled = False, True
        self.progress.visible = False
        self.text.content = text
        s = None if layout is None else best(layout)
        self.layout = layout if s is not None else None
        if s is not None:
            self._show(ghosts(s))
            self.accept_btn.disabled = self.dismiss_btn.disabled = False

    def cancel(self) -> None:
        job = self.job_id
        self._gen += 1
        if job is not None:
            try:
                self.client.cancel_job(job)
            except ApiProblem as e:
                log.info("cancel of layout job %s: %s", job, e)
        self.job_id = None
        self.ask_btn.disabled, self.cancel_btn.disabled = False, True
        self.progress.visible = False
        self.text.content = "Search cancelled."

    def _show(self, gs: list[Ghost]) -> None:
        """Ghost boxes at the suggested poses (nodes made once per tray, then moved)."""
        with self.server.atomic():
            for g in gs:
                h = self._ghosts.get(g.tray)
                if h is None:
                    h = self._ghosts[g.tray] = self.server.scene.add_box(
                        f"/suggestion/{g.tray}", dimensions=g.size, color=GHOST, opacity=0.4,
                        cast_shadow=False, receive_shadow=False,
                    )  # fmt: skip
                h.dimensions, h.position, h.wxyz = g.size, g.centre, yaw_quat(g.yaw)
                h.visible = True
            for tid, h in self._ghosts.items():
                if tid not in {g.tray for g in gs}:
                    h.visible = False

    def dismiss(self) -> None:
        """Forget the suggestion shown (a search under way goes on, unseen: cancel stops it)."""
        self._gen += 1
        self.layout = None
        for h in self._ghosts.values():
            h.visible = False
        self.accept_btn.disabled = self.dismiss_btn.disabled = True
        self.text.content = ""

    def accept(self) -> None:
        layout = self.layout
        s = None if layout is None else best(layout)
        if s is None:
            return
        label = "layout " + ", ".join(m["tray"] for m in s["moves"])
        self.dismiss()
        self._accept(s["scene"], label)

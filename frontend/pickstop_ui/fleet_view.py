"""The planner's fleet panel: dispatch the plan through the API and follow the job live, the
vehicle's position on the floor and each stop's status (pending, running, finished, failed)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from pickstop_ui.client import ApiProblem, PickStopClient

POLL = 0.5  # [s] between job reads
COLOURS = {
    "pending": (170, 170, 170),
    "running": (255, 190, 0),
    "finished": (40, 170, 70),
    "failed": (220, 40, 40),
}
END = ("done", "failed", "cancelled", "interrupted")


def panel(job: dict[str, Any]) -> str:
    """The job as markdown: state, nodes reached, picks, each stop's status and failures."""
    s = job.get("result") or {}
    lines = [f"**Dispatch** `{job['id']}`: {job['state']}"]
    if job.get("error"):
        lines.append(f"⚠ {job['error']}")
    if s:
        lines.append(
            f"nodes reached {s['nodes_reached']}/{s['nodes']}, picks finished "
            f"{s['actions_finished']}/{s['actions']}, failed {s['actions_failed']}"
        )
        for k, st in enumerate(s["stops"]):
            lines.append(f"- stop {k} ({st['node_id']}): **{st['status']}**")
            lines += [f"  - {f['result']}" for f in st["failed"]]
    return "\n".join(lines)


class FleetView:
    def __init__(
        self, server: Any, api: PickStopClient, store_plan: Callable[[], str | None]
    ) -> None:
        self.server, self.api, self.store_plan = server, api, store_plan
        gui = server.gui
        with gui.add_folder("Fleet"):
            self.serial = gui.add_text("vehicle serial", "sim-1")
            self.go = gui.add_button("Dispatch plan")
            self.follow_id = gui.add_text("follow job", "")
            self.md = gui.add_markdown("")
        self.go.on_click(lambda _: threading.Thread(target=self._dispatch, daemon=True).start())
        self.follow_id.on_update(lambda _: self.follow(self.follow_id.value.strip()))
        self.vehicle: Any = None
        self.stops: dict[str, Any] = {}
        self.job: dict[str, Any] | None = None
        self._following: str | None = None

    def _dispatch(self) -> None:
        try:
            plan_id = self.store_plan()
            if plan_id is None:
                self.md.content = "No plan to dispatch yet."
                return
            job = self.api.dispatch(plan_id, {"serial_number": self.serial.value})
        except ApiProblem as e:
            self.md.content = f"⚠ {e.title}: {e.detail}"
            return
        self.follow(job["id"])

    def follow(self, job_id: str) -> None:
        """Poll the job until it ends, showing each read."""
        if not job_id or job_id == self._following:
            return
        self._following = job_id
        threading.Thread(target=self._poll, args=(job_id,), daemon=True).start()

    def _poll(self, job_id: str) -> None:
        while self._following == job_id:
            try:
                job = self.api.job(job_id)
            except ApiProblem as e:
                self.md.content = f"⚠ {e.title}: {e.detail}"
                return
            self.show(job)
            if job["state"] in END:
                return
            time.sleep(POLL)

    def show(self, job: dict[str, Any]) -> None:
        """Draw one read of the job: the vehicle, the stops' colours, the panel."""
        self.job = job
        sc = self.server.scene
        s = job.get("result") or {}
        pos = s.get("position")
        if pos is not None:
            if self.vehicle is None:
                self.vehicle = sc.add_icosphere(
                    "/fleet/vehicle", radius=0.12, color=(30, 110, 230), position=(0, 0, 0.12)
                )
            self.vehicle.position = (pos["x"], pos["y"], 0.12)
        for st in s.get("stops", []):
            if st.get("x") is None:
                continue
            h = self.stops.get(st["node_id"])
            colour = COLOURS.get(st["status"], COLOURS["pending"])
            if h is None or h.color != colour:
                if h is not None:
                    h.remove()
                h = self.stops[st["node_id"]] = sc.add_icosphere(
                    f"/fleet/stops/{st['node_id']}",
                    radius=0.06,
                    color=colour,
                    position=(st["x"], st["y"], 0.02),
                )
        self.md.content = panel(job)

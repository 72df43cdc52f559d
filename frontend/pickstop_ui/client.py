"""A typed client of the PickStop REST API (the 3D planner is one more client of it)."""

from __future__ import annotations

import asyncio
import threading
from dataclasses import dataclass
from typing import Any

import httpx

from pickstop.sequence.plan_model import Plan

API = "/api/v1"
CANCEL_POLL = 0.01  # [s] between looks at a cancellable request's event


class ApiProblem(Exception):
    """An error answer of the API (RFC 9457 problem details)."""

    def __init__(self, status: int, title: str, detail: str, field: str | None = None) -> None:
        super().__init__(f"{title}: {detail}")
        self.status, self.title, self.detail, self.field = status, title, detail, field


class RequestCancelled(Exception):
    """A cancellable request was given up before its answer came (its connection closed)."""


@dataclass(frozen=True)
class StoredScene:
    id: str
    etag: str
    revision: int
    doc: dict[str, Any]


@dataclass(frozen=True)
class PlanResult:
    plan: Plan
    id: str | None  # stored plan id, or None for a preview
    seconds: float  # round trip [s]


class StaleConnectionRetry(httpx.HTTPTransport):
    """Sends a request once more, on a new connection, when a kept-alive one turns out to be
    closed before any response came: the API ends an idle connection (uvicorn after 5 s) and
    the pool may hand it out at that moment ("Server disconnected without sending a
    response"). A request that got any answer is never sent twice."""

    def handle_request(self, request: httpx.Request) -> httpx.Response:
        try:
            return super().handle_request(request)
        except httpx.RemoteProtocolError as e:
            if "without sending a response" not in str(e):
                raise
            return super().handle_request(request)


class PickStopClient:
    def __init__(self, base_url: str, api_key: str | None = None, timeout: float = 300) -> None:
        self.base_url = base_url.rstrip("/")
        headers = {"Authorization": f"Bearer {api_key}"} if api_key else {}
        self.http = httpx.Client(base_url=self.base_url, headers=headers, timeout=timeout,
                                 transport=StaleConnectionRetry())  # fmt: skip

    def close(self) -> None:
        self.http.close()

    def _check(self, r: httpx.Response) -> httpx.Response:
        if r.status_code >= 400:
            try:
                body = r.json()
            except ValueError:
                body = {"title": r.reason_phrase, "detail": r.text[:500]}
            raise ApiProblem(
                r.status_code, body.get("title", "Error"), body.get("detail", ""), body.get("field")
            )
        return r

    def health(self) -> dict[str, Any]:
        return dict(self._check(self.http.get(f"{API}/health")).json())

    def robot_model(self, name: str) -> dict[str, Any]:
        """A robot's URDF (mesh references ``files/<id>``), arm joints and joint values."""
        return dict(self._check(self.http.get(f"{API}/robots/{name}/model")).json())

    def robot_file(self, name: str, file_id: str) -> bytes:
        """One mesh file of a robot's model."""
        return self._check(self.http.get(f"{API}/robots/{name}/files/{file_id}")).content

    def scene(self, scene_id: str) -> StoredScene:
        r = self._check(self.http.get(f"{API}/scenes/{scene_id}"))
        body = r.json()
        return StoredScene(body["id"], _etag(r), body["revision"], body["scene"])

    def create_scene(self, doc: dict[str, Any]) -> StoredScene:
        r = self._check(self.http.post(f"{API}/scenes", json=doc))
        body = r.json()
        return StoredScene(body["id"], _etag(r), body["revision"], body["scene"])

    def placement(
        self, scene: dict[str, Any], tray: str, x: float, y: float, yaw: float,
        z_hint: float | None = None,
    ) -> dict[str, Any]:  # fmt: skip
        """Where ``tray`` of an inline scene would stand with its footprint at ``(x, y)`` [m]
        turned to ``yaw`` [rad] (``POST /placements``): the support under it, its top and the
        pose height that rests the tray there [m], whether it stands free and why not."""
        body = {"scene": scene, "tray": tray, "x": x, "y": y, "yaw": yaw, "z_hint": z_hint}
        return dict(self._check(self.http.post(f"{API}/placements", json=body)).json())

    def copy_tray(self, scene: dict[str, Any], tray: str) -> dict[str, Any] | None:
        """A copy of ``tray`` on the nearest free spot of the support it stands on, as a tray
        document with new ids (None: that support has no free spot)."""
        r = self._check(self.http.post(f"{API}/placements/copy", json={"scene": scene,
                                                                        "tray": tray}))  # fmt: skip
        tray_doc = r.json()["tray"]
        return None if tray_doc is None else dict(tray_doc)

    def save_scene(self, scene_id: str, doc: dict[str, Any], etag: str) -> StoredScene:
        """Replace the stored scene; ApiProblem 412 if someone changed it since ``etag``."""
        r = self._check(
            self.http.put(f"{API}/scenes/{scene_id}", json=doc, headers={"If-Match": f'"{etag}"'})
        )
        body = r.json()
        return StoredScene(body["id"], _etag(r), body["revision"], body["scene"])

    def delete_scene(self, scene_id: str, etag: str) -> None:
        """Delete the stored scene; ApiProblem 412 if someone changed it since ``etag`` (the
        API requires If-Match on every change, deletes included)."""
        self._check(self.http.delete(f"{API}/scenes/{scene_id}", headers={"If-Match": f'"{etag}"'}))

    def limits(self) -> dict[str, Any]:
        """What one request may ask for (trays, parts, samples, body size, deadlines)."""
        return dict(self._check(self.http.get(f"{API}/limits")).json())

    def plan(
        self,
        scene: dict[str, Any],
        options: dict[str, Any],
        store: bool = False,
        preview: bool = False,
        cancel: threading.Event | None = None,
    ) -> PlanResult:
        """Plan an inline scene document (not stored unless ``store``; ``preview``: the quick
        unverified plan drawn while a tray is dragged).

        cancel: when set before the answer, the request's connection is closed, which stops
        the computation in the API (it watches its clients), and :class:`RequestCancelled`
        is raised: a long Monte Carlo no longer holds up the next quick plan.
        """
        body: dict[str, Any] = {"scene": scene, "options": options, "store": store}
        if preview:
            body["mode"] = "preview"
        if cancel is None:
            r = self._check(self.http.post(f"{API}/plans", json=body))
        else:
            r = self._check(asyncio.run(self._cancellable_post(f"{API}/plans", body, cancel)))
        body = r.json()
        return PlanResult(Plan.model_validate(body["plan"]), body["id"], r.elapsed.total_seconds())

    async def _cancellable_post(
        self, url: str, body: dict[str, Any], cancel: threading.Event
    ) -> httpx.Response:
        """POST ``body`` on a connection of its own, closed as soon as ``cancel`` is set
        (cancelling an asyncio request closes its connection; a blocking one cannot be
        interrupted from another thread)."""
        async with httpx.AsyncClient(
            base_url=self.base_url, headers=self.http.headers, timeout=self.http.timeout
        ) as http:
            task = asyncio.ensure_future(http.post(url, json=body))
            while not task.done():
                await asyncio.wait({task}, timeout=CANCEL_POLL)
                if cancel.is_set() and not task.done():
                    task.cancel()
                    await asyncio.gather(task, return_exceptions=True)
                    raise RequestCancelled(f"POST {url} cancelled")
            return task.result()

    def mix(self, scene: dict[str, Any], options: dict[str, Any]) -> dict[str, Any]:
        """Every order of an inline scene planned on its layout (not stored): the mix document
        (``pickstop.mix``: weighted totals and each order's figures)."""
        body = {"scene": scene, "options": options, "orders": "scene", "store": False}
        return dict(self._check(self.http.post(f"{API}/plans", json=body)).json()["mix"])

    def guidance(
        self,
        scene: dict[str, Any],
        tray: str,
        sigma: float | None = None,
        cancel: threading.Event | None = None,
    ) -> dict[str, Any]:
        """Where ``tray`` of an inline scene could go: the API's GeoJSON zones (``POST
        /guidance``); ``cancel`` as in :meth:`plan`."""
        body: dict[str, Any] = {"scene": scene, "tray": tray}
        if sigma is not None:
            body["sigma"] = sigma
        if cancel is None:
            return dict(self._check(self.http.post(f"{API}/guidance", json=body)).json())
        r = asyncio.run(self._cancellable_post(f"{API}/guidance", body, cancel))
        return dict(self._check(r).json())

    def dispatch(self, plan_id: str, body: dict[str, Any]) -> dict[str, Any]:
        """Start a dispatch job of a stored plan (the service's MQTT broker)."""
        return dict(
            self._check(self.http.post(f"{API}/plans/{plan_id}/dispatch", json=body)).json()
        )

    def submit_layout(self, body: dict[str, Any]) -> dict[str, Any]:
        """Start a layout search (``POST /layouts``): the job, checked and queued."""
        return dict(self._check(self.http.post(f"{API}/layouts", json=body)).json())

    def cancel_job(self, job_id: str) -> dict[str, Any]:
        return dict(self._check(self.http.post(f"{API}/jobs/{job_id}/cancel")).json())

    def job(self, job_id: str) -> dict[str, Any]:
        return dict(self._check(self.http.get(f"{API}/jobs/{job_id}")).json())

    def report(self, plan_id: str) -> bytes:
        """A stored plan's report: one self-contained HTML page."""
        return self._check(self.http.get(f"{API}/plans/{plan_id}/report")).content

    def stops_csv(self, plan_id: str) -> bytes:
        """A stored plan's stops as CSV, one row per stop."""
        return self._check(self.http.get(f"{API}/plans/{plan_id}/stops.csv")).content

    def plan_url(self, plan_id: str) -> str:
        return f"{self.base_url}{API}/plans/{plan_id}"


def _etag(r: httpx.Response) -> str:
    return r.headers.get("etag", "").strip('"')

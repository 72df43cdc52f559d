"""Placement guidance in the planner: zones fetched off the UI thread, drawn in place.

:class:`GuidanceFetcher` asks the API (``POST /guidance``) on a thread of its own for the
newest request only; a newer request or :meth:`GuidanceFetcher.clear` cancels the one under
way (its connection is closed) and an answer that is no longer the newest is dropped.
:class:`GuidanceLayer` keeps one mesh node per kind of zone under ``/guidance`` and updates
their arrays in place (with a software renderer, adding and removing nodes is slow).
"""

from __future__ import annotations

import copy
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import viser

from pickstop_ui.client import ApiProblem, RequestCancelled
from pickstop_ui.guidance_view import COLOURS, KINDS, OPACITY, GuidanceDrawing
from pickstop_ui.plan_layer import _set

log = logging.getLogger("pickstop.ui")


@dataclass(frozen=True)
class GuidanceRequest:
    seq: int  # 1, 2, ... in the order of submission
    tray: str
    scene: dict[str, Any]  # a copy of the document as it was
    sigma: float  # [m]
    t0: float  # submitted at [s, perf_counter]


class GuidanceClient(Protocol):
    def guidance(
        self, scene: dict[str, Any], tray: str, sigma: float | None = None,
        cancel: threading.Event | None = None,
    ) -> dict[str, Any]: ...  # fmt: skip


#: Called on the fetcher's thread with the request and its guidance document (or the problem).
Sink = Callable[[GuidanceRequest, "dict[str, Any] | ApiProblem"], None]


class GuidanceFetcher:
    """One thread asking the API for the newest guidance request; ``sink`` gets each answer
    still the newest when it comes."""

    def __init__(self, client: GuidanceClient, sink: Sink) -> None:
        self.client, self.sink = client, sink
        self.seq = 0
        self.dropped = 0  # answers that came after a newer request or a clear
        self._lock = threading.Lock()
        self._pending: GuidanceRequest | None = None
        self._cancel: threading.Event | None = None
        self._wake = threading.Event()
        self._stop = False
        self._thread = threading.Thread(target=self._loop, name="pickstop-guidance", daemon=True)
        self._thread.start()

    def submit(self, scene: dict[str, Any], tray: str, sigma: float) -> GuidanceRequest:
        """Ask for ``tray``'s zones in ``scene`` (copied now) at ``sigma`` [m]."""
        with self._lock:
            self.seq += 1
            req = GuidanceRequest(self.seq, tray, copy.deepcopy(scene), sigma, time.perf_counter())
            self._pending = req
            if self._cancel is not None:
                self._cancel.set()
        self._wake.set()
        return req

    def clear(self) -> None:
        """Forget every request: none pending, the one under way cancelled, no answer drawn."""
        with self._lock:
            self.seq += 1
            self._pending = None
            if self._cancel is not None:
                self._cancel.set()

    def current(self, req: GuidanceRequest) -> bool:
        with self._lock:
            return req.seq == self.seq

    def close(self, timeout: float = 5.0) -> None:
        self._stop = True
        self.clear()
        self._wake.set()
        self._thread.join(timeout)

    def _loop(self) -> None:
        while not self._stop:
            self._wake.wait()
            self._wake.clear()
            with self._lock:
                req, self._pending = self._pending, None
                cancel = self._cancel = threading.Event()
            if req is None or self._stop:
                continue
            try:
                answer: dict[str, Any] | ApiProblem = self.client.guidance(
                    req.scene, req.tray, req.sigma, cancel=cancel
                )
            except RequestCancelled:
                self.dropped += 1
                continue
            except ApiProblem as e:
                answer = e
            except Exception as e:  # the API is down or answered nonsense
                answer = ApiProblem(0, "API unreachable", str(e))
            with self._lock:
                self._cancel = None
            if not self.current(req):
                self.dropped += 1
                continue
            try:
                self.sink(req, answer)
            except Exception:  # a drawing bug must not stop the fetcher
                log.exception("drawing guidance #%d failed", req.seq)


class GuidanceLayer:
    """Mesh nodes ``/guidance/<kind>``, made on first use, then updated in place."""

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self.nodes: dict[str, Any] = {}

    def show(self, d: GuidanceDrawing) -> None:
        with self.server.atomic():
            for kind in KINDS:
                v, f = d.meshes[kind]
                h = self.nodes.get(kind)
                if not len(f):
                    if h is not None:
                        _set(h, visible=False)
                    continue
                if h is None:
                    self.nodes[kind] = self.server.scene.add_mesh_simple(
                        f"/guidance/{kind}", v, f, color=COLOURS[kind], opacity=OPACITY,
                        side="double", cast_shadow=False, receive_shadow=False,
                    )  # fmt: skip
                else:
                    _set(h, vertices=v, faces=f, visible=True)

    def hide(self) -> None:
        for h in self.nodes.values():
            _set(h, visible=False)

    def visible(self) -> dict[str, bool]:
        """Which kinds are drawn now."""
        return {k: bool(h.visible) for k, h in self.nodes.items()}

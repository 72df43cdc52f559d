"""Where trays stand, asked of the API off the UI thread (``POST /placements``).

:class:`Placer` runs one thread. A drag asks for the newest pose only (a newer one replaces
a pose not yet asked); a release, a typed pose or a check after an undo is asked in its turn
and never dropped. Each answer goes to the sink on the placer's thread, with its request, as
the API's placement document or the problem that stands for it. The UI turns answers into
heights and reasons with :mod:`pickstop_ui.resting`.
"""

from __future__ import annotations

import collections
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal, Protocol

from pickstop_ui.client import ApiProblem

log = logging.getLogger("pickstop.ui")

Kind = Literal["drag", "commit", "check"]


@dataclass(frozen=True)
class Ask:
    """Where tray ``tray`` of ``scene`` (the document as the API is asked: every tray at a
    pose known to stand) would stand at ``(x, y)`` [m] turned to ``yaw`` [rad]; ``z_hint``
    its height now [m]. ``kind``: a drag under way, a pose to commit (a release, typed
    numbers), or a check of a tray's standing; ``gen`` the document's edit generation."""

    seq: int
    tray: str
    scene: dict[str, Any]
    x: float
    y: float
    yaw: float
    z_hint: float
    kind: Kind
    gen: int
    label: str = ""  # a commit's undo step
    t0: float = 0.0  # submitted at [s, perf_counter]


class PlacementClient(Protocol):
    def placement(
        self, scene: dict[str, Any], tray: str, x: float, y: float, yaw: float,
        z_hint: float | None = None,
    ) -> dict[str, Any]: ...  # fmt: skip


Sink = Callable[[Ask, "dict[str, Any] | ApiProblem"], None]


class Placer:
    """One thread asking the API where trays stand; ``sink`` gets every answer asked."""

    def __init__(self, client: PlacementClient, sink: Sink) -> None:
        self.client, self.sink = client, sink
        self.seq = 0
        self.replaced = 0  # drag poses replaced by a newer one before they were asked
        self._lock = threading.Lock()
        self._drag: Ask | None = None
        self._queue: collections.deque[Ask] = collections.deque()
        self._wake = threading.Event()
        self._stop = False
        self._thread = threading.Thread(target=self._loop, name="pickstop-placer", daemon=True)
        self._thread.start()

    def submit(self, tray: str, scene: dict[str, Any], x: float, y: float, yaw: float,
               z_hint: float, kind: Kind, gen: int, label: str = "") -> Ask:  # fmt: skip
        """Ask where ``tray`` would stand (``scene`` is not copied: hand a copy)."""
        with self._lock:
            self.seq += 1
            ask = Ask(self.seq, tray, scene, x, y, yaw, z_hint, kind, gen, label,
                      time.perf_counter())  # fmt: skip
            if kind != "check":  # a release ends the drag: its poses not yet asked go
                self.replaced += self._drag is not None
                self._drag = None
            if kind == "drag":
                self._drag = ask
            else:
                self._queue.append(ask)
        self._wake.set()
        return ask

    def idle(self) -> bool:
        """Nothing waits to be asked."""
        with self._lock:
            return self._drag is None and not self._queue

    def close(self, timeout: float = 5.0) -> None:
        self._stop = True
        self._wake.set()
        self._thread.join(timeout)

    def _next(self) -> Ask | None:
        with self._lock:
            if self._queue:
                return self._queue.popleft()
            ask, self._drag = self._drag, None
            return ask

    def _loop(self) -> None:
        while not self._stop:
            self._wake.wait()
            self._wake.clear()
            while not self._stop and (ask := self._next()) is not None:
                try:
                    answer: dict[str, Any] | ApiProblem = self.client.placement(
                        ask.scene, ask.tray, ask.x, ask.y, ask.yaw, ask.z_hint
                    )
                except ApiProblem as e:
                    answer = e
                except Exception as e:  # the API is down or answered nonsense
                    answer = ApiProblem(0, "API unreachable", str(e))
                try:
                    self.sink(ask, answer)
                except Exception:  # a drawing bug must not stop the placer
                    log.exception("placement #%d failed", ask.seq)

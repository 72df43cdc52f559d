"""The re-plan worker: asks the API for a plan of the latest request only, then its success rates.

Every change of the layout or the options submits a request; a newer request replaces one
that is still pending, so while a plan is computed the requests in between are skipped. A
quick plan (no Monte Carlo) is reported first; once no newer request has come for
``mc_quiet`` seconds the same plan with ``mc_samples`` Monte Carlo samples follows. A preview
(a drag under way) gets no Monte Carlo. A newer request cancels a Monte Carlo under way (its
connection is closed and the API stops it): the API computes one request at a time, so a
Monte Carlo at a new sigma (about a second) would otherwise hold up the next quick plan.

Asking, the Monte Carlo and drawing run on three threads, so the next request is on its way
to the API while a result is drawn or success rates are computed. Every result newer than
the screen is drawn, even when newer requests wait (during a drag that outpaces the API, a
result that waited for the newest would never come); a result not yet drawn when a newer
one arrives is skipped. A failure is told only while its request is the newest. The worker
talks to the API through ``client.plan`` and to the planner through a :class:`Sink`, so it
runs under test with fakes of both.
"""

from __future__ import annotations

import copy
import logging
import threading
import time
from dataclasses import dataclass
from typing import Any, Protocol

from pickstop.sequence.plan_model import Plan
from pickstop_ui.client import ApiProblem, PlanResult, RequestCancelled

log = logging.getLogger("pickstop.ui")

MC_SAMPLES = 300
MC_QUIET = 0.4  # [s] without a newer request before the Monte Carlo starts


@dataclass(frozen=True)
class Request:
    seq: int  # 1, 2, ... in the order of submission
    scene: dict[str, Any]  # a copy of the document as it was
    options: dict[str, Any]  # PlanOptions as JSON (samples 0: the quick plan)
    t0: float  # submitted at [s, perf_counter]
    cause: str  # what changed, for the panel
    preview: bool = False  # a drag is under way: a quick unverified plan


class PlanClient(Protocol):
    def plan(
        self, scene: dict[str, Any], options: dict[str, Any], store: bool = False,
        preview: bool = False, cancel: threading.Event | None = None,
    ) -> PlanResult: ...  # fmt: skip


class Sink(Protocol):
    """Where the worker's results go: the drawing thread calls every method one at a time,
    except :meth:`success_rates_started`, which the Monte Carlo's thread calls."""

    def plan_ready(self, req: Request, plan: Plan, final: bool) -> None:
        """A plan of ``req``: the quick one (``final`` False) or with its success rates."""

    def plan_failed(self, req: Request, problem: ApiProblem) -> None:
        """The API refused ``req`` or could not be reached."""

    def success_rates_started(self, req: Request) -> None:
        """The Monte Carlo of ``req`` is running."""

    def success_rates_failed(self, req: Request, problem: ApiProblem) -> None:
        """The Monte Carlo of ``req`` failed; its quick plan stays drawn."""


class Replanner:
    """Threads asking the API for the newest request, for its success rates, and drawing the
    newest result;
    ``lock`` guards the document the requests copy (the planner's, so an edit and a
    submission never interleave)."""

    def __init__(
        self,
        client: PlanClient,
        sink: Sink,
        lock: threading.Lock | None = None,
        mc_samples: int = MC_SAMPLES,
        mc_quiet: float = MC_QUIET,
    ) -> None:
        self.client, self.sink = client, sink
        self.lock = lock or threading.Lock()
        self.mc_samples, self.mc_quiet = mc_samples, mc_quiet
        self.seq = 0
        self._pending: Request | None = None
        self._wake = threading.Event()
        self._stop = False
        self._out: tuple[str, Request, Any] | None = None  # the newest result not yet drawn
        self._out_lock = threading.Lock()
        self._out_ready = threading.Event()
        self.skipped = 0  # results replaced before they were drawn
        self.drawn_seq = 0  # the newest request whose result was handed to the sink
        self._mc_req: Request | None = None  # the exact plan whose success rates come next
        self._mc_ready = threading.Event()
        self._mc_cancel: threading.Event | None = None  # set: drop the Monte Carlo under way
        self.cancelled = 0  # Monte Carlos cancelled by a newer request
        self._threads = [
            threading.Thread(target=self._loop, name="pickstop-replan-ask", daemon=True),
            threading.Thread(target=self._mc_loop, name="pickstop-replan-mc", daemon=True),
            threading.Thread(target=self._draw_loop, name="pickstop-replan-draw", daemon=True),
        ]
        for t in self._threads:
            t.start()

    def submit(
        self, doc: dict[str, Any], options: dict[str, Any], cause: str, preview: bool = False
    ) -> Request:
        """Plan ``doc`` (copied now, under the lock) with ``options``; replaces any pending
        request. Returns the request."""
        with self.lock:
            self.seq += 1
            req = Request(
                self.seq, copy.deepcopy(doc), dict(options), time.perf_counter(), cause, preview
            )
            self._pending = req
            if self._mc_cancel is not None:
                self._mc_cancel.set()
        self._wake.set()
        return req

    def newer(self, req: Request) -> bool:
        """Has a request come after ``req``?"""
        with self.lock:
            return self.newer_locked(req)

    def newer_locked(self, req: Request) -> bool:
        """:meth:`newer`, with ``lock`` held."""
        return self._pending is not None or self.seq != req.seq

    def close(self, timeout: float = 5.0) -> None:
        self._stop = True
        with self.lock:
            if self._mc_cancel is not None:
                self._mc_cancel.set()
        self._wake.set()
        self._out_ready.set()
        self._mc_ready.set()
        for t in self._threads:
            t.join(timeout)

    # -- the worker's thread ------------------------------------------------------------------
    def _loop(self) -> None:
        while not self._stop:
            self._wake.wait()
            self._wake.clear()
            with self.lock:
                req, self._pending = self._pending, None
            if req is None or self._stop:
                continue
            plan = self._ask(req, req.options, req.preview)
            if isinstance(plan, ApiProblem):
                if not self.newer(req):
                    self._post("failed", req, plan)
                continue
            self._post("quick", req, plan)
            if not req.preview:
                with self._out_lock:
                    self._mc_req = req
                self._mc_ready.set()

    # -- the Monte Carlo's thread ---------------------------------------------------------------
    def _mc_loop(self) -> None:
        """The success rates of the newest exact plan, once the engineer has paused: while a
        slider or a tray is still moving, a Monte Carlo would slow the next quick plan. On a
        thread of its own, so a request that comes while it runs is asked at once."""
        while not self._stop:
            self._mc_ready.wait()
            self._mc_ready.clear()
            with self._out_lock:
                req, self._mc_req = self._mc_req, None
            if req is None or self._stop or not self._quiet(req):
                continue
            cancel = threading.Event()
            with self.lock:
                if self.newer_locked(req):
                    continue
                self._mc_cancel = cancel
            self.sink.success_rates_started(req)
            mc = self._ask(req, {**req.options, "samples": self.mc_samples}, False, cancel)
            with self.lock:
                self._mc_cancel = None
            if mc is None:
                self.cancelled += 1
            elif not self.newer(req):
                self._post("mc failed" if isinstance(mc, ApiProblem) else "final", req, mc)

    def _quiet(self, req: Request) -> bool:
        """Wait ``mc_quiet`` seconds; False as soon as a request newer than ``req`` comes."""
        end = time.monotonic() + self.mc_quiet
        while time.monotonic() < end:
            if self.newer(req) or self._stop:
                return False
            time.sleep(min(0.02, self.mc_quiet))
        return not self.newer(req)

    def _post(self, kind: str, req: Request, payload: Any) -> None:
        """Hand a result to the drawing thread, replacing one it has not taken yet."""
        with self._out_lock:
            if self._out is not None:
                self.skipped += 1
            self._out = (kind, req, payload)
        self._out_ready.set()

    # -- the drawing thread -------------------------------------------------------------------
    def _draw_loop(self) -> None:
        while not self._stop:
            self._out_ready.wait()
            self._out_ready.clear()
            with self._out_lock:
                item, self._out = self._out, None
            if item is None or self._stop:
                continue
            kind, req, payload = item
            if req.seq < self.drawn_seq:  # an older request's answer, overtaken
                self.skipped += 1
                continue
            self.drawn_seq = req.seq
            try:
                if kind in ("quick", "final"):
                    self.sink.plan_ready(req, payload, final=kind == "final")
                elif kind == "failed":
                    self.sink.plan_failed(req, payload)
                else:
                    self.sink.success_rates_failed(req, payload)
            except Exception:  # a drawing bug must not stop the planner's updates
                log.exception("drawing plan #%d failed", req.seq)

    def _ask(
        self,
        req: Request,
        options: dict[str, Any],
        preview: bool,
        cancel: threading.Event | None = None,
    ) -> Plan | ApiProblem | None:
        """The API's plan, the problem that stands for it, or None once ``cancel`` was set."""
        try:
            if cancel is None:
                return self.client.plan(req.scene, options, preview=preview).plan
            return self.client.plan(req.scene, options, preview=preview, cancel=cancel).plan
        except RequestCancelled:
            return None
        except ApiProblem as e:
            problem = e
        except Exception as e:  # the API is down or answered nonsense
            problem = ApiProblem(0, "API unreachable", str(e))
        log.info("plan #%d: %s", req.seq, problem)
        return problem

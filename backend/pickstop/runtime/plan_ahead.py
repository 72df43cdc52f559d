"""When the planner works ahead of the requests: the plan-ahead policy.

Requests hold a planner's lock ahead of any background work (:meth:`PlanAhead.request`).
After a plan and :data:`QUIET` seconds without a newer request, the plans of the neighbouring
sigma bands and of the other objective are made in the background (their stop selections
kept), then every candidate's centre is checked, so that the next change of sigma (the 3D
planner's slider) finds its selection made and its stops checked. After a preview and
:data:`HOLD` seconds without a newer request, the previewed layout's exact plan is made, so
that the plan asked for when the drag ends finds it done.

What the planner does ahead (``StopPlanner.prefetch_selections``, ``prefetch_checks``,
``plan_ahead``) leaves only memo entries; this module decides when it runs and makes it give
way: it takes the lock only while no request waits (:class:`Yielding`), and it is given up
once a newer request came (``stale``).
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Executor
from typing import TYPE_CHECKING, Any

from pickstop.errors import PickStopError

if TYPE_CHECKING:
    from pickstop.scene.model import Scene
    from pickstop.sequence.plan_model import PlanOptions
    from pickstop.speedups.stop_planner import StopPlanner

log = logging.getLogger("pickstop.api")

QUIET = 0.1  # [s] without a new plan before the last one's are planned ahead
# [s] without a newer request before a previewed layout's exact plan is made ahead: a drag
# asks for previews several times a second; holding still for this long is a pause.
HOLD = 0.25


class Yielding:
    """A planner's lock as background work takes it: only while no request waits for it, so
    a request waits at most for the one background step under way."""

    def __init__(self, lock: Any, waiting: Callable[[], bool]) -> None:
        self.lock, self.waiting = lock, waiting

    def acquire(self) -> bool:
        while True:
            while self.waiting():
                time.sleep(0.002)
            self.lock.acquire()
            if not self.waiting():
                return True
            self.lock.release()

    def release(self) -> None:
        self.lock.release()

    def __enter__(self) -> Yielding:
        self.acquire()
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


Ahead = Callable[[Yielding, Callable[[], bool]], object]


class PlanAhead:
    """The requests and the background work on one service's planners (``background``: the
    executor the background work runs on)."""

    def __init__(self, background: Executor) -> None:
        self.background = background
        self._generation = 0  # requests made: background work for an older one stops early
        self._waiting = 0  # requests waiting for a planner's lock (background work gives way)
        self._count = threading.Lock()

    @contextlib.contextmanager
    def request(self, lock: Any) -> Iterator[None]:
        """Hold a planner's ``lock`` for a request, ahead of any background work waiting
        for it."""
        with self._count:
            self._waiting += 1
        try:
            lock.acquire()
        finally:
            with self._count:
                self._waiting -= 1
        try:
            yield
        finally:
            lock.release()

    def after_plan(
        self, planner: StopPlanner, lock: Any, scene: Scene, options: PlanOptions
    ) -> None:
        """A plan was made: after :data:`QUIET` seconds without another, the plans of the
        neighbouring sigma bands and the other objective (what the slider and switch ask
        next), then every candidate's centre check."""

        def work(held: Yielding, stale: Callable[[], bool]) -> None:
            planner.prefetch_selections(scene, options, held, stale=stale)
            planner.prefetch_checks(scene, held, stale=stale)

        self._submit(lock, QUIET, work)

    def after_preview(
        self, planner: StopPlanner, lock: Any, scene: Scene, options: PlanOptions
    ) -> None:
        """A preview was made: after :data:`HOLD` seconds without another request (the
        editor paused its drag), the layout's exact plan (``StopPlanner.plan_ahead``)."""
        self._submit(
            lock, HOLD, lambda held, stale: planner.plan_ahead(scene, options, held, stale=stale)
        )

    def _submit(self, lock: Any, quiet: float, work: Ahead) -> None:
        self._generation += 1
        self.background.submit(self._when_quiet, lock, self._generation, quiet, work)

    def _when_quiet(self, lock: Any, generation: int, quiet: float, work: Ahead) -> None:
        """``work(lock, stale)`` once no request has come for ``quiet`` seconds since the one
        of ``generation``: under ``lock`` as background work takes it (it gives way to any
        request), given up once ``stale()`` (a newer request came). Never lets an error
        disturb a request: a layout without a plan is left for a request to explain,
        anything else is logged."""

        def stale() -> bool:
            return self._generation != generation

        end = time.monotonic() + quiet
        while not stale() and time.monotonic() < end:
            time.sleep(0.01)
        if stale():
            return
        try:
            work(Yielding(lock, lambda: self._waiting > 0), stale)
        except PickStopError:
            pass
        except Exception:
            log.exception("planning ahead failed")

"""Computations with a deadline that can be stopped: plans, regions, and the jobs' steps.

The event loop never computes: it hands the work to a planner thread and waits, watching the
deadline and the client. When either runs out, the thread is stopped where it is: a
:class:`Cancelled` exception is raised inside it (``PyThreadState_SetAsyncExc``), which unwinds
the planner's ``with lock:`` blocks like any other error, so its locks are released and the
next request is served at once. The exception derives from ``BaseException`` so that the
core's ``except Exception`` never swallows it. Python raises it at the thread's next bytecode,
so a long single native call (one solver run) finishes first; the solver's own time limit
bounds that.
"""

from __future__ import annotations

import asyncio
import ctypes
import threading
import time
from collections.abc import Callable
from concurrent.futures import Executor
from typing import Any, TypeVar

from starlette.requests import Request

from pickstop.api.problems import Problem

T = TypeVar("T")


class Cancelled(BaseException):
    """Raised inside a computation that passed its deadline or whose client left."""


class Work:
    """One computation on a worker thread, stoppable from another thread."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._thread: int | None = None
        self._stopped = False

    def run(self, fn: Callable[..., T], *args: Any) -> T:
        with self._lock:
            if self._stopped:
                raise Cancelled()
            self._thread = threading.get_ident()
        try:
            return fn(*args)
        finally:
            with self._lock:
                self._thread = None

    def stop(self) -> None:
        """Stop the computation (idempotent; a no-op once it has finished)."""
        with self._lock:
            if self._stopped:
                return
            self._stopped = True
            if self._thread is not None:
                ctypes.pythonapi.PyThreadState_SetAsyncExc(
                    ctypes.c_ulong(self._thread), ctypes.py_object(Cancelled)
                )

    @property
    def stopped(self) -> bool:
        return self._stopped


async def compute(
    pool: Executor,
    fn: Callable[..., T],
    *args: Any,
    deadline: float,
    request: Request | None = None,
    poll: float = 0.05,
) -> T:
    """``fn(*args)`` on ``pool``, awaited without blocking the event loop.

    deadline: seconds it may take; then it is stopped and the request answered 504.
    request: whose client is watched; if it disconnects the work is stopped (503).
    """
    work = Work()
    loop = asyncio.get_running_loop()
    fut = loop.run_in_executor(pool, work.run, fn, *args)
    end = time.monotonic() + deadline
    try:
        while True:
            left = end - time.monotonic()
            if left <= 0:
                work.stop()
                raise Problem(504, "Deadline exceeded", f"the computation took longer than "
                              f"the request deadline of {deadline:g} s and was stopped; simplify "
                              "the request or submit it as a job", kind="deadline")  # fmt: skip
            done, _ = await asyncio.wait({fut}, timeout=min(poll, left))
            if done:
                try:
                    return fut.result()
                except Cancelled:
                    raise Problem(503, "Cancelled", "the computation was stopped",
                                  kind="cancelled") from None  # fmt: skip
            if request is not None and await request.is_disconnected():
                work.stop()
                raise Problem(503, "Cancelled", "the client disconnected; the computation was "
                              "stopped", kind="cancelled")  # fmt: skip
    except asyncio.CancelledError:  # the server is shutting down, or the task was cancelled
        work.stop()
        raise

"""A request's computation with a deadline, stopped when the deadline passes or the client
leaves.

The event loop never computes: it hands the work to a planner thread (a
:class:`~pickstop.runtime.cancel.Work`) and waits, watching the deadline and the client. When
either runs out, the work's token is cancelled (:mod:`pickstop.runtime.cancel`) and the request
answered 504 or 503.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from concurrent.futures import Executor
from typing import Any, TypeVar

from starlette.requests import Request

from pickstop.api.problems import Problem
from pickstop.runtime.cancel import Cancelled, Work

T = TypeVar("T")


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
                work.stop("deadline")
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
        work.stop("closing")
        raise

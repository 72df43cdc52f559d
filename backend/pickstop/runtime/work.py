"""A computation on a thread of its own, stoppable from another thread.

:class:`Work` runs a function as the computation of its :class:`~pickstop.runtime.cancel.Token`.
Cancelling the token stops it at its next checkpoint and, between checkpoints, where it is: a
:class:`~pickstop.runtime.cancel.Cancelled` exception is raised inside its thread
(``PyThreadState_SetAsyncExc``), which unwinds the planner's ``with lock:`` blocks like any
other error, so its locks are released and the next request is served at once. Python raises
it at the thread's next bytecode, so a long single native call (one solver run) finishes
first; the solver's own time limit bounds that.
"""

from __future__ import annotations

import ctypes
import threading
from collections.abc import Callable
from typing import Any, TypeVar

from pickstop.runtime.cancel import Cancelled, Token, scope

T = TypeVar("T")


class Work:
    """One computation on a worker thread, stoppable from another thread."""

    def __init__(self) -> None:
        self.token = Token()
        self._lock = threading.Lock()
        self._thread: int | None = None
        self.token.on_cancel(self._interrupt)

    def run(self, fn: Callable[..., T], *args: Any) -> T:
        """``fn(*args)`` in this thread as the token's computation (:class:`Cancelled` at
        once if it was stopped before it began)."""
        with self._lock:
            self.token.check()
            self._thread = threading.get_ident()
        try:
            with scope(self.token):
                return fn(*args)
        finally:
            with self._lock:
                self._thread = None

    def stop(self, reason: str = "cancelled") -> None:
        """Stop the computation (idempotent: the first reason stays; a no-op once it has
        finished)."""
        self.token.cancel(reason)

    def _interrupt(self) -> None:
        with self._lock:
            if self._thread is not None:
                ctypes.pythonapi.PyThreadState_SetAsyncExc(
                    ctypes.c_ulong(self._thread), ctypes.py_object(Cancelled)
                )

    @property
    def stopped(self) -> bool:
        return self.token.cancelled

"""When a computation is to stop: one token per computation, checked at the same points.

Every computation that can be stopped runs in the scope of a :class:`Token`: a request's plan
(its deadline passed, its client left), a job (cancelled, past its deadline, the service
stopping), the planner's background work (a request waits for the planner, or the layout
changed since), a region helper process (the planner gave its request up). The computation
calls :func:`checkpoint` where everything it has made so far is whole: between the parts of a
region, its refinement rounds and its waves of growth, between the steps of a plan, between
the scenes of a batch, the orders of a mix and the progress reports of a build. There, a
cancelled token raises :class:`Cancelled`.

A token is also delivered where no checkpoint comes soon: :class:`Work` runs a function on a
thread as its token's computation and raises :class:`Cancelled` inside that thread when the
token is cancelled (``PyThreadState_SetAsyncExc``), at the thread's next bytecode: after a long
native call (a solver run, whose own time limit bounds it) returns. The exception unwinds the
planner's ``with lock:`` blocks like any other error, so its locks are released and the next
request is served at once. A region helper reads its token from memory shared with the
planner. The token's ``reason`` says why (``"cancelled"``,
``"deadline"``, ``"closing"``, ``"give way"``), so the one who catches :class:`Cancelled`
records the right outcome.

The current token is a context variable: each thread starts with one that is never cancelled,
so core code called outside any scope (a batch plan, a notebook) checks nothing.
"""

from __future__ import annotations

import contextlib
import contextvars
import ctypes
import threading
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

T = TypeVar("T")


class Cancelled(BaseException):
    """Raised where a computation stops because its token was cancelled.

    A ``BaseException``, so that no ``except Exception`` between the checkpoint and the one
    who stopped the computation swallows it."""


class Token:
    """Whether a computation is to stop: cancelled by :meth:`cancel` (from any thread), or
    when ``give_way()`` says so (a predicate read at each check, e.g. a flag in memory shared
    with a parent process), or when the token it was made ``within`` is."""

    def __init__(
        self,
        give_way: Callable[[], bool] | None = None,
        *,
        within: Token | None = None,
        reason: str = "give way",
    ) -> None:
        self._give_way = give_way
        self._within = within
        self._give_way_reason = reason
        self._reason: str | None = None
        self._callbacks: list[Callable[[], object]] = []
        self._lock = threading.Lock()

    def cancel(self, reason: str = "cancelled") -> None:
        """Cancel the computation (idempotent: the first reason stays); the callbacks
        registered with :meth:`on_cancel` run here, once."""
        with self._lock:
            if self._reason is not None:
                return
            self._reason = reason
            callbacks, self._callbacks = self._callbacks, []
        for fn in callbacks:
            fn()

    def on_cancel(self, fn: Callable[[], object]) -> None:
        """Run ``fn`` when the token is cancelled (at once if it already is)."""
        with self._lock:
            if self._reason is None:
                self._callbacks.append(fn)
                return
        fn()

    @property
    def reason(self) -> str | None:
        """Why the computation is to stop, or None while it is not."""
        if self._reason is not None:
            return self._reason
        if self._within is not None and (outer := self._within.reason) is not None:
            return outer
        if self._give_way is not None and self._give_way():
            return self._give_way_reason
        return None

    @property
    def cancelled(self) -> bool:
        return self.reason is not None

    def check(self) -> None:
        """Raise :class:`Cancelled` if the computation is to stop."""
        if (reason := self.reason) is not None:
            raise Cancelled(reason)


#: The token of a computation no one stops.
NEVER = Token()

_current: contextvars.ContextVar[Token] = contextvars.ContextVar("pickstop_token", default=NEVER)


def current() -> Token:
    """The token of the computation running in this thread (:data:`NEVER` outside any)."""
    return _current.get()


@contextlib.contextmanager
def scope(token: Token) -> Iterator[Token]:
    """Run the block as the computation of ``token``."""
    reset = _current.set(token)
    try:
        yield token
    finally:
        _current.reset(reset)


@contextlib.contextmanager
def giving_way(give_way: Callable[[], bool]) -> Iterator[Token]:
    """Run the block as background work that stops at its next checkpoint once
    ``give_way()`` is true, or once the computation around it is cancelled."""
    with scope(Token(give_way, within=current())) as token:
        yield token


def checkpoint() -> None:
    """Raise :class:`Cancelled` if the computation running in this thread is to stop."""
    _current.get().check()


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

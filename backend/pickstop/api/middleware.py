"""ASGI middleware: HEAD, unexpected errors, the body size limit and the stored-plan fast path.

They run before routing, so they see every request, chunked or not, and never compute.
"""

from __future__ import annotations

import logging
from typing import Any

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from pickstop.api.problems import Problem, problem_response
from pickstop.settings import Settings

API = "/api/v1"
log = logging.getLogger("pickstop.api")


class Head:
    """``HEAD`` answered as ``GET`` without the body (RFC 9110: what GET would answer, headers
    only), so that every resource whose ``Allow`` lists HEAD serves it."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] != "HEAD":
            await self.app(scope, receive, send)
            return

        async def headers_only(msg: Message) -> None:
            if msg["type"] == "http.response.body":
                if msg.get("more_body", False):
                    return
                msg = {"type": "http.response.body", "body": b""}
            await send(msg)

        await self.app({**scope, "method": "GET"}, receive, headers_only)


class ErrorGuard:
    """An unexpected error answers 500 (a problem document, logged) and leaves the connection
    usable: Starlette's last-resort handler answers and then raises again, and the server
    drops a connection whose request raised, unannounced. Once an answer has begun nothing
    can be said; the error goes on and the server closes the connection."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        started = False

        async def watch(msg: Message) -> None:
            nonlocal started
            started = started or msg["type"] == "http.response.start"
            await send(msg)

        try:
            await self.app(scope, receive, watch)
        except Exception as exc:
            if started:
                raise
            log.exception("unexpected error on %s", scope.get("path"))
            p = Problem(500, "Internal error", f"{type(exc).__name__}: the request failed",
                        kind="internal")  # fmt: skip
            await problem_response(p, scope.get("path"))(scope, receive, send)


class BodyLimit:
    """Refuse request bodies over ``limit`` bytes with 413, declared or streamed."""

    def __init__(self, app: ASGIApp, limit: int) -> None:
        self.app, self.limit = app, limit

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        # The rest of the body is not read: the connection is closed after the answer, and
        # says so.
        too_big = Problem(
            413,
            "Request too large",
            f"the request body exceeds {self.limit} bytes",
            kind="too-large",
            field="body",
            headers={"Connection": "close"},
        )
        for k, v in scope.get("headers", []):
            if k == b"content-length" and v.isdigit() and int(v) > self.limit:
                await problem_response(too_big, scope.get("path"))(scope, receive, send)
                return
        seen = 0

        async def limited() -> Any:
            nonlocal seen
            msg = await receive()
            if msg["type"] == "http.request":
                seen += len(msg.get("body", b""))
                if seen > self.limit:
                    raise _TooLarge(413, too_big.title, too_big.detail, kind="too-large",
                                    field="body", headers=too_big.headers)  # fmt: skip
            return msg

        try:
            await self.app(scope, limited, send)
        except _TooLarge:
            await problem_response(too_big, scope.get("path"))(scope, receive, send)


class _TooLarge(Problem):
    """Raised from ``receive`` once a streamed body passes the limit: a route reading the
    body answers 413 through the problem handler; anything else, this middleware does."""


class StoredPlanFastPath:
    """``GET /api/v1/plans/{id}`` for a plan already in the service's body cache, answered
    before routing: stored plans are immutable and are the reads an MES makes most. Anything
    else (a query string, a plan not cached yet, reads that need a key) takes the normal way,
    which also fills the cache."""

    PREFIX = f"{API}/plans/"

    def __init__(self, app: ASGIApp, settings: Settings) -> None:
        self.app, self.enabled = app, not settings.read_requires_key

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if (
            self.enabled
            and scope["type"] == "http"
            and scope["method"] == "GET"
            and not scope.get("query_string")
            and scope["path"].startswith(self.PREFIX)
        ):
            service = getattr(scope["app"].state, "service", None)
            plan_id = scope["path"][len(self.PREFIX) :]
            body = service.bodies.cached(plan_id) if service is not None else None
            if body is not None:
                await send({"type": "http.response.start", "status": 200, "headers": [
                    (b"content-type", b"application/json"),
                    (b"content-length", str(len(body)).encode()),
                    (b"cache-control", b"public, max-age=31536000, immutable"),
                ]})  # fmt: skip
                await send({"type": "http.response.body", "body": body})
                return
        await self.app(scope, receive, send)

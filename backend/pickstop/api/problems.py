"""Errors as RFC 9457 problem details (``application/problem+json``).

Every error response carries ``type``, ``title``, ``status`` and ``detail``; validation errors
add ``field`` (the first offending field, dotted) and ``errors`` (every field with its message).
"""

from __future__ import annotations

from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from pickstop.errors import (
    DatabaseMismatchError,
    DatabaseNotFoundError,
    InputError,
    PickStopError,
)
from pickstop.sequence.cover import InfeasiblePlanError

BASE = "https://pickstop.dev/problems/"
MEDIA = "application/problem+json"


class Problem(Exception):
    """Raise anywhere in a request to answer with a problem document."""

    def __init__(
        self,
        status: int,
        title: str,
        detail: str,
        *,
        kind: str | None = None,
        field: str | None = None,
        errors: list[dict[str, str]] | None = None,
        headers: dict[str, str] | None = None,
    ) -> None:
        super().__init__(detail)
        self.status, self.title, self.detail = status, title, detail
        self.kind = kind or title.lower().replace(" ", "-")
        self.field, self.errors, self.headers = field, errors, headers


def problem_response(p: Problem, instance: str | None = None) -> JSONResponse:
    body: dict[str, Any] = {
        "type": BASE + p.kind,
        "title": p.title,
        "status": p.status,
        "detail": p.detail,
    }
    if instance:
        body["instance"] = instance
    if p.field:
        body["field"] = p.field
    if p.errors:
        body["errors"] = p.errors
    return JSONResponse(body, status_code=p.status, media_type=MEDIA, headers=p.headers)


def from_error(e: PickStopError) -> Problem:
    """A PickStop error as the problem a client can act on."""
    if isinstance(e, InfeasiblePlanError):
        return Problem(422, "Infeasible plan", e.message, field=e.field)
    if isinstance(e, DatabaseNotFoundError):
        return Problem(409, "No reachability database", e.message, kind="no-database")
    if isinstance(e, DatabaseMismatchError):
        return Problem(409, "Database mismatch", e.message)
    if isinstance(e, InputError):
        problems = getattr(e, "problems", None)
        errors = [{"field": f, "message": m} for f, m in problems] if problems else None
        return Problem(
            422, "Invalid input", e.message, kind="validation", field=e.field, errors=errors
        )
    return Problem(500, "Internal error", e.message, kind="internal")


def _loc(loc: tuple[Any, ...] | list[Any]) -> str:
    parts = [str(p) for p in loc]
    if parts and parts[0] in ("body", "query", "path", "header"):
        parts = parts[1:] or parts
    return ".".join(parts) or "(root)"


def install(app: FastAPI) -> None:
    @app.exception_handler(Problem)
    async def _problem(request: Request, exc: Problem) -> JSONResponse:
        return problem_response(exc, request.url.path)

    @app.exception_handler(PickStopError)
    async def _pickstop(request: Request, exc: PickStopError) -> JSONResponse:
        return problem_response(from_error(exc), request.url.path)

    @app.exception_handler(RequestValidationError)
    async def _validation(request: Request, exc: RequestValidationError) -> JSONResponse:
        errors = [{"field": _loc(e["loc"]), "message": e["msg"]} for e in exc.errors()]
        detail = "; ".join(f"{e['field']}: {e['message']}" for e in errors[:5])
        p = Problem(
            422,
            "Invalid input",
            detail,
            kind="validation",
            field=errors[0]["field"] if errors else None,
            errors=errors,
        )
        return problem_response(p, request.url.path)

    @app.exception_handler(StarletteHTTPException)
    async def _http(request: Request, exc: StarletteHTTPException) -> JSONResponse:
        title = {404: "Not found", 405: "Method not allowed"}.get(exc.status_code, "Error")
        p = Problem(exc.status_code, title, str(exc.detail), headers=getattr(exc, "headers", None))
        return problem_response(p, request.url.path)

    @app.exception_handler(Exception)
    async def _unexpected(request: Request, exc: Exception) -> JSONResponse:
        import logging

        logging.getLogger("pickstop.api").exception("unexpected error on %s", request.url.path)
        p = Problem(
            500, "Internal error", f"{type(exc).__name__}: the request failed", kind="internal"
        )
        return problem_response(p, request.url.path)

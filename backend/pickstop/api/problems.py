"""Errors as RFC 9457 problem details (``application/problem+json``).

Every error response carries ``type``, ``title``, ``status`` and ``detail``; validation errors
add ``field`` (the first offending field, dotted) and ``errors`` (each field with its message:
the first :data:`MAX_ERRORS` of them, the detail saying how many there are).
"""

from __future__ import annotations

import re
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from pickstop.errors import (
    CorruptShardError,
    DatabaseError,
    DatabaseMismatchError,
    DatabaseNotFoundError,
    ExistsError,
    InputError,
    PickStopError,
    UnavailableError,
)
from pickstop.sequence.cover import InfeasiblePlanError

BASE = "https://pickstop.dev/problems/"
MAX_ERRORS = 50  # listed in one answer: a body can hold thousands, each costing the server
MAX_DETAIL = 2000  # [characters] of the detail
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


_ROOTS: list[str] = []


def server_roots(*paths: Any) -> None:
    """Folders of this server never to be shown in an answer (the data folder, the install,
    the temporary folder, home): a path under one is shown relative to it."""
    import sys
    import tempfile
    from pathlib import Path

    here = Path(__file__).resolve().parents[3]  # the checkout or site-packages
    found = {str(Path(p)) for p in paths if p} | {str(Path(p).resolve()) for p in paths if p}
    found |= {sys.prefix, sys.base_prefix, tempfile.gettempdir(), str(Path.home()), str(here)}
    found |= {str(Path(tempfile.gettempdir()).resolve())}
    _ROOTS[:] = sorted({r.rstrip("/") for r in found if len(r) > 1}, key=len, reverse=True)


def scrub(text: str) -> str:
    """``text`` without server folders: ``/srv/data/robots/x.urdf`` becomes ``robots/x.urdf``."""
    for root in _ROOTS:
        if root in text:
            text = re.sub(re.escape(root) + "/", "", text)  # a path under it: relative
            # the folder itself (not a longer name it begins): named by what it is
            text = re.sub(re.escape(root) + r"(?![\w/-]|\.\w)", "the server's folder", text)
    return text


def problem_response(p: Problem, instance: str | None = None) -> JSONResponse:
    detail = scrub(p.detail)
    if len(detail) > MAX_DETAIL:
        detail = detail[: MAX_DETAIL - 3] + "..."
    if p.errors and len(p.errors) > MAX_ERRORS:
        detail += f" ({len(p.errors)} errors; the first {MAX_ERRORS} are listed)"
    body: dict[str, Any] = {
        "type": BASE + p.kind,
        "title": p.title,
        "status": p.status,
        "detail": detail,
    }
    if instance:
        body["instance"] = instance
    if p.field:
        body["field"] = p.field
    if p.errors:
        body["errors"] = [{**e, "message": scrub(e["message"])} for e in p.errors[:MAX_ERRORS]]
    return JSONResponse(body, status_code=p.status, media_type=MEDIA, headers=p.headers)


def from_error(e: PickStopError) -> Problem:
    """A PickStop error as the problem a client can act on."""
    if isinstance(e, InfeasiblePlanError):
        return Problem(422, "Infeasible plan", e.message, field=e.field)
    if isinstance(e, DatabaseNotFoundError):
        return Problem(409, "No reachability database", e.message, kind="no-database")
    if isinstance(e, DatabaseMismatchError):
        return Problem(409, "Database mismatch", e.message)
    if isinstance(e, DatabaseError) and not isinstance(e, CorruptShardError):
        # incomplete, being built, or of an older format: the request may succeed later
        return Problem(409, "Database not usable", e.message, kind="database-unusable")
    if isinstance(e, ExistsError):
        return Problem(409, "Conflict", e.message, kind="exists", field=e.field)
    if isinstance(e, InputError):
        problems = getattr(e, "problems", None)
        errors = [{"field": f, "message": m} for f, m in problems] if problems else None
        return Problem(
            422, "Invalid input", e.message, kind="validation", field=e.field, errors=errors
        )
    if isinstance(e, UnavailableError):
        return Problem(503, "Unavailable", e.message, kind="unavailable",
                       headers={"Retry-After": "5"})  # fmt: skip
    return Problem(500, "Internal error", e.message, kind="internal")


def _allowed(request: Request) -> list[str]:
    """Methods the OpenAPI document gives the request's path (for a 405's Allow header): the
    resource ``/jobs/batch`` itself, not the job "batch" of ``/jobs/{job_id}``."""
    paths: dict[str, dict[str, Any]] = request.app.openapi()["paths"]
    path = request.url.path
    ops = paths.get(path)
    if ops is None:
        for template, candidate in paths.items():
            if re.fullmatch(re.sub(r"\{[^/]+\}", "[^/]+", template), path):
                ops = candidate
                break
    methods = {m.upper() for m in ops or {}}
    if "GET" in methods:
        methods.add("HEAD")
    return sorted(methods)


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
        headers = dict(getattr(exc, "headers", None) or {})
        if exc.status_code == 405:  # every route at the path, not only the first one matched
            headers = {k: v for k, v in headers.items() if k.lower() != "allow"}
            headers["Allow"] = ", ".join(_allowed(request))
        p = Problem(exc.status_code, title, str(exc.detail), headers=headers or None)
        return problem_response(p, request.url.path)

    @app.exception_handler(RecursionError)
    async def _nested(request: Request, exc: RecursionError) -> JSONResponse:
        # Only a request body nested deeper than Python recurses gets here.
        p = Problem(422, "Invalid input", "body: nested too deeply (arrays or objects inside "
                    "each other)", kind="validation", field="body")  # fmt: skip
        return problem_response(p, request.url.path)

    @app.exception_handler(Exception)
    async def _unexpected(request: Request, exc: Exception) -> JSONResponse:
        import logging

        logging.getLogger("pickstop.api").exception("unexpected error on %s", request.url.path)
        p = Problem(
            500, "Internal error", f"{type(exc).__name__}: the request failed", kind="internal"
        )
        return problem_response(p, request.url.path)

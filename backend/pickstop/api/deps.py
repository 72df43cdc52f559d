"""What route handlers receive: the service, the key checks, a JSON body, a stored scene.

Route-level ``dependencies=[WriteKey]`` run before a handler's own parameters, so a request
without a valid key is answered 401 before its body is read or validated. The light ones (the
service, the key checks: a hash and a compare) are coroutines, so they cost no hop to a worker
thread; anything touching SQLite is a plain function, run in the thread pool.
"""

from __future__ import annotations

import hmac
from typing import Annotated, Any

from fastapi import Depends, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from starlette.concurrency import run_in_threadpool

from pickstop.api import body
from pickstop.api.problems import Problem
from pickstop.api.service import Service
from pickstop.settings import hash_key

bearer = HTTPBearer(auto_error=False)
Credentials = Annotated[HTTPAuthorizationCredentials | None, Depends(bearer)]


async def get_service(request: Request) -> Service:
    service: Service = request.app.state.service
    return service


ServiceDep = Annotated[Service, Depends(get_service)]


def _check_key(service: Service, cred: HTTPAuthorizationCredentials | None, what: str) -> None:
    keys = service.key_hashes
    if cred is not None:
        h = hash_key(cred.credentials)
        if any(hmac.compare_digest(h, k) for k in keys):
            return
    raise Problem(
        401,
        "Unauthorized",
        f"{what} needs an API key: Authorization: Bearer <key>"
        if cred is None
        else "the API key is not valid",
        field="Authorization",
        headers={"WWW-Authenticate": "Bearer"},
    )


async def write_key(service: ServiceDep, cred: Credentials) -> None:
    _check_key(service, cred, "this request (a write)")


async def read_key(service: ServiceDep, cred: Credentials) -> None:
    if service.settings.read_requires_key:
        _check_key(service, cred, "this request (reads need a key on this server)")


WriteKey = Depends(write_key)
ReadKey = Depends(read_key)


def _is_json(content_type: str) -> bool:
    media = content_type.split(";", 1)[0].strip().lower()
    return media == "application/json" or (
        media.startswith("application/") and media.endswith("+json")
    )


async def json_body(request: Request) -> Any:
    """The request's JSON document, decoded off the event loop (415 unless it says JSON)."""
    ctype = request.headers.get("content-type")
    if ctype is None or not _is_json(ctype):
        raw = await request.body()
        if ctype is not None or raw.strip():
            raise Problem(
                415,
                "Unsupported media type",
                f"the body must be application/json, not {ctype or 'untyped'}",
                field="Content-Type",
                headers={"Accept-Post": "application/json"},
            )
    else:
        raw = await request.body()
    return await run_in_threadpool(body.decode, raw)


JsonBody = Annotated[Any, Depends(json_body)]

YAML_TYPES = ("application/yaml", "application/x-yaml", "text/yaml", "text/x-yaml")


async def config_body(request: Request) -> Any:
    """A config document, JSON or YAML by its content type, decoded off the event loop."""
    ctype = (request.headers.get("content-type") or "").split(";", 1)[0].strip().lower()
    if ctype in YAML_TYPES:
        return await run_in_threadpool(body.decode_yaml, await request.body())
    try:
        return await json_body(request)
    except Problem as e:
        if e.status == 415:
            e.detail = (
                f"the body must be application/json or application/yaml, not {ctype or 'untyped'}"
            )
            e.headers = {**(e.headers or {}), "Accept-Post": "application/json, application/yaml"}
        raise


ConfigBody = Annotated[Any, Depends(config_body)]


def scene_row(scene_id: str, service: ServiceDep) -> dict[str, Any]:
    """The stored scene ``scene_id`` (404 if there is none)."""
    row = service.store.scene(scene_id)
    if row is None:
        raise Problem(404, "Not found", f"no scene {scene_id!r}", field="scene_id")
    return row


SceneRow = Annotated[dict[str, Any], Depends(scene_row)]

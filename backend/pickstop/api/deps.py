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


def content_type(request: Request) -> tuple[str | None, str]:
    """The request's media type (lower case, None if it gives none) and its charset (UTF-8
    unless it names another); a charset Python cannot decode is a 415."""
    header = request.headers.get("content-type")
    if header is None:
        return None, "utf-8"
    media, _, params = header.partition(";")
    charset = "utf-8"
    for param in params.split(";"):
        key, _, value = param.partition("=")
        if key.strip().lower() == "charset" and value.strip():
            charset = value.strip().strip('"').lower()
    if not body.known_charset(charset):
        raise Problem(415, "Unsupported media type", f"the charset {charset!r} is not one this "
                      "server decodes (send UTF-8)", field="Content-Type")  # fmt: skip
    return media.strip().lower(), charset


def _is_json(media: str) -> bool:
    return media == "application/json" or (
        media.startswith("application/") and media.endswith("+json")
    )


async def json_body(request: Request) -> Any:
    """The request's JSON document, decoded off the event loop in the charset its content
    type names (415 unless it says JSON)."""
    media, charset = content_type(request)
    raw = await request.body()
    # A request without a content type and without a body reads as an empty JSON body.
    if not (media is None and not raw.strip()) and (media is None or not _is_json(media)):
        raise Problem(
            415,
            "Unsupported media type",
            f"the body must be application/json, not {media or 'untyped'}",
            field="Content-Type",
            headers={"Accept-Post": "application/json"},
        )
    return await run_in_threadpool(body.decode, raw, charset)


JsonBody = Annotated[Any, Depends(json_body)]

YAML_TYPES = ("application/yaml", "application/x-yaml", "text/yaml", "text/x-yaml")


async def config_body(request: Request, service: ServiceDep) -> Any:
    """A config document, JSON or YAML by its content type, decoded off the event loop (YAML
    in a child process, and at most ``max_yaml_bytes`` of it)."""
    media, charset = content_type(request)
    if media in YAML_TYPES:
        raw = await request.body()
        limit = service.settings.max_yaml_bytes
        if len(raw) > limit:
            raise Problem(413, "Request too large", f"a YAML body may hold {limit} bytes, this "
                          f"one holds {len(raw)}; send JSON for more", kind="too-large",
                          field="body")  # fmt: skip
        return await run_in_threadpool(body.decode_yaml, raw, charset)
    try:
        return await json_body(request)
    except Problem as e:
        if e.status == 415 and e.field == "Content-Type" and "charset" not in e.detail:
            e.detail = (
                f"the body must be application/json or application/yaml, not {media or 'untyped'}"
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


def robot_name(name: str, service: ServiceDep) -> str:
    """The name of a preset or registered robot (404 if there is none)."""
    if not service.robots.exists(name):
        raise Problem(404, "Not found", f"no robot {name!r}", field="name")
    return name


RobotName = Annotated[str, Depends(robot_name)]

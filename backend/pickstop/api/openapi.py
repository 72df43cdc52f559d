"""The OpenAPI document as the contract: typed request bodies, security as configured, every
error status documented.

Routes read their JSON bodies themselves (see :mod:`pickstop.api.body`), so FastAPI does not
see their models; :func:`json_request` declares each body by a component schema and
:func:`install` adds those schemas (the scene and robot formats, the request models).
"""

from __future__ import annotations

from typing import Any

from fastapi import FastAPI
from fastapi.openapi.utils import get_openapi
from pydantic import BaseModel

from pickstop.settings import Settings

REF = "#/components/schemas/{model}"

# Statuses any operation may answer, and when.
COMMON: dict[int, str] = {
    500: "an unexpected server error (the detail never names server paths)",
    503: "the computation was stopped (client gone, or shutting down), or the planner "
    "process restarted: try again",
}
BODY: dict[int, str] = {
    413: "the request body exceeds the limit (see /limits)",
    415: "the body is not application/json (nor, where accepted, application/yaml)",
    422: "invalid input, or an infeasible plan; `field` names the offending field or `body`",
}
TEXT: dict[int, str] = {
    400: "the request is malformed",
    401: "an API key is needed or not valid",
    404: "no such resource",
    405: "the method is not allowed here (see Allow)",
    409: "no reachability database fits the request",
    412: "the resource changed since it was read (If-Match)",
    428: "If-Match is required",
    504: "the computation passed the request deadline and was stopped",
}


def json_request(schema: str, description: str = "", yaml: bool = False) -> dict[str, Any]:
    """``openapi_extra`` of a route whose JSON (and, with ``yaml``, YAML) body is the component
    ``schema``."""
    ref = {"schema": {"$ref": REF.format(model=schema)}}
    content = {"application/json": ref, **({"application/yaml": ref} if yaml else {})}
    return {"requestBody": {"required": True, "description": description, "content": content}}


def install(app: FastAPI, settings: Settings, models: dict[str, type[BaseModel]]) -> None:
    """Generate the document once: component schemas of ``models`` (with their definitions),
    bearer security on writes (on reads only if they need a key), problem responses."""

    def openapi() -> dict[str, Any]:
        if app.openapi_schema:
            return app.openapi_schema
        doc = get_openapi(
            title=app.title,
            version=app.version,
            description=app.description,
            routes=app.routes,
        )
        comps = doc.setdefault("components", {})
        schemas = comps.setdefault("schemas", {})
        for name, model in models.items():
            js = model.model_json_schema(ref_template=REF)
            for k, v in js.pop("$defs", {}).items():
                schemas.setdefault(k, v)
            schemas[name] = js
        _link(doc)
        _limits(schemas, settings)
        _rules(schemas)
        comps.setdefault("securitySchemes", {})["bearer"] = {"type": "http", "scheme": "bearer"}
        for path, ops in doc["paths"].items():
            for method, op in ops.items():
                _operation(op, method, path, settings)
        app.openapi_schema = doc
        return doc

    app.openapi = openapi  # type: ignore[method-assign]


def _limits(schemas: dict[str, Any], s: Settings) -> None:
    """The size limits of the settings as the schemas' own bounds, so that a client (and a
    schema-driven test) knows them before sending."""

    def bound(model: str, prop: str, **kw: Any) -> None:
        target = schemas.get(model, {}).get("properties", {}).get(prop)
        if target is not None:
            target.update(kw)

    bound("BatchRequest", "scenes", maxItems=s.max_batch)
    bound("Scene", "trays", maxItems=s.max_trays)
    bound("Scene", "obstacles", maxItems=s.max_obstacles)
    bound("Tray", "parts", maxItems=s.max_parts_per_tray)
    bound("BuildRequest", "samples", maximum=s.max_samples)
    samples = schemas.get("BuildRequest", {}).get("properties", {}).get("samples", {})
    if "default" in samples:
        samples["default"] = min(samples["default"], s.max_samples)
    samples = schemas.get("PlanOptions", {}).get("properties", {}).get("samples", {})
    for branch in [samples, *samples.get("anyOf", []), *samples.get("allOf", [])]:
        if "maximum" in branch:
            branch["maximum"] = min(branch["maximum"], s.max_mc_samples)


def _rules(schemas: dict[str, Any]) -> None:
    """The rules between fields that the models check, in the schemas too (or, where JSON
    Schema cannot say them, in the descriptions)."""
    one_of = [
        {"required": ["scene_id"], "properties": {"scene_id": {"type": "string"}}},
        {"required": ["scene"], "properties": {"scene": {"type": "object"}}},
    ]
    for name in ("BatchItem", "PlanRequest"):
        if name in schemas:
            schemas[name]["oneOf"] = one_of
            schemas[name]["description"] = "give exactly one of scene_id and scene"
    zero = {"type": "array", "items": {"const": 0}}
    hand = schemas.get("Hand", {}).get("properties", {})
    config = schemas.get("RobotConfig", {}).get("properties", {})
    for props, axis in ((hand, "approach_axis"), (hand, "closing_axis"), (config, "approach_axis")):
        if axis in props:
            props[axis]["not"] = zero
            props[axis]["description"] = (
                "a non-zero direction in the grasp point's frame; closing_axis is "
                "perpendicular to approach_axis (to 0.06 deg)"
            )
    extent = schemas.get("Extent")
    if extent is not None:
        extent["description"] = "a rectangle on the floor [m]: min below max in x and in y"


#: Where what a POST creates is read: (path suffix, status) -> (operation id, parameter).
CREATED = {
    ("/scenes", "201"): ("get_scene_api_v1_scenes__scene_id__get", "scene_id"),
    ("/plans", "201"): ("get_plan_api_v1_plans__plan_id__get", "plan_id"),
    ("/databases", "202"): ("job_api_v1_jobs__job_id__get", "job_id"),
    ("/jobs/batch", "202"): ("job_api_v1_jobs__job_id__get", "job_id"),
}


def _links(op: dict[str, Any], method: str, path: str) -> None:
    """OpenAPI links from a creating POST to the resource it made (a database build makes a
    job, not yet a database)."""
    if method != "post":
        return
    for (suffix, status), (target, param) in CREATED.items():
        answer = op.get("responses", {}).get(status)
        if path.endswith(suffix) and answer is not None:
            link = {"operationId": target, "parameters": {param: "$response.body#/id"}}
            answer["links"] = {"created": link}


def _link(node: Any) -> None:
    """Replace every ``{"x-component": name}`` marker by a $ref to that component."""
    stack = [node]
    while stack:
        n = stack.pop()
        if isinstance(n, dict):
            for k, v in n.items():
                if isinstance(v, dict) and set(v) == {"x-component"}:
                    n[k] = {"$ref": REF.format(model=v["x-component"])}
                else:
                    stack.append(v)
        elif isinstance(n, list):
            for i, v in enumerate(n):
                if isinstance(v, dict) and set(v) == {"x-component"}:
                    n[i] = {"$ref": REF.format(model=v["x-component"])}
                else:
                    stack.append(v)


def _operation(op: dict[str, Any], method: str, path: str, settings: Settings) -> None:
    write = method in ("post", "put", "delete", "patch")
    secured = write or settings.read_requires_key
    op.pop("security", None)
    if secured:
        op["security"] = [{"bearer": []}]
    responses = op.setdefault("responses", {})
    codes = dict(COMMON)
    if secured:
        codes[401] = TEXT[401]
    if "requestBody" in op:
        codes.update(BODY)
    if "{" in path:
        codes[404] = TEXT[404]
    if op.get("parameters"):
        codes[422] = BODY[422]
    if method in ("put", "delete") and "scenes/{" in path:
        codes[412], codes[428] = TEXT[412], TEXT[428]
        for param in op.get("parameters", []):
            if param.get("in") == "header" and param.get("name", "").lower() == "if-match":
                # Required: without it the answer is 428 (RFC 6585), not a plain 422.
                param["required"] = True
                param["schema"] = {"type": "string", "minLength": 1}
    if path.endswith(("/plans", "/regions", "/batch", "/guidance")):
        codes[409], codes[504] = TEXT[409], TEXT[504]
    if method == "delete" and "/databases/{" in path:
        codes[409] = "the database is being built: cancel its build job first"
    if path.endswith("/errors/fit"):  # a stored scene written with its ETag
        codes[404], codes[412], codes[428] = TEXT[404], TEXT[412], TEXT[428]
    if path.endswith("/dispatch"):
        codes[409] = "no MQTT broker is configured on this server (PICKSTOP_MQTT_BROKER)"
    if path.endswith("/check") or path.endswith("/model"):
        codes[504] = TEXT[504]
    if method == "post" and path.endswith("/robots"):
        codes[409] = "a robot of that name exists already"
    _links(op, method, path)
    codes[405] = TEXT[405]
    for code, text in codes.items():
        responses.setdefault(
            str(code),
            {
                "description": text,
                "content": {
                    "application/problem+json": {
                        "schema": {"$ref": REF.format(model="ProblemDetails")}
                    }
                },
            },
        )
    # FastAPI documents its own 422 with its own schema; ours is a problem document.
    if "422" in responses and "application/json" in responses["422"].get("content", {}):
        responses["422"] = {
            "description": BODY[422],
            "content": {
                "application/problem+json": {"schema": {"$ref": REF.format(model="ProblemDetails")}}
            },
        }

"""Flatten a JSON schema into ``path -> facts`` (type, required, enum, bounds), so that a
pydantic model's schema and the published one compare field by field."""

from __future__ import annotations

from typing import Any

FACTS = ("enum", "minimum", "maximum")


def _types(s: dict[str, Any]) -> tuple[str, ...]:
    t = s.get("type")
    if t is None and "enum" in s:
        t = "string"
    if isinstance(t, list):
        ts = set(t)
    elif t is None:
        ts = set()
    else:
        ts = {t}
    if "number" in ts and len(ts) > 1:
        ts.discard("integer")  # a JSON number covers integers
    return tuple(sorted(ts))


def flatten(schema: dict[str, Any]) -> dict[str, dict[str, Any]]:
    defs = {**schema.get("definitions", {}), **schema.get("$defs", {})}
    out: dict[str, dict[str, Any]] = {}

    def resolve(s: dict[str, Any]) -> dict[str, Any]:
        while "$ref" in s:
            s = {**defs[s["$ref"].split("/")[-1]], **{k: v for k, v in s.items() if k != "$ref"}}
        alts = [a for a in s.get("anyOf", []) if a.get("type") != "null"]
        if alts:
            rest = {k: v for k, v in s.items() if k != "anyOf"}
            if len(alts) == 1:
                return resolve({**rest, **resolve(alts[0])})
            ts = sorted({t for a in alts for t in _types(resolve(a))})
            return resolve({**rest, "type": ts})
        return s

    def walk(s: dict[str, Any], path: str, depth: int) -> None:
        s = resolve(s)
        if "const" in s:  # a one-value Literal
            s = {**s, "enum": [s["const"]]}
        facts: dict[str, Any] = {"type": _types(s)}
        for k in FACTS:
            if k in s:
                facts[k] = sorted(s[k]) if k == "enum" else float(s[k])
        if "properties" in s:
            facts["type"] = ("object",)
            facts["required"] = sorted(s.get("required", []))
        out[path] = facts
        if depth > 12:
            return
        for k, v in s.get("properties", {}).items():
            walk(v, f"{path}.{k}", depth + 1)
        if "items" in s and isinstance(s["items"], dict):
            walk(s["items"], f"{path}[]", depth + 1)

    walk(schema, "", 0)
    return out

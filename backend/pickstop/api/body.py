"""Request bodies: JSON decoded off the event loop, with every problem located.

FastAPI would decode a body on the event loop and before the key is checked; PickStop's routes
take the raw bytes instead (:func:`pickstop.api.deps.json_body`) and decode them here, in a
worker thread, after authentication: not UTF-8, not JSON, nested too deep, a 5,000-digit
integer or a NaN each come back as a 422 whose ``field`` is ``body`` (or the value's path) and
whose detail says where. Nesting is bounded by the decoder's recursion limit (about 1,000
levels); anything recursing over a document later answers the same 422 (see problems.py).
"""

from __future__ import annotations

import json
import math
import re
from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

from pickstop.api.problems import Problem

M = TypeVar("M", bound=BaseModel)


def invalid(field: str, message: str, errors: list[tuple[str, str]] | None = None) -> Problem:
    errs = errors or [(field, message)]
    return Problem(
        422,
        "Invalid input",
        "; ".join(f"{f}: {m}" for f, m in errs[:5]),
        kind="validation",
        field=field,
        errors=[{"field": f, "message": m} for f, m in errs],
    )


# Numbers Python would read as infinite or NaN: only then is the document walked for them.
_NON_FINITE = re.compile(rb"NaN|Infinity|\d[eE]\+?\d{3}")
_DIGITS = re.compile(r"has (\d+) digits")


def _text(raw: bytes, kind: str) -> str:
    """The body as UTF-8 text, or a 422 saying it is empty or where it is not UTF-8."""
    if not raw.strip():
        raise invalid("body", f"the request needs a {kind} body")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise invalid("body", f"not valid UTF-8 at byte {e.start}") from None


def decode(raw: bytes) -> Any:
    """The JSON document in ``raw``, or a 422 :class:`Problem` saying where it breaks. Costs
    one pass of the C decoder: a 1 MB scene takes milliseconds."""
    text = _text(raw, "JSON")
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as e:
        raise invalid(
            "body", f"not valid JSON at line {e.lineno} column {e.colno}: {e.msg}"
        ) from None
    except RecursionError:
        raise nested() from None
    except ValueError as e:  # an integer of more than 4,300 digits
        m = _DIGITS.search(str(e))
        raise invalid("body", f"an integer of {m.group(1) if m else 'too many'} digits, "
                      "more than any field accepts") from None  # fmt: skip
    if _NON_FINITE.search(raw):
        bad = finite_problem(doc)
        if bad is not None:
            raise invalid(*bad)
    return doc


def decode_yaml(raw: bytes) -> Any:
    """The YAML document in ``raw`` (safe types only, no anchors or aliases: a few bytes of
    aliases can stand for gigabytes), or a 422 :class:`Problem` saying where it breaks."""
    import yaml

    class _NoAliases(yaml.SafeLoader):
        def compose_node(self, parent: Any, index: Any) -> Any:
            if self.check_event(yaml.AliasEvent):
                mark = self.peek_event().start_mark
                raise yaml.YAMLError(
                    f"aliases are not accepted (line {mark.line + 1} column {mark.column + 1})"
                )
            return super().compose_node(parent, index)

    text = _text(raw, "YAML")
    try:
        doc = yaml.load(text, Loader=_NoAliases)
    except yaml.YAMLError as e:
        where = getattr(e, "problem_mark", None)
        at = f" at line {where.line + 1} column {where.column + 1}" if where else ""
        raise invalid("body", f"not valid YAML{at}: {getattr(e, 'problem', None) or e}") from None
    except RecursionError:
        raise nested() from None
    bad = finite_problem(doc)
    if bad is not None:
        raise invalid(*bad)
    return doc


def nested() -> Problem:
    return invalid("body", "nested too deeply (arrays or objects inside each other)")


def finite_problem(doc: Any) -> tuple[str, str] | None:
    """The path of the first non-finite number in a decoded document (NaN, Infinity, 1e400)."""
    stack: list[tuple[str, Any]] = [("", doc)]
    while stack:
        path, v = stack.pop()
        if isinstance(v, float) and not math.isfinite(v):
            return path or "body", f"{v} is not a finite number"
        if isinstance(v, dict):
            stack.extend((f"{path}.{k}" if path else str(k), x) for k, x in v.items())
        elif isinstance(v, list):
            stack.extend((f"{path}.{i}" if path else str(i), x) for i, x in enumerate(v))
    return None


def validate(model: type[M], doc: Any, prefix: str = "") -> M:
    """``doc`` as ``model``, or a 422 naming every offending field (dotted, from the body's
    root). Strict as JSON is: ``false`` is no number and ``"1"`` no integer."""
    if not isinstance(doc, dict):
        raise invalid(prefix.rstrip(".") or "body", f"expected a JSON object, got {_kind(doc)}")
    errors = type_errors(model, doc, prefix)
    if errors:
        raise invalid(errors[0][0], errors[0][1], errors)
    return model.model_validate(doc)


def type_errors(model: type[BaseModel], doc: Any, prefix: str = "") -> list[tuple[str, str]]:
    """What strict JSON validation of ``doc`` as ``model`` finds, as (field, message)."""
    try:
        model.model_validate_json(json.dumps(doc), strict=True)
    except ValidationError as e:
        return [
            (prefix + (".".join(str(p) for p in err["loc"]) or "body"), err["msg"])
            for err in e.errors()
        ]
    except RecursionError:
        raise nested() from None
    return []


def _kind(v: Any) -> str:
    return {list: "an array", str: "a string", bool: "a boolean", type(None): "null"}.get(
        type(v), "a number"
    )

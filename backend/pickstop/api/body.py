"""Request bodies: JSON decoded off the event loop, with every problem located.

FastAPI would decode a body on the event loop and before the key is checked; PickStop's routes
take the raw bytes instead (:func:`pickstop.api.deps.json_body`) and decode them here, in a
worker thread, after authentication, in the ``charset`` the content type names (UTF-8 if it
names none): not in that charset, not JSON, nested too deep, a 5,000-digit integer or a NaN
each come back as a 422 whose ``field`` is ``body`` (or the value's path) and whose detail
says where. Nesting is bounded by the decoder's recursion limit (about 1,000 levels); anything
recursing over a document later answers the same 422 (see problems.py). YAML is decoded in a
warm child process under a time limit (:mod:`pickstop.runtime.yaml_decoders`), never on the API's
interpreter.
"""

from __future__ import annotations

import codecs
import json
import math
import re
from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

from pickstop.api.problems import Problem
from pickstop.runtime import yaml_decoders

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
_NON_FINITE = re.compile(r"NaN|Infinity|\d[eE]\+?\d{3}")
_DIGITS = re.compile(r"has (\d+) digits")


def _text(raw: bytes, kind: str, charset: str = "utf-8") -> str:
    """The body as text in ``charset``, or a 422 saying it is empty or where it breaks."""
    if not raw.strip():
        raise invalid("body", f"the request needs a {kind} body")
    try:
        return raw.decode(charset)
    except UnicodeDecodeError as e:
        raise invalid("body", f"not valid {_charset_name(charset)} at byte {e.start}") from None


def _charset_name(charset: str) -> str:
    return "UTF-8" if codecs.lookup(charset).name == "utf-8" else charset


def known_charset(charset: str) -> bool:
    """Whether Python decodes bytes in ``charset`` to text (``latin-1`` yes, ``rot13`` no)."""
    try:
        return bool(getattr(codecs.lookup(charset), "_is_text_encoding", True))
    except LookupError:
        return False


def decode(raw: bytes, charset: str = "utf-8") -> Any:
    """The JSON document in ``raw``, or a 422 :class:`Problem` saying where it breaks. Costs
    one pass of the C decoder: a 1 MB scene takes milliseconds."""
    text = _text(raw, "JSON", charset)
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
    if _NON_FINITE.search(text):
        bad = finite_problem(doc)
        if bad is not None:
            raise invalid(*bad)
    return doc


#: Time [s] a YAML body may take to decode in its child process.
YAML_SECONDS = 5.0


def decode_yaml(raw: bytes, charset: str = "utf-8") -> Any:
    """The YAML document in ``raw`` as JSON values (no aliases, no types JSON lacks), or a 422
    :class:`Problem` saying where it breaks. Decoded in a warm child process
    (:mod:`pickstop.runtime.yaml_decoders`) under :data:`YAML_SECONDS`, at most two at once,
    so that no document holds this interpreter nor outlives its request."""
    text = _text(raw, "YAML", charset)
    try:
        answer = yaml_decoders.DECODERS.decode(text.encode("utf-8", "surrogatepass"), YAML_SECONDS)
        out = json.loads(answer)
    except yaml_decoders.DecodeTimeout:
        raise invalid("body", f"the YAML took more than {YAML_SECONDS:g} s to decode "
                      "(nested too deeply, or too complex)") from None  # fmt: skip
    except (yaml_decoders.ChildLost, ValueError):  # the child stopped without an answer
        raise invalid("body", "the YAML could not be decoded (nested too deeply, or too "
                      "complex)") from None  # fmt: skip
    if "error" in out:
        raise invalid("body", str(out["error"]))
    doc = out["doc"]
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
        model.model_validate_json(json.dumps(_integral(doc)), strict=True)
    except ValidationError as e:
        return [
            (prefix + (".".join(str(p) for p in err["loc"]) or "body"), err["msg"])
            for err in e.errors()
        ]
    except RecursionError:
        raise nested() from None
    return []


def _integral(doc: Any) -> Any:
    """``doc`` with every float that is a whole number written as an integer: JSON (and JSON
    Schema) do not tell ``3.0`` from ``3``, so neither does strict validation."""
    if isinstance(doc, float) and doc.is_integer() and abs(doc) < 2**64:
        return int(doc)
    if isinstance(doc, dict):
        return {k: _integral(v) for k, v in doc.items()}
    if isinstance(doc, list):
        return [_integral(v) for v in doc]
    return doc


def _kind(v: Any) -> str:
    return {list: "an array", str: "a string", bool: "a boolean", type(None): "null"}.get(
        type(v), "a number"
    )

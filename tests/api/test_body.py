"""Request bodies: YAML decoded off the API's interpreter to JSON's types only, any declared
charset, whole-number floats as integers."""

from __future__ import annotations

import time

import pytest

from pickstop.api.body import YAML_SECONDS, decode, decode_yaml, validate
from pickstop.api.problems import Problem
from pickstop.api.schemas import PlanRequest


def _cpu() -> float:
    """CPU time of the calling thread [s]: the one a decoder in this process would spend
    (the process's total counts whatever other threads a test session left running)."""
    return time.thread_time()


def test_yaml_is_decoded_in_another_process():
    """100 kB of YAML costs this process (the API's) almost no CPU: the parser runs in a
    child, whatever the document does to it."""
    doc = "items:\n" + "".join(f"  - {{a: {i}, b: [1, 2.5, x{i}], c: 's'}}\n" for i in range(2500))
    assert len(doc) > 90_000
    before = _cpu()
    out = decode_yaml(doc.encode())
    assert len(out["items"]) == 2500 and out["items"][7] == {"a": 7, "b": [1, 2.5, "x7"], "c": "s"}
    assert _cpu() - before < 0.2


def test_yaml_nested_beyond_the_parser_is_refused_in_bounded_time():
    t0 = time.perf_counter()
    with pytest.raises(Problem) as e:
        decode_yaml(b"[" * 40_000 + b"]" * 40_000)
    assert e.value.status == 422 and e.value.field == "body"
    assert time.perf_counter() - t0 < YAML_SECONDS + 3


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("name: 2024-01-01\n", "2024-01-01"),  # dates are the strings they read as
        ("name: 2024-13-45\n", "2024-13-45"),
        ("name: 2001-12-14t21:59:43.10-05:00\n", "2001-12-14t21:59:43.10-05:00"),
        ("name: !!str 12\n", "12"),
    ],
)
def test_yaml_dates_stay_strings(text, value):
    assert decode_yaml(text.encode()) == {"name": value}


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("name: !!binary aGVsbG8=\n", "!!binary is not accepted"),
        ("name: !!set {a, b}\n", "!!set is not accepted"),
        ("name: !!timestamp 2024-01-01\n", "!!timestamp is not accepted"),
        ("? !!binary aGVsbG8=\n: 1\n", "keys must be strings"),
        ("1: x\n", "keys must be strings"),
        ("name: " + "9" * 5000 + "\n", "an integer of 5000 digits"),
        ("a: &a [x]\nb: *a\n", "aliases"),
        ("a: !!python/object:os.system x\n", "is not accepted"),
    ],
)
def test_yaml_beyond_json_is_refused_saying_where(text, words):
    with pytest.raises(Problem) as e:
        decode_yaml(text.encode())
    assert e.value.status == 422 and e.value.field == "body"
    assert words in e.value.detail and "line 1" in e.value.detail, e.value.detail


@pytest.mark.parametrize("charset", ["latin-1", "utf-16", "cp1252"])
def test_the_declared_charset_is_honoured(charset):
    raw = '{"name": "caf\u00e9"}'.encode(charset)
    assert decode(raw, charset) == {"name": "caf\u00e9"}
    assert decode_yaml("name: caf\u00e9\n".encode(charset), charset) == {"name": "caf\u00e9"}


def test_a_whole_number_float_is_an_integer():
    """JSON Schema's integer includes 3.0: so does validation."""
    body = validate(PlanRequest, {"scene_id": "s", "options": {"seed": 10964587078361.0}})
    assert body.options.seed == 10964587078361
    with pytest.raises(Problem) as e:
        validate(PlanRequest, {"scene_id": "s", "options": {"seed": 1.5}})
    assert e.value.field == "options.seed"

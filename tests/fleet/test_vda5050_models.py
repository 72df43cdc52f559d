"""The message models against the published VDA 5050 schemas, field by field."""

from __future__ import annotations

import pytest

from pickstop.fleet import published
from pickstop.fleet import vda5050 as v
from tests.fleet.schema_walk import flatten

MODELS = [
    ("order", "2.0.0", v.Order20),
    ("state", "2.0.0", v.State20),
    ("connection", "2.0.0", v.Connection21),
    ("instantActions", "2.0.0", v.InstantActions2),
    ("instantActions", "2.1.0", v.InstantActions2),
    ("instantActions", "3.0.0", v.InstantActions30),
    ("order", "2.1.0", v.Order21),
    ("order", "3.0.0", v.Order30),
    ("state", "2.1.0", v.State21),
    ("state", "3.0.0", v.State30),
    ("connection", "2.1.0", v.Connection21),
    ("connection", "3.0.0", v.Connection30),
]


def official(kind: str, version: str) -> dict:
    return published.schema(kind, version)


@pytest.mark.parametrize(("kind", "version", "model"), MODELS)
def test_model_matches_the_published_schema_field_by_field(kind, version, model):
    theirs = flatten(official(kind, version))
    ours = flatten(model.model_json_schema(by_alias=True))
    assert sorted(set(theirs) - set(ours)) == [], "fields of the schema the model lacks"
    assert sorted(set(ours) - set(theirs)) == [], "fields the model adds to the schema"
    wrong = {p: (ours[p], theirs[p]) for p in theirs if ours[p] != theirs[p]}
    assert wrong == {}

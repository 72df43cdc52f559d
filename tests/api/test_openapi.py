"""The OpenAPI document says what the service answers: statuses, media types, required
headers, the rules between fields."""

from __future__ import annotations

import pytest

from .conftest import AUTH


@pytest.fixture(scope="module")
def spec(client):
    return client.get("/api/v1/openapi.json").json()


@pytest.mark.parametrize("path", ["check", "model", "files/x"])
def test_an_unknown_robot_is_404_as_documented(client, spec, path):
    r = client.get(f"/api/v1/robots/no_such_robot/{path}")
    assert r.status_code == 404, r.text
    template = "/api/v1/robots/{name}/" + ("files/{file_id}" if path == "files/x" else path)
    assert "404" in spec["paths"][template]["get"]["responses"]


def test_if_match_is_required_and_its_absence_is_428(client, spec, paper_doc):
    for method in ("put", "delete"):
        op = spec["paths"]["/api/v1/scenes/{scene_id}"][method]
        (param,) = [p for p in op["parameters"] if p["name"].lower() == "if-match"]
        assert param["required"] is True and "428" in op["responses"]
    sid = client.post("/api/v1/scenes", json=paper_doc, headers=AUTH).json()["id"]
    assert client.delete(f"/api/v1/scenes/{sid}", headers=AUTH).status_code == 428


def test_the_yaml_export_is_documented(spec):
    content = spec["paths"]["/api/v1/plans/{plan_id}/export"]["get"]["responses"]["200"]["content"]
    assert {"application/json", "application/yaml"} <= set(content)


def test_the_rules_between_fields_are_in_the_schemas(spec):
    schemas = spec["components"]["schemas"]
    for name in ("PlanRequest", "BatchItem"):
        branches = schemas[name]["oneOf"]
        assert [b["required"] for b in branches] == [["scene_id"], ["scene"]]
    hand = schemas["Hand"]["properties"]
    assert hand["approach_axis"]["not"] == {"type": "array", "items": {"const": 0}}
    assert schemas["RobotConfig"]["properties"]["approach_axis"]["not"]["type"] == "array"
    assert "perpendicular" in hand["closing_axis"]["description"]
    assert "min below max" in schemas["Extent"]["description"]


def test_an_integral_float_is_an_integer_as_json_schema_says(client, spec, paper_doc):
    assert spec["components"]["schemas"]["PlanOptions"]["properties"]["seed"]["type"] == "integer"
    body = {"scene": paper_doc, "options": {"samples": 0, "seed": 10964587078361.0},
            "store": False}  # fmt: skip
    r = client.post("/api/v1/plans", json=body, headers=AUTH)
    assert r.status_code == 200, r.text
    assert r.json()["plan"]["parameters"]["seed"] == 10964587078361

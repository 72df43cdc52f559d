"""LIF 2.0 layouts of the example plans: the published schema (strictly: no property it does not
name), a station per stop on its interaction node, the picks and the allowed deviation."""

from __future__ import annotations

import copy
import json

import jsonschema
import pytest

from pickstop.errors import InputError
from pickstop.fleet import published
from pickstop.fleet.lif import LIF_VERSION, LifOptions, build_lif
from pickstop.fleet.vehicle_types import PickAction
from pickstop.frames import wrap_angle
from tests.fleet.conftest import SCENES


def strict(schema: dict) -> dict:
    """The schema with ``additionalProperties: false`` on every object that lists its
    properties: a misspelt or invented field fails."""
    s = copy.deepcopy(schema)

    def walk(node):
        if isinstance(node, dict):
            if node.get("type") == "object" and "properties" in node:
                node.setdefault("additionalProperties", False)
            for v in node.values():
                walk(v)
        elif isinstance(node, list):
            for v in node:
                walk(v)

    walk(s)
    return s


LIF = strict(published.schema("lif", LIF_VERSION))


def test_the_vendored_schema_is_the_published_draft_and_strict_catches_a_typo():
    raw = published.schema("lif", "2.0.0")
    assert raw["title"] == "Layout Interchange Format"
    assert "stations" in raw["definitions"]["layout"]["required"]
    jsonschema.Draft7Validator.check_schema(raw)
    meta = {"projectIdentification": "p", "creator": "c", "exportTimestamp": "t"}
    bad = {"metaInformation": {**meta, "lifVersion": "2.0.0", "colour": "red"}, "layouts": []}
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(bad, LIF)


@pytest.mark.parametrize("name", SCENES)
def test_layouts_of_every_example_validate(example_plans, name):
    scene, plan = example_plans[name]
    doc = build_lif(plan, LifOptions(start_yaw=scene.start.yaw, goal_yaw=scene.goal.yaw,
                                     timestamp="2026-01-01T00:00:00.000Z"))  # fmt: skip
    jsonschema.validate(doc, LIF)
    (layout,) = doc["layouts"]
    nodes = {n["nodeId"]: n for n in layout["nodes"]}
    assert len(nodes) == len(layout["nodes"])
    assert all(e["startNodeId"] in nodes and e["endNodeId"] in nodes for e in layout["edges"])
    assert len(layout["stations"]) == len(plan.stops)
    for st, s in zip(layout["stations"], plan.stops, strict=True):
        (nid,) = st["interactionNodeIds"]
        node = nodes[nid]
        assert node["nodePosition"] == {"x": s.x, "y": s.y}
        (prop,) = node["vehicleTypeNodeProperties"]
        assert prop["theta"] == pytest.approx(wrap_angle(s.yaw), abs=1e-12)
        picks = prop["actions"]
        assert len(picks) == len(s.witnesses)
        assert {p["requirementType"] for p in picks} == {"REQUIRED"}
        keys = {a["key"]: a["value"] for a in picks[0]["actionParameters"]}
        assert keys["trayId"] == s.witnesses[0].tray_id
        assert json.loads(keys["jointPositions"]) == pytest.approx(s.witnesses[0].theta, abs=1e-6)
        (arrive,) = [e for e in layout["edges"] if e["endNodeId"] == nid]
        dev = arrive["vehicleTypeEdgeProperties"][0]["allowedDeviationXY"]
        assert dev == {"a": s.inscribed_radius, "b": s.inscribed_radius, "theta": 0.0}


def test_checked_shapes_and_a_vehicle_type_reach_the_layout(example_plans, planner):
    from pickstop.fleet.pickcheck import PickChecker

    scene, plan = example_plans["paper_experiment"]
    shapes = PickChecker(planner, scene).shapes(plan)
    pick = PickAction(action_type="pickPart", parameters={"station": "trayId"})
    doc = build_lif(plan, LifOptions(vehicle_type_id="acme.MM-1", shapes=shapes, pick=pick))
    jsonschema.validate(doc, LIF)
    (layout,) = doc["layouts"]
    for st, sh in zip(layout["stations"], shapes, strict=True):
        (arrive,) = [e for e in layout["edges"] if e["endNodeId"] == st["interactionNodeIds"][0]]
        (prop,) = arrive["vehicleTypeEdgeProperties"]
        assert prop["vehicleTypeId"] == "acme.MM-1"
        e = sh.ellipse
        assert prop["allowedDeviationXY"] == {"a": e.a, "b": e.b, "theta": e.theta}
    node = next(n for n in layout["nodes"] if n["nodeId"] == layout["stations"][0]
                ["interactionNodeIds"][0])  # fmt: skip
    act = node["vehicleTypeNodeProperties"][0]["actions"][0]
    assert act["actionType"] == "pickPart" and [p["key"] for p in act["actionParameters"]] == [
        "station"
    ]
    with pytest.raises(InputError) as e:
        build_lif(plan, LifOptions(vehicle_type_id=""))
    assert e.value.field == "vehicle_type_id"
    json.dumps(doc)  # plain JSON

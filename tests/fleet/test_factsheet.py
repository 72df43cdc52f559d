"""Factsheets: the simulated vehicle's validate against the published schemas of every
version, and an order asking for an action, parameter, data type, size or protocol version the
factsheet does not list is refused naming it."""

from __future__ import annotations

import jsonschema
import pytest

from pickstop.errors import InputError
from pickstop.fleet import factsheet as fs
from pickstop.fleet import order as od
from pickstop.fleet import published
from pickstop.fleet.vehicle_types import DEFAULT_PICK, PickAction

PICK_PART = PickAction(
    action_type="pickPart",
    parameters={"station": "trayId", "load": "partId"},
    constants={"stationType": "TRAY"},
)


def sheet(version: str = "2.0.0", pick: PickAction = DEFAULT_PICK, **change) -> dict:
    doc = fs.describe(version, "acme", "mm-1", [fs.pick_spec(pick)], fs.Body(series_name="MM-1"))
    for k, val in change.items():
        doc[k] = val
    return doc


@pytest.mark.parametrize("version", ["2.0.0", "2.1.0", "3.0.0"])
@pytest.mark.parametrize("pick", [DEFAULT_PICK, PICK_PART])
def test_a_described_factsheet_validates_and_reads_back(version, pick):
    doc = sheet(version, pick)
    jsonschema.validate(doc, published.schema("factsheet", version))
    caps = fs.read(doc)
    assert caps.version == version and caps.series_name == "MM-1"
    spec = caps.actions[pick.action_type]
    assert spec.scopes == {"NODE"}
    assert set(spec.parameters) == set(pick.parameters) | set(pick.constants)
    assert caps.actions["factsheetRequest"].scopes == {"INSTANT"}


@pytest.mark.parametrize("version", ["2.0", "2.1", "3.0"])
def test_an_order_with_the_vehicles_own_pick_passes(example_plans, version):
    _, plan = example_plans["five_trays"]
    order = od.build_order(plan, od.OrderOptions(version=version, pick=PICK_PART))
    caps = fs.read(sheet(order.version, PICK_PART))
    assert fs.check_order(order, caps) == []


def test_pickstops_own_pick_is_refused_by_a_vehicle_that_calls_it_pickpart(example_plans):
    _, plan = example_plans["five_trays"]
    order = od.build_order(plan, od.OrderOptions(version="2.0"))
    problems = fs.check_order(order, fs.read(sheet("2.0.0", PICK_PART)))
    assert problems == [
        "the vehicle's factsheet lists no action 'pick' (it lists: factsheetRequest, pickPart)"
    ]


def test_each_missing_or_extra_parameter_and_wrong_type_is_named(example_plans):
    _, plan = example_plans["paper_experiment"]
    doc = sheet("2.0.0", PICK_PART)
    params = doc["protocolFeatures"]["agvActions"][0]["actionParameters"]
    params[:] = [
        {"key": "station", "valueDataType": "STRING"},
        {"key": "load", "valueDataType": "INTEGER"},  # the order sends a string
        {"key": "lhd", "valueDataType": "STRING"},  # required, never sent
        {"key": "height", "valueDataType": "NUMBER", "isOptional": True},  # optional: fine
    ]
    order = od.build_order(plan, od.OrderOptions(version="2.0", pick=PICK_PART))
    problems = fs.check_order(order, fs.read(doc))
    assert problems == [
        "parameter 'load' of action 'pickPart' must be INTEGER, the order sends str",
        "action 'pickPart' has no parameter 'stationType' in the vehicle's factsheet (it lists: "
        "station, load, lhd, height)",
        "action 'pickPart' requires parameter 'lhd', which the order does not send",
    ]


def test_scopes_blocking_limits_versions_and_required_fields(example_plans):
    _, plan = example_plans["five_trays"]
    doc = sheet("2.0.0")
    act = doc["protocolFeatures"]["agvActions"][0]
    act["actionScopes"] = ["EDGE"]
    act["blockingTypes"] = ["NONE", "SOFT"]
    doc["protocolLimits"]["maxArrayLens"] = {"order.nodes": 3, "node.actions": 0}
    doc["protocolFeatures"]["optionalParameters"].append(
        {"parameter": "order.edges.trajectory", "support": "REQUIRED"}
    )
    order = od.build_order(plan, od.OrderOptions(version="2.1"))
    problems = fs.check_order(order, fs.read(doc))
    assert problems[0] == "the order is VDA 5050 2.1.0, the vehicle speaks 2.0.0 (its factsheet)"
    assert problems[1].startswith("order.nodes: the order has ") and "at most 3" in problems[1]
    assert "action 'pick' is not allowed on nodes (scopes: EDGE)" in problems
    assert "action 'pick': blocking type HARD is not one of NONE, SOFT" in problems
    assert problems[-1] == (
        "the vehicle requires order.edges.trajectory, which the order does not carry"
    )
    assert not any("node.actions" in p for p in problems)  # 0: no limit


def test_a_3_0_factsheet_names_its_actions_mobile_robot_actions(example_plans):
    _, plan = example_plans["paper_experiment"]
    doc = sheet("3.0.0", PICK_PART)
    assert "mobileRobotActions" in doc["protocolFeatures"]
    order = od.build_order(plan, od.OrderOptions(version="3.0"))
    assert fs.check_order(order, fs.read(doc))[0].startswith(
        "the vehicle's factsheet lists no action 'pick'"
    )


def test_an_unusable_factsheet_names_the_field():
    doc = sheet()
    del doc["protocolFeatures"]
    with pytest.raises(InputError) as e:
        fs.read(doc)
    assert e.value.field == "factsheet.protocolFeatures"

"""Vehicle types: a configured pick mapping renames the action and its parameters in the order
and the simulated vehicle executes it; files with mistakes are refused naming the field."""

from __future__ import annotations

import pytest
import yaml

from pickstop.errors import InputError
from pickstop.fleet import order as od
from pickstop.fleet import vda5050 as v
from pickstop.fleet.execution import vehicle_for
from pickstop.fleet.pickcheck import PickChecker
from pickstop.fleet.tracker import OrderTracker
from pickstop.fleet.vehicle_types import (
    VehicleTypes,
    load_vehicle_types,
    parse_vehicle_types,
)

TYPES = {
    "format": "pickstop.vehicles",
    "version": 1,
    "vehicle_types": [
        {
            "name": "mm1",
            "manufacturer": "acme",
            "series_name": "MM-1",
            "pick": {
                "action_type": "pickPart",
                "parameters": {"station": "trayId", "load": "partId"},
                "constants": {"stationType": "TRAY"},
            },
        },
        {"name": "acme-any", "manufacturer": "acme"},
    ],
}


def test_a_mapping_renames_the_action_type_and_its_parameters(example_plans):
    scene, plan = example_plans["five_trays"]
    vt = parse_vehicle_types(TYPES).select("acme", "x", "MM-1")
    assert vt is not None and vt.name == "mm1"
    order = od.build_order(plan, od.OrderOptions(version="2.0", pick=vt.pick))
    actions = [a for n in order.nodes for a in n.actions]
    assert len(actions) == sum(len(scene.tray(t).parts) for s in plan.stops for t in s.trays)
    for n, s in zip([n for n in order.nodes if n.actions], plan.stops, strict=True):
        got = {(p["station"], p["load"]) for p in _params(n)}
        assert got == {(t, part.id) for t in s.trays for part in scene.tray(t).parts}
        for a in n.actions:
            assert a.action_type == "pickPart" and a.blocking_type == "HARD"
            assert [q.key for q in a.action_parameters] == ["station", "load", "stationType"]
            assert a.action_parameters[2].value == "TRAY"


def _params(node) -> list[dict]:
    return [{q.key: q.value for q in a.action_parameters} for a in node.actions]


def test_selection_by_name_manufacturer_series_and_serial():
    types = parse_vehicle_types(TYPES)
    assert types.select("acme", "x", "MM-1").name == "mm1"
    assert types.select("acme", "x", None).name == "acme-any"  # the series is unknown
    assert types.select("acme", "x", "MM-2").name == "acme-any"
    assert types.select("other", "x", "MM-1") is None
    assert types.select("other", "x", None, name="mm1").name == "mm1"
    with pytest.raises(InputError, match=r"no vehicle type 'nope' \(known: mm1, acme-any\)"):
        types.select("acme", "x", None, name="nope")
    serials = parse_vehicle_types(
        {"vehicle_types": [{"name": "two", "serial_numbers": ["a", "b"]}]}
    )
    assert serials.select("m", "b").name == "two" and serials.select("m", "c") is None
    assert VehicleTypes().select("acme", "x") is None


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (lambda d: d.update(format="other"), "format"),
        (lambda d: d["vehicle_types"][0]["pick"]["parameters"].update(load="weight"),
         "vehicle_types.0.pick.parameters.load"),
        (lambda d: d["vehicle_types"][0]["pick"]["constants"].update(load=1),
         "vehicle_types.0.pick"),
        (lambda d: d["vehicle_types"][1].update(name="mm1"), "(root)"),
        (lambda d: d["vehicle_types"][0].update(colour="red"), "vehicle_types.0.colour"),
    ],
)  # fmt: skip
def test_a_bad_vehicle_types_file_names_the_field(tmp_path, change, field):
    import copy

    doc = copy.deepcopy(TYPES)
    change(doc)
    path = tmp_path / "types.yaml"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(InputError) as e:
        load_vehicle_types(path)
    assert e.value.field == field, e.value.message
    path.write_text(yaml.safe_dump(TYPES))
    assert load_vehicle_types(path).vehicle_types[0].pick.action_type == "pickPart"
    path.write_text("a: [")
    with pytest.raises(InputError, match="not YAML"):
        load_vehicle_types(path)


def test_the_simulated_vehicle_runs_a_mapped_order_and_refuses_pickstops_own(
    example_plans, planner
):
    scene, plan = example_plans["paper_experiment"]
    vt = parse_vehicle_types(TYPES).select("acme", "x", "MM-1")
    veh = vehicle_for(plan, PickChecker(planner, scene), seed=0, version="2.0.0")
    veh.pick = vt.pick
    veh.forced_error = (0.0, 0.0, 0.0)
    plain = od.build_order(plan, od.OrderOptions(version="2.0", order_id="plain"))
    assert not veh.accept(v.dump(plain))
    err = veh.state()["errors"][0]
    assert err["errorType"] == "orderError"
    assert err["errorDescription"].startswith(
        "order action is not executable: the vehicle's factsheet lists no action 'pick'"
    )
    order = od.build_order(plan, od.OrderOptions(version="2.0", pick=vt.pick))
    tracker = OrderTracker(order)
    assert veh.accept(v.dump(order))
    while veh.busy:
        veh.advance(veh.next_event())
        tracker.update(veh.state())
    s = tracker.summary()
    assert s["done"] and s["actions_finished"] == s["actions"] > 0
    results = [a["result"] for a in tracker.actions.values()]
    assert all(r.startswith("part ") and "graspable" in r for r in results)


def test_a_2_0_vehicle_refuses_a_newer_order(example_plans, planner):
    scene, plan = example_plans["paper_experiment"]
    veh = vehicle_for(plan, PickChecker(planner, scene), seed=0, version="2.0.0")
    assert not veh.accept(v.dump(od.build_order(plan, od.OrderOptions(version="2.1"))))
    assert veh.state()["errors"][0]["errorDescription"] == (
        "order version 2.1.0 is not compatible with vehicle version 2.0.0"
    )
    assert veh.accept(v.dump(od.build_order(plan, od.OrderOptions(version="2.0"))))

"""Live over MQTT with a Mosquitto of the test's own on 127.0.0.1: dispatch to a simulated
vehicle, a broker restart in the middle of an order, and executed against predicted success."""

from __future__ import annotations

import threading
import time

import pytest

from pickstop.fleet import order as od
from pickstop.fleet.dispatch import Dispatcher, DispatchError
from pickstop.fleet.execution import execute, report, table, vehicle_for
from pickstop.fleet.pickcheck import PickChecker
from pickstop.fleet.sim_node import VehicleNode

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def paper(example_plans, planner):
    scene, plan = example_plans["paper_experiment"]
    return scene, plan, PickChecker(planner, scene)


def test_dispatch_to_a_simulated_vehicle_completes_the_order(mosquitto, paper):
    _, plan, check = paper
    veh = vehicle_for(plan, check, seed=0)
    veh.forced_error = (0.0, 0.0, 0.0)
    node = VehicleNode(veh, mosquitto.broker, rate_hz=20, time_scale=200).start()
    d = Dispatcher(mosquitto.broker, veh.manufacturer, veh.serial_number).start()
    try:
        order = od.build_order(plan)
        seen = []
        s = d.run(order, timeout=60, progress=seen.append)
    finally:
        d.stop()
        node.stop()
    assert s["done"] and s["reached"] == [n.node_id for n in order.nodes]
    assert s["actions_finished"] == s["actions"] > 0 and s["actions_failed"] == 0
    assert all(st["status"] == "finished" for st in s["stops"])
    assert s["latency"] is not None and 0 <= s["latency"] < 2.0
    assert len(seen) >= 2 and seen[-1] == s  # progress reported on the way and at the end


def test_the_tracker_survives_a_broker_restart(mosquitto, paper):
    _, plan, check = paper
    veh = vehicle_for(plan, check, seed=0)
    veh.forced_error = (0.0, 0.0, 0.0)
    # ~60 s of simulated order in about 3 s of wall time
    node = VehicleNode(veh, mosquitto.broker, rate_hz=20, time_scale=20).start()
    d = Dispatcher(mosquitto.broker, veh.manufacturer, veh.serial_number).start()
    order = od.build_order(plan)
    out: dict = {}

    def run() -> None:
        try:
            out["summary"] = d.run(order, timeout=60)
        except DispatchError as e:
            out["error"] = e

    t = threading.Thread(target=run)
    try:
        t.start()
        t_end = time.monotonic() + 20
        while time.monotonic() < t_end and not (d.tracker and len(d.tracker.reached) >= 2):
            time.sleep(0.02)
        assert d.tracker is not None and 2 <= len(d.tracker.reached) < len(order.nodes)
        mosquitto.restart()  # same port; both clients must reconnect by themselves
        t.join(60)
    finally:
        d.stop()
        node.stop()
    assert "error" not in out, out.get("error")
    s = out["summary"]
    assert s["done"] and s["reached"] == [n.node_id for n in order.nodes]
    assert s["actions_finished"] == s["actions"]
    assert d.link.connects >= 2 and node.link.connects >= 2


def test_dispatch_without_a_vehicle_says_so(mosquitto, paper):
    _, plan, _ = paper
    d = Dispatcher(mosquitto.broker, "nobody", "none").start()
    try:
        with pytest.raises(DispatchError, match="no vehicle"):
            d.run(od.build_order(plan, od.OrderOptions(manufacturer="nobody")), wait_vehicle=0.3)
    finally:
        d.stop()


def test_executed_success_lies_within_the_predicted_interval(mosquitto, paper):
    """The paper-like scene, its sigma-rule plan: 80 executions of the order, each stop
    landing off by the scene's error model and each pick checked exactly."""
    _, plan, check = paper
    outcomes = execute(plan, check, runs=80, seed=5, broker=mosquitto.broker)
    rep = report(plan, outcomes)
    print(table(rep))
    lo, hi = rep["plan"]["executed_interval"]
    plo, phi = rep["plan"]["predicted_interval"]
    assert lo <= rep["plan"]["predicted"] <= hi  # the prediction within the executed interval
    assert plo <= rep["plan"]["executed"] <= phi or (lo <= phi and plo <= hi)
    for s in rep["stops"]:
        elo, ehi = s["executed_interval"]
        assert elo <= s["predicted"] <= ehi
    t = rep["time"]
    assert t["executed_mean"] == pytest.approx(t["predicted"], rel=0.03)


@pytest.mark.parametrize("version", ["2.1.0", "3.0.0"])
def test_connection_messages_follow_the_schema(mosquitto, paper, version):
    import json
    from pathlib import Path

    import jsonschema

    from pickstop.fleet import vda5050 as v
    from pickstop.fleet.mqtt import Link

    _, plan, check = paper
    veh = vehicle_for(plan, check, seed=0, version=version)
    schema = json.loads(
        (Path(v.__file__).parent / "schemas" / f"connection-{version}.schema.json").read_text()
    )
    got: list[dict] = []
    watcher = Link(mosquitto.broker)
    topic = f"uagv/{v.major(version)}/{veh.manufacturer}/{veh.serial_number}/connection"
    watcher.subscribe(topic, lambda _t, doc: got.append(doc), qos=1)
    watcher.start()
    try:
        node = VehicleNode(veh, mosquitto.broker).start()
        t_end = time.monotonic() + 5
        while time.monotonic() < t_end and not got:
            time.sleep(0.02)
        node.stop()
        while time.monotonic() < t_end and len(got) < 2:
            time.sleep(0.02)
    finally:
        watcher.stop()
    assert [g["connectionState"] for g in got[:2]] == ["ONLINE", "OFFLINE"]
    for g in got:
        jsonschema.validate(g, schema)


def test_a_refused_order_fails_the_dispatch_with_the_vehicles_reason(mosquitto, paper):
    _, plan, check = paper
    veh = vehicle_for(plan, check, seed=0)
    node = VehicleNode(veh, mosquitto.broker, rate_hz=5, time_scale=0).start()
    d = Dispatcher(mosquitto.broker, veh.manufacturer, veh.serial_number).start()
    try:
        order = od.build_order(plan, od.OrderOptions(order_id="broken"))
        bad = order.model_copy(deep=True)
        bad.nodes[1].sequence_id = 3  # odd: nodes must be even
        with pytest.raises(DispatchError, match=r"refused order broken.*sequenceId is odd"):
            d.run(bad, timeout=20)
        # the next, valid order runs: the old refusal does not stick to it
        s = d.run(od.build_order(plan, od.OrderOptions(order_id="good")), timeout=60)
        assert s["done"] and s["nodes_reached"] == s["nodes"]
    finally:
        d.stop()
        node.stop()


def test_a_vehicle_whose_factsheet_lacks_the_pick_gets_no_order(mosquitto, paper):
    """A 2.0.0 vehicle whose controller calls a pick ``pickPart`` (``station``, ``load``):
    PickStop's own pick is refused, naming it, before anything is sent; the vehicle type of its
    series maps the pick onto it and the order runs to the end."""
    from dataclasses import replace

    from pickstop.fleet.dispatch import VehicleRefusal, checked_order
    from pickstop.fleet.factsheet import Body
    from pickstop.fleet.vehicle_types import parse_vehicle_types
    from tests.fleet.test_vehicle_types import TYPES

    _, plan, check = paper
    types = parse_vehicle_types(TYPES)
    veh = vehicle_for(plan, check, seed=0, version="2.0.0")
    veh.manufacturer, veh.serial_number = "acme", "mm-7"
    veh.pick, veh.body = types.vehicle_types[0].pick, Body(series_name="MM-1")
    veh.forced_error = (0.0, 0.0, 0.0)
    node = VehicleNode(veh, mosquitto.broker, rate_hz=20, time_scale=0).start()
    d = Dispatcher(mosquitto.broker, "acme", "mm-7", "2.0.0").start()
    opts = od.OrderOptions(version="2.0", manufacturer="acme", serial_number="mm-7")
    try:
        with pytest.raises(VehicleRefusal) as e:
            checked_order(d, lambda pick: od.build_order(plan, replace(opts, pick=pick)))
        assert "lists no action 'pick' (it lists: factsheetRequest, pickPart)" in e.value.message
        assert e.value.exit_code == 3
        time.sleep(0.3)
        assert veh.order_id == "" and node._inbox.empty()  # nothing was sent
        order, vt = checked_order(
            d, lambda pick: od.build_order(plan, replace(opts, pick=pick)), types
        )
        assert vt.name == "mm1" and order.nodes[2].actions[0].action_type == "pickPart"
        s = d.run(order, timeout=60)
    finally:
        d.stop()
        node.stop()
    assert s["done"] and s["actions_finished"] == s["actions"] > 0


def test_a_factsheet_is_asked_for_when_none_is_retained(mosquitto, paper):
    from pickstop.fleet.mqtt import Link

    _, plan, check = paper
    veh = vehicle_for(plan, check, seed=0)
    node = VehicleNode(veh, mosquitto.broker).start()
    topic = node.topics["factsheet"]
    try:
        wipe = Link(mosquitto.broker).start()
        time.sleep(0.2)
        wipe.client.publish(topic, b"", qos=1, retain=True).wait_for_publish(5)
        wipe.stop()
        d = Dispatcher(mosquitto.broker, veh.manufacturer, veh.serial_number).start()
        try:
            caps = d.read_factsheet(wait=5, ask_after=0.3)
        finally:
            d.stop()
    finally:
        node.stop()
    assert caps.series_name == "pickstop-sim" and "pick" in caps.actions
    assert node._factsheet_header >= 1  # published again, on request


def test_dispatch_to_a_vehicle_without_a_factsheet_says_so(mosquitto):
    d = Dispatcher(mosquitto.broker, "nobody", "none").start()
    try:
        with pytest.raises(DispatchError, match="no factsheet on uagv/v2/nobody/none/factsheet"):
            d.read_factsheet(wait=0.5, ask_after=0.2)
    finally:
        d.stop()

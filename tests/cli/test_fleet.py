"""The fleet commands: export to files, bad input exits 2 naming the field, dispatch and
sim-vehicle over a live Mosquitto, execute-sim prints and writes its report."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time

import pytest

from pickstop.cli import main
from pickstop.fleet import nav2
from tests.cli.conftest import EXAMPLES


def test_export_writes_vda5050_and_nav2(plan_file, tmp_path, capsys):
    scene = str(EXAMPLES / "paper_experiment.json")
    out = tmp_path / "order.json"
    args = ["export", str(plan_file), "--format", "vda5050", "--out", str(out), "--scene", scene]
    assert main([*args, "--vda-version", "3.0"]) == 0
    order = json.loads(out.read_text())
    assert order["version"] == "3.0.0" and order["nodes"][-1]["nodePosition"]["theta"]
    y = tmp_path / "goal.yaml"
    assert main(["export", str(plan_file), "--format", "nav2", "--out", str(y)]) == 0
    assert nav2.loads(y.read_text())["distro"] == "jazzy"
    capsys.readouterr()
    assert main(["export", str(plan_file), "--format", "vda5050"]) == 0
    assert json.loads(capsys.readouterr().out)["version"] == "2.1.0"


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--vda-version", "9"], "vda_version"),
        (["--manufacturer", "a+b"], "manufacturer"),
        (["--scene", str(EXAMPLES / "five_trays.json")], "not the scene this plan was made for"),
    ],
)
def test_bad_export_input_exits_2_naming_it(plan_file, capsys, extra, message):
    assert main(["export", str(plan_file), "--format", "vda5050", *extra]) == 2
    assert message in capsys.readouterr().err


def test_a_bad_plan_file_exits_2(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "pickstop.plan"}')
    assert main(["export", str(bad), "--format", "nav2"]) == 2
    assert "plan" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "missing.json"), "--format", "nav2"]) == 2
    assert main(["dispatch", str(bad), "--broker", "http://x"]) == 2


@pytest.mark.slow
def test_dispatch_to_sim_vehicle_processes(plan_file, mosquitto, region_db, tmp_path):
    """Both commands as separate processes, as a user runs them."""
    folder, db = region_db
    url = mosquitto.broker.url
    env_cmd = [sys.executable, "-m", "pickstop.cli", "--data-dir", str(folder)]
    veh = subprocess.Popen(
        [*env_cmd, "sim-vehicle", "--broker", url, "--scene",
         str(EXAMPLES / "paper_experiment.json"), "--serial", "agv-9", "--time-scale", "0",
         "--sigma", "0", "--db", db.id],
        stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        line = veh.stdout.readline()  # printed once connected
        assert "agv-9/order" in line
        t0 = time.monotonic()
        r = subprocess.run(
            [*env_cmd, "dispatch", str(plan_file), "--broker", url, "--serial", "agv-9",
             "--quiet", "--timeout", "120"],
            capture_output=True, text=True, timeout=180,
        )  # fmt: skip
        assert r.returncode == 0, r.stderr
        summary = json.loads(r.stdout)
        assert summary["done"] and summary["nodes_reached"] == summary["nodes"]
        assert summary["actions_finished"] == summary["actions"]
        assert time.monotonic() - t0 < 120
    finally:
        veh.terminate()
        veh.wait(10)


@pytest.mark.slow
def test_execute_sim_prints_and_writes_the_report(plan_file, region_db, tmp_path, capsys):
    folder, db = region_db
    out = tmp_path / "report.json"
    code = main(
        ["--data-dir", str(folder), "execute-sim", str(plan_file), "--scene",
         str(EXAMPLES / "paper_experiment.json"), "--runs", "10", "--out", str(out),
         "--db", db.id]
    )  # fmt: skip
    assert code == 0
    printed = capsys.readouterr().out
    assert "executed" in printed and "predicted" in printed and "stop 0" in printed
    rep = json.loads(out.read_text())
    assert rep["runs"] == 10 and len(rep["stops"]) == len(rep["stops"]) >= 1
    assert 0 <= rep["plan"]["executed"] <= 1
    # the plan's failure model runs with it: re-docks and operator calls beside the expected
    assert "expected" in printed and "re-docks per run" in printed
    assert rep["time"]["expected"] >= rep["time"]["predicted"]
    assert rep["recovery"]["retries_mean"] >= 0 and rep["recovery"]["retries_expected"] >= 0
    assert main(["execute-sim", str(plan_file), "--scene", "x.json", "--runs", "0"]) == 2


def test_verify_yaw_sets_each_stops_tolerance_from_exact_checks(
    plan_file, example_plans, planner, region_db, tmp_path
):
    from pickstop.fleet.pickcheck import PickChecker
    from pickstop.fleet.yaw import STEP, verified_yaw_tolerance

    scene, plan = example_plans["paper_experiment"]
    check = PickChecker(planner, scene)
    tol = verified_yaw_tolerance(check, plan.stops[0])
    assert 0 <= tol <= math.radians(10) and round(tol / STEP, 9) % 1 == 0
    if tol > 0:  # every offset up to it passes, both ways
        assert all(check(t, plan.stops[0].x, plan.stops[0].y, plan.stops[0].yaw - tol)[0]
                   for t in plan.stops[0].trays)  # fmt: skip
    folder, db = region_db
    out = tmp_path / "order.json"
    scene_file = str(EXAMPLES / "paper_experiment.json")
    args = ["--data-dir", str(folder), "export", str(plan_file), "--format", "vda5050",
            "--scene", scene_file, "--verify-yaw", "--db", db.id, "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    nodes = [n for n in json.loads(out.read_text())["nodes"] if n["actions"]]
    assert nodes[0]["nodePosition"]["allowedDeviationTheta"] == pytest.approx(tol)
    assert main(["export", str(plan_file), "--format", "nav2", "--verify-yaw"]) == 2


def test_verify_xy_exports_the_checked_ellipse_and_circle(plan_file, region_db, tmp_path):
    """``--verify-xy``: a 3.0 order's stops carry the checked ellipse, a 2.1 order's and a
    Nav2 goal's the checked circle; without ``--scene`` it is refused (exit 2)."""
    folder, db = region_db
    scene_file = str(EXAMPLES / "paper_experiment.json")
    common = ["--scene", scene_file, "--verify-xy", "--db", db.id]
    got = {}
    for version in ("3.0", "2.1"):
        out = tmp_path / f"order-{version}.json"
        args = ["--data-dir", str(folder), "export", str(plan_file), "--format", "vda5050",
                "--vda-version", version, *common, "--out", str(out)]  # fmt: skip
        assert main(args) == 0
        nodes = [n for n in json.loads(out.read_text())["nodes"] if n["actions"]]
        got[version] = [n["nodePosition"]["allowedDeviationXY"] for n in nodes]
    assert got["3.0"] and all(set(e) == {"a", "b", "theta"} for e in got["3.0"])
    assert all(e["a"] >= e["b"] > 0 for e in got["3.0"])
    assert all(e["a"] * e["b"] >= r * r for e, r in zip(got["3.0"], got["2.1"], strict=True))
    plan = json.loads(plan_file.read_text())
    # the checked circle is the plan's inscribed radius or less (a failing pose shrinks it)
    assert all(r <= s["inscribed_radius"] for r, s in zip(got["2.1"], plan["stops"], strict=True))
    assert main(["export", str(plan_file), "--format", "nav2", "--verify-xy"]) == 2


def test_export_lif_writes_a_layout_with_a_station_per_stop(plan_file, tmp_path):
    import jsonschema

    from pickstop.fleet import published

    out = tmp_path / "layout.lif.json"
    scene = str(EXAMPLES / "paper_experiment.json")
    args = ["export", str(plan_file), "--format", "lif", "--scene", scene, "--out", str(out),
            "--order-id", "cell-a"]  # fmt: skip
    assert main(args) == 0
    doc = json.loads(out.read_text())
    jsonschema.validate(doc, published.schema("lif", "2.0.0"))
    (layout,) = doc["layouts"]
    plan = json.loads(plan_file.read_text())
    assert layout["layoutId"] == "cell-a" and len(layout["stations"]) == len(plan["stops"])
    assert main(["export", str(plan_file), "--format", "lif", "--verify-xy"]) == 2


def test_export_and_dispatch_with_a_vehicle_types_file(
    plan_file, example_plans, planner, mosquitto, tmp_path, capsys
):
    """``--vehicle-types``: the export renames the pick; a dispatch to a vehicle that calls it
    ``pickPart`` exits 3 naming the missing action without the file, and runs with it."""
    import jsonschema
    import yaml

    from pickstop.fleet import published
    from pickstop.fleet.execution import vehicle_for
    from pickstop.fleet.factsheet import Body
    from pickstop.fleet.pickcheck import PickChecker
    from pickstop.fleet.sim_node import VehicleNode
    from pickstop.fleet.vehicle_types import parse_vehicle_types
    from tests.fleet.test_vehicle_types import TYPES

    types = tmp_path / "vehicles.yaml"
    types.write_text(yaml.safe_dump(TYPES))
    out = tmp_path / "order.json"
    args = ["export", str(plan_file), "--format", "vda5050", "--vda-version", "2.0",
            "--vehicle-types", str(types), "--vehicle-type", "mm1", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    order = json.loads(out.read_text())
    jsonschema.validate(order, published.schema("order", "2.0.0"))
    acts = [a for n in order["nodes"] for a in n["actions"]]
    assert acts and {a["actionType"] for a in acts} == {"pickPart"}
    assert main([*args[:-2], "--vehicle-type", "nope"]) == 2

    scene, plan = example_plans["paper_experiment"]
    veh = vehicle_for(plan, PickChecker(planner, scene), seed=0, version="2.0.0")
    veh.manufacturer, veh.serial_number = "acme", "mm-3"
    veh.pick = parse_vehicle_types(TYPES).vehicle_types[0].pick
    veh.body = Body(series_name="MM-1")
    veh.forced_error = (0.0, 0.0, 0.0)
    node = VehicleNode(veh, mosquitto.broker, rate_hz=20, time_scale=0).start()
    base = ["dispatch", str(plan_file), "--broker", mosquitto.broker.url, "--manufacturer",
            "acme", "--serial", "mm-3", "--vda-version", "2.0", "--quiet"]  # fmt: skip
    try:
        capsys.readouterr()
        assert main(base) == 3
        err = capsys.readouterr().err
        assert "cannot run order" in err and "lists no action 'pick'" in err
        assert veh.order_id == ""
        assert main([*base, "--vehicle-types", str(types)]) == 0
        summary = json.loads(capsys.readouterr().out)
        assert summary["done"] and summary["actions_finished"] == summary["actions"] > 0
    finally:
        node.stop()


def test_dispatch_records_every_arrival(plan_file, example_plans, planner, mosquitto, tmp_path):
    from pickstop.fleet.arrivals import read_log
    from pickstop.fleet.execution import vehicle_for
    from pickstop.fleet.pickcheck import PickChecker
    from pickstop.fleet.sim_node import VehicleNode

    scene, plan = example_plans["paper_experiment"]
    veh = vehicle_for(plan, PickChecker(planner, scene), seed=0)
    veh.serial_number = "rec-1"
    veh.forced_error = (0.01, 0.0, 0.0)
    node = VehicleNode(veh, mosquitto.broker, rate_hz=20, time_scale=0).start()
    log = tmp_path / "log.jsonl"
    try:
        for k in range(2):  # a new order id each time: the same one again is a repeat
            assert main(["dispatch", str(plan_file), "--broker", mosquitto.broker.url,
                         "--serial", "rec-1", "--quiet", "--record", str(log),
                         "--order-id", f"rec-{k}"]) == 0  # fmt: skip
    finally:
        node.stop()
    arrivals = read_log(log)
    assert [a.node_id for a in arrivals] == [f"stop{k}" for k in range(len(plan.stops))] * 2
    assert all(a.reported.x - a.planned.x == pytest.approx(0.01) for a in arrivals)
    assert all(a.serial_number == "rec-1" for a in arrivals)
    assert [a.order_id for a in arrivals[:: len(plan.stops)]] == ["rec-0", "rec-1"]

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
from tests.fleet.conftest import EXAMPLES


@pytest.fixture(scope="module")
def plan_file(example_plans, tmp_path_factory):
    _, plan = example_plans["paper_experiment"]
    path = tmp_path_factory.mktemp("fleetcli") / "plan.json"
    path.write_text(json.dumps(plan.model_dump(mode="json")))
    return path


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

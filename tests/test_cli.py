"""The ``pickstop`` command: JSON out, clear errors, exit code 2 for bad input; plans of one
scene or a folder of them, layouts."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from pickstop.cli import main

EXAMPLES = Path(__file__).parents[1] / "examples" / "scenes"


def _run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture(scope="module")
def cli_data(tmp_path_factory):
    folder = tmp_path_factory.mktemp("clidata")
    code = main(
        [
            "--data-dir",
            str(folder),
            "reach",
            "build",
            "--samples",
            "40000",
            "--chunk-size",
            "20000",
            "--workers",
            "1",
            "--quiet",
        ]
    )
    assert code == 0
    return folder


def test_build_info_query(cli_data, capsys):
    code, out, _ = _run(capsys, "--data-dir", str(cli_data), "reach", "info")
    assert code == 0
    info = json.loads(out)
    assert info[0]["state"] == "complete" and info[0]["shards"] == 2
    assert info[0]["indexed"] and info[0]["index_bytes"] > 0 and info[0]["voxels"] > 0
    code, out, _ = _run(
        capsys,
        "--data-dir",
        str(cli_data),
        "reach",
        "query",
        "--pose",
        "0.6",
        "-0.2",
        "0.8",
        "0.7071068",
        "0",
        "0.7071068",
        "0",
        "--neighbours",
        "--refine",
    )
    assert code == 0
    res = json.loads(out)
    assert res["voxel"]["resolution_m"] == 0.05
    assert res["count"] >= len(res["candidates"]) and len(res["candidates"]) <= 10
    assert res["count"] > 0 and res["candidates"][0]["theta"]
    assert "refined" in res and isinstance(res["refined"]["success"], bool)


def test_build_again_is_a_no_op(cli_data, capsys):
    code, out, _ = _run(
        capsys,
        "--data-dir",
        str(cli_data),
        "reach",
        "build",
        "--samples",
        "40000",
        "--chunk-size",
        "20000",
        "--workers",
        "1",
        "--quiet",
    )
    assert code == 0 and json.loads(out)["state"] == "complete"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["reach", "query", "--pose", "1", "2", "3"], "expected 7 arguments"),
        (["reach", "query", "--pose", "1", "2", "x", "1", "0", "0", "0"], "not a number: 'x'"),
        (["reach", "build", "--samples", "-5"], "must be positive"),
        (["reach", "build", "--robot", "fetchy"], "unknown robot 'fetchy'"),
        (["reach", "build", "--resolution", "0", "--samples", "5000"], "resolution must be"),
        (
            ["reach", "query", "--pose", "0.5", "0", "0.7", "1", "1", "0", "0"],
            "unit quaternion",
        ),
        (["ui", "--draft-scale", "0"], "--draft-scale: must be in (0, 1], got 0"),
        (["ui", "--draft-scale", "1.5"], "must be in (0, 1], got 1.5"),
        (["ui", "--lighting", "dark"], "--lighting: invalid choice: 'dark'"),
        (["nonsense"], "invalid choice"),
    ],
)
def test_bad_arguments_exit_2(tmp_path, capsys, argv, message):
    try:
        code = main(["--data-dir", str(tmp_path), *argv])
    except SystemExit as e:  # argparse
        code = e.code
    err = capsys.readouterr().err
    assert code == 2
    assert message in err


def test_query_without_database_explains(tmp_path, capsys):
    code, _, err = _run(
        capsys,
        "--data-dir",
        str(tmp_path),
        "reach",
        "query",
        "--pose",
        "0.5",
        "0",
        "0.7",
        "1",
        "0",
        "0",
        "0",
    )
    assert code == 5  # no database: its own exit code, documented in docs/cli.md
    assert "no complete reachability database for robot 'tiago'" in err
    assert f"`pickstop --data-dir {tmp_path.resolve()} reach build --robot tiago`" in err


def test_console_script_installed(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "pickstop.cli", "--data-dir", str(tmp_path), "reach", "info"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0 and json.loads(proc.stdout) == []


def _scene_naming(folder, robot_block):
    """The paper-like scene in ``folder``, naming its robot by ``robot_block``."""
    from pathlib import Path

    src = Path(__file__).parents[1] / "examples" / "scenes" / "paper_experiment.json"
    doc = json.loads(src.read_text())
    doc["robot"] = robot_block
    path = folder / "scene.json"
    path.write_text(json.dumps(doc))
    return path, doc["trays"][0]["id"]


def _hint(err):
    import re

    (command,) = re.findall(r"`(pickstop [^`]+)`", err)
    return command


def test_missing_database_hint_for_a_config_robot_runs_as_printed(tmp_path, capsys, monkeypatch):
    import shlex

    import pickstop.cli.reach
    from tests.robot.synthetic import write_dense_robot

    config = write_dense_robot(tmp_path / "robot", triangles=500, arm_mesh=False)
    monkeypatch.chdir(tmp_path)  # the hint names the config relative to the working folder
    scene, tray = _scene_naming(tmp_path, {"config": "robot/dense_amr.yaml"})
    data = ["--data-dir", str(tmp_path / "data")]
    code, _, err = _run(capsys, *data, "regions", str(scene), "--tray", tray)
    assert code == 5, err
    command = _hint(err)
    assert "--robot robot/dense_amr.yaml" in command and "dense_amr.yaml" in str(config)
    # Run as printed (the default sample count made small for a test).
    monkeypatch.setattr(pickstop.cli.reach, "DEFAULT_SAMPLES", 20_000)
    code, out, err = _run(capsys, *shlex.split(command)[1:], "--quiet")
    assert code == 0, err
    assert json.loads(out)["state"] == "complete"
    code, out, err = _run(capsys, *data, "regions", str(scene), "--tray", tray)
    assert code == 0, err
    assert json.loads(out)["database"]


def test_robot_option_overrides_the_scenes_robot(tmp_path, capsys, monkeypatch):
    from tests.robot.synthetic import write_dense_robot

    config = write_dense_robot(tmp_path / "robot", triangles=500, arm_mesh=False)
    monkeypatch.chdir(tmp_path)
    scene, tray = _scene_naming(tmp_path, {"preset": "tiago"})
    data = ["--data-dir", str(tmp_path / "data")]
    for argv in (["plan", str(scene)], ["regions", str(scene), "--tray", tray]):
        code, _, err = _run(capsys, *data, *argv, "--robot", str(config))
        assert code == 5, err  # the config robot has no database: it, not TIAGo, was asked for
        assert "robot 'dense_amr'" in err and "--robot robot/dense_amr.yaml" in _hint(err)
        code, _, err = _run(capsys, *data, *argv, "--robot", "tiago")
        assert code == 5 and "--robot tiago" in _hint(err)
        code, _, err = _run(capsys, *data, *argv, "--robot", "nowhere.yaml")
        assert code == 2 and "nowhere.yaml: robot config file not found" in err


def test_ui_robot_option_registers_a_config_with_the_api(tmp_path):
    import httpx

    from pickstop.cli.service import _api_robot
    from pickstop_ui.client import PickStopClient
    from tests.robot.synthetic import write_dense_robot

    config = write_dense_robot(tmp_path, triangles=500, arm_mesh=False)
    posted = []

    def api(request: httpx.Request) -> httpx.Response:
        if request.method == "GET":
            return httpx.Response(200, json=[{"name": "tiago"}])
        posted.append((request.headers["content-type"], request.content))
        return httpx.Response(201, json={"name": "dense_amr"})

    client = PickStopClient("http://api")
    client.http = httpx.Client(base_url="http://api", transport=httpx.MockTransport(api))
    assert _api_robot(client, "tiago") == "tiago" and not posted  # a preset: as it is
    assert _api_robot(client, str(config)) == "dense_amr"
    assert posted == [("application/yaml", config.read_bytes())]


def test_plan_one_scene_to_a_file(region_db, tmp_path, capsys):
    folder, db = region_db
    out = tmp_path / "plan.json"
    code, stdout, _ = _run(
        capsys, "--data-dir", str(folder), "plan", str(EXAMPLES / "paper_experiment.json"),
        "--samples", "200", "--out", str(out), "--db", db.id,
    )  # fmt: skip
    assert code == 0
    summary = json.loads(stdout)
    plan = json.loads(out.read_text())
    assert plan["format"] == "pickstop.plan" and plan["database"] == db.id
    assert summary["stops"] == len(plan["stops"]) and summary["naive_stops"] == 3
    assert plan["parameters"]["samples"] == 200


def test_plan_a_folder_with_one_bad_scene(region_db, tmp_path, capsys):
    folder, db = region_db
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    shutil.copy(EXAMPLES / "paper_experiment.json", scenes / "a.json")
    doc = json.loads((EXAMPLES / "paper_experiment.json").read_text())
    doc["sigma"] = 0.5
    (scenes / "b_wide_sigma.json").write_text(json.dumps(doc))
    (scenes / "c_broken.json").write_text("{not json")
    code, stdout, _ = _run(
        capsys, "--data-dir", str(folder), "plan", str(scenes), "--samples", "0",
        "--out", str(tmp_path / "plans"), "--db", db.id,
    )  # fmt: skip
    assert code == 2  # the worst failure: an invalid file
    lines = stdout.splitlines()
    assert lines[0].split()[:4] == ["scene", "status", "trays", "stops"]
    assert lines[1].startswith("a.json") and " ok " in lines[1]
    assert "b_wide_sigma.json: no plan with sigma = 0.500 m" in stdout
    assert "c_broken.json:" in stdout and "not valid JSON" in stdout
    assert "1 of 3 scenes planned" in stdout
    assert sorted(p.name for p in (tmp_path / "plans").iterdir()) == ["a.plan.json"]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--sigma", "-0.1"], "--sigma: Input should be greater than or equal to 0"),
        (["--target", "1.5"], "--target: Input should be less than 1"),
        (["--samples", "-3"], "--samples: Input should be greater than or equal to 0"),
        (["--rule", "luck"], "invalid choice: 'luck'"),
    ],
)
def test_bad_plan_options_exit_2(tmp_path, capsys, extra, message):
    try:
        code = main(
            ["--data-dir", str(tmp_path), "plan", str(EXAMPLES / "paper_experiment.json"), *extra]
        )
    except SystemExit as e:
        code = e.code
    assert code == 2
    assert message in capsys.readouterr().err


def test_infeasible_plan_exits_3_with_its_explanation(region_db, capsys):
    folder, db = region_db
    code, stdout, err = _run(
        capsys, "--data-dir", str(folder), "plan", str(EXAMPLES / "paper_experiment.json"),
        "--sigma", "0.6", "--samples", "0", "--db", db.id,
    )  # fmt: skip
    assert code == 3 and stdout == ""
    assert "no plan with sigma = 0.600 m: tray tray_1:" in err


def test_expected_time_objective_carries_its_trade_off(region_db, tmp_path, capsys):
    folder, db = region_db
    out = tmp_path / "plan.json"
    code, stdout, _ = _run(
        capsys, "--data-dir", str(folder), "plan", str(EXAMPLES / "five_trays.json"),
        "--objective", "expected-time", "--samples", "100", "--out", str(out), "--db", db.id,
    )  # fmt: skip
    assert code == 0
    plan = json.loads(out.read_text())
    assert plan["parameters"]["objective"] == "expected-time"
    rows = plan["tradeoff"]
    assert [r["stops"] for r in rows] == sorted(r["stops"] for r in rows)
    assert [r["stops"] for r in rows if r["chosen"]] == [len(plan["stops"])]
    summary = json.loads(stdout)
    assert summary["expected_s"] == round(plan["totals"]["time"]["expected"], 1)
    assert summary["expected_s"] >= summary["time_s"]


def test_plan_every_order_of_a_mix_to_a_folder(region_db, tmp_path, capsys):
    folder, db = region_db
    orders = tmp_path / "orders.json"
    orders.write_text(json.dumps([{"id": "a", "trays": ["tray_1", "tray_2"], "weight": 2},
                                  {"id": "b", "parts": ["p4a"]}]))  # fmt: skip
    out = tmp_path / "mix"
    code, stdout, _ = _run(
        capsys, "--data-dir", str(folder), "plan", str(EXAMPLES / "paper_experiment.json"),
        "--orders", str(orders), "--samples", "0", "--out", str(out), "--db", db.id,
    )  # fmt: skip
    assert code == 0
    mix = json.loads(stdout)
    assert mix == json.loads((out / "mix.json").read_text())
    assert mix["format"] == "pickstop.mix" and mix["totals"]["planned"] == 2
    assert sorted(p.name for p in out.iterdir()) == ["a.plan.json", "b.plan.json", "mix.json"]
    b = json.loads((out / "b.plan.json").read_text())
    assert b["format"] == "pickstop.plan" and b["trays"] == ["tray_4"]
    assert mix["orders"][1] == {**mix["orders"][1], "plan": "b.plan.json", "trays": ["tray_4"],
                                "stops": 1, "naive_stops": 1}  # fmt: skip


def test_orders_the_scene_lacks_or_a_tray_in_mid_air_exit_2(tmp_path, capsys):
    scene = str(EXAMPLES / "paper_experiment.json")
    code = main(["--data-dir", str(tmp_path), "plan", scene, "--orders"])
    assert code == 2 and "the scene has no orders" in capsys.readouterr().err
    bad = tmp_path / "orders.json"
    bad.write_text(json.dumps([{"id": "a", "trays": ["tray_7"]}]))
    code = main(["--data-dir", str(tmp_path), "plan", scene, "--orders", str(bad)])
    assert code == 2 and "orders.0.trays.0: order 'a': unknown tray 'tray_7'" in (
        capsys.readouterr().err
    )
    doc = json.loads((EXAMPLES / "paper_experiment.json").read_text())
    doc["trays"][3]["pose"]["y"] = 1.1  # beside its table
    (tmp_path / "air.json").write_text(json.dumps(doc))
    code = main(["--data-dir", str(tmp_path), "plan", str(tmp_path / "air.json")])
    err = capsys.readouterr().err
    assert code == 2 and "tray 'tray_4' stands on nothing: its bottom is 0.720 m" in err


def test_layout_suggestions_to_a_file(region_db, tmp_path, capsys):
    folder, db = region_db
    out = tmp_path / "layout.json"
    code, stdout, _ = _run(
        capsys, "--data-dir", str(folder), "layout", str(EXAMPLES / "paper_experiment.json"),
        "--movable", "tray_4", "--turns", "0", "--step", "0.2", "--samples", "0",
        "--suggestions", "1", "--shortlist", "4", "--out", str(out), "--db", db.id, "--quiet",
    )  # fmt: skip
    assert code == 0
    summary, doc = json.loads(stdout), json.loads(out.read_text())
    assert doc["format"] == "pickstop.layout" and summary["out"] == str(out)
    assert summary["before"] == doc["before"]["totals"] and doc["orders"] == ["task"]
    code, _, err = _run(capsys, "--data-dir", str(folder), "layout",
                        str(EXAMPLES / "paper_experiment.json"), "--movable", "tray_3")  # fmt: skip
    assert code == 2 and "no order needs tray 'tray_3'" in err
